//! The training objective (DESIGN.md section 6): differentiable image losses.

pub mod ssim;

pub use ssim::{Ssim, SsimOutput, ssim, ssim_map};
