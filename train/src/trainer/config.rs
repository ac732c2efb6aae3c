//! Training configuration (serde, every value exposed; defaults follow the SaRO-GS
//! D-NeRF configs and the paper's protocol unless noted).

use maaf_filter::FilterConfig;
use serde::{Deserialize, Serialize};

use crate::Error;
use crate::models::ModelConfig;

/// Densification schedule and thresholds (3DGS `densify_and_prune`, SaRO-GS D-NeRF
/// config: from 500 to 15 000 every 100, gradient threshold 2e-4, opacity reset every
/// 2000, prune below opacity 0.005, clone/split boundary 0.01 x scene extent).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DensifyConfig {
    /// First densification iteration.
    pub from: usize,
    /// Last densification iteration.
    pub until: usize,
    /// Interval.
    pub every: usize,
    /// Mean screen-space gradient norm (pixels, at the training resolution) above
    /// which a Gaussian is cloned or split.
    pub grad_threshold: f64,
    /// Opacity reset interval (0 = never).
    pub opacity_reset_every: usize,
    /// Opacity below which Gaussians are pruned.
    pub min_opacity: f64,
    /// Clone if the largest scale is at most this fraction of the scene extent, else split.
    pub percent_dense: f64,
    /// After the first opacity reset, prune Gaussians whose screen radius exceeded this (pixels).
    pub max_screen_size: f64,
    /// Hard cap on the number of Gaussians (CPU budget); growth stops there.
    pub max_gaussians: usize,
}

impl Default for DensifyConfig {
    fn default() -> Self {
        DensifyConfig {
            from: 500,
            until: 15_000,
            every: 100,
            grad_threshold: 2e-4,
            opacity_reset_every: 2000,
            min_opacity: 0.005,
            percent_dense: 0.01,
            max_screen_size: 20.0,
            max_gaussians: 60_000,
        }
    }
}

/// Everything a training run needs besides the data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Iterations (one view per iteration).
    pub iterations: usize,
    /// Training scale relative to the source images (0.25 = 200x200 from 800x800).
    pub train_scale: f64,
    /// Seed of initialisation, view order and densification noise.
    pub seed: u64,
    /// Initial random points inside the scene bounds.
    pub init_points: usize,
    /// D-SSIM weight lambda in `(1 - lambda) L1 + lambda D-SSIM`.
    pub lambda_dssim: f64,
    /// Raise the evaluated SH degree by one every this many iterations (3DGS: 1000).
    pub sh_degree_every: usize,
    /// Write a checkpoint every this many iterations (and always at the end).
    pub checkpoint_every: usize,
    /// Log a row to log.csv every this many iterations.
    pub log_every: usize,
    /// Record the validation PSNR (`val_psnr` in log.csv) every this many iterations
    /// and at the last one (0 = never); it goes on that iteration's log row, so use a
    /// multiple of `log_every`.
    pub val_every: usize,
    /// Held-back views the validation PSNR averages (evenly spaced over the val split,
    /// else the test split).
    pub val_views: usize,
    /// Scan every forward value and cotangent for NaN/Inf (slower; names the op).
    pub validate: bool,
    /// The 4D representation: its kind (`"kind": "saro"`) and settings.
    pub model: ModelConfig,
    /// The 3D smoothing filter (kind and KDE parameters).
    pub filter: FilterConfig,
    /// Densification.
    pub densify: DensifyConfig,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            iterations: 20_000,
            train_scale: 0.25,
            seed: 0,
            init_points: 10_000,
            lambda_dssim: 0.2,
            sh_degree_every: 1000,
            checkpoint_every: 5000,
            log_every: 100,
            val_every: 500,
            val_views: 3,
            validate: false,
            model: ModelConfig::default(),
            filter: FilterConfig::default(),
            densify: DensifyConfig::default(),
        }
    }
}

impl TrainConfig {
    /// Checks the model and filter settings, naming the field at fault.
    pub fn validate(&self) -> Result<(), Error> {
        self.model.validate().map_err(Error::Input)?;
        self.filter
            .validate()
            .map_err(|e| Error::Input(format!("filter config: {e}")))
    }
}
