//! Evaluation metrics beyond one image's PSNR and SSIM (docs/conventions.md,
//! "Metrics"): PSNR by moving and static region, squared error by ring around the
//! silhouette, temporal stability and popping, and the per-image metrics a program
//! registers ([`image_metric`]). The image metrics they build on (PSNR,
//! SSIM, error maps, why a metric fails) are [`maaf_scene::metrics`], which the trainer's
//! validation uses too. Not differentiable; every sum is accumulated in f64 whatever
//! the image type.

pub mod image_metric;
pub mod popping;
pub mod regions;
pub mod rings;
pub mod temporal;
