//! The sections of a training configuration besides the model and the filter:
//! densification, sensitivity pruning, camera colour correction, the initial points,
//! the loss region and the background layer.

use maaf_filter::FilterKind;
use serde::{Deserialize, Serialize};

/// Densification schedule and thresholds (3DGS `densify_and_prune`, SaRO-GS D-NeRF
/// config: from 500 to 15 000 every 100, gradient threshold 2e-4, opacity reset every
/// 2000, prune below opacity 0.005, clone/split boundary 0.01 x scene extent, and
/// after the first reset prune above 0.1 x scene extent).
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
    /// Which screen-space gradient statistic `grad_threshold` applies to
    /// ([`DensifyGradient`]).
    pub gradient: DensifyGradient,
    /// Opacity reset interval (0 = never).
    pub opacity_reset_every: usize,
    /// What the opacity reset caps ([`OpacityReset`]): the opacity the 3D filter
    /// draws (`filtered`, Mip-Splatting) or the stored one (`raw`, 3DGS).
    pub reset_opacity: OpacityReset,
    /// Opacity below which Gaussians are pruned.
    pub min_opacity: f64,
    /// Clone if the largest scale is at most this fraction of the scene extent, else split.
    pub percent_dense: f64,
    /// After the first opacity reset, prune Gaussians whose largest activated scale
    /// exceeds this fraction of the scene extent (3DGS `big_points_ws`, 0.1; 0 = off).
    pub max_world_size: f64,
    /// After the first opacity reset, prune Gaussians whose screen radius since the
    /// last densification exceeded this many pixels (0 = off, the default). 3DGS and
    /// the 4D references pass 20, but `densification_postfix` zeroes `max_radii2D`
    /// before `densify_and_prune` reads it, so their test never fires; gsplat leaves it
    /// off too. Live, it prunes by a pixel count that does not follow the training
    /// resolution: at 400x400 it emptied a Deformable-3DGS mutant run by iteration 6000.
    pub max_screen_size: f64,
    /// Hard cap on the number of Gaussians (CPU budget); growth stops there.
    pub max_gaussians: usize,
    /// The densification strategy by its registered name (`"default"`,
    /// `"sensitivity"`, or a program's own: `maaf::cli::Maaf::strategy`); `null`
    /// chooses `"sensitivity"` when `prune.every` > 0, else `"default"`.
    pub strategy: Option<String>,
    /// A strategy of one's own's options (`"densify": {"strategy": "NAME",
    /// "options": {...}}`), for its maker to read and check, naming the field; the
    /// built-in strategies take none. Left out of the JSON when empty.
    #[serde(skip_serializing_if = "serde_json::Map::is_empty")]
    pub options: serde_json::Map<String, serde_json::Value>,
}

impl Default for DensifyConfig {
    fn default() -> Self {
        DensifyConfig {
            from: 500,
            until: 15_000,
            every: 100,
            grad_threshold: 2e-4,
            gradient: DensifyGradient::Mean,
            opacity_reset_every: 2000,
            reset_opacity: OpacityReset::Filtered,
            min_opacity: 0.005,
            percent_dense: 0.01,
            max_world_size: 0.1,
            max_screen_size: 0.0,
            max_gaussians: 60_000,
            strategy: None,
            options: serde_json::Map::new(),
        }
    }
}

/// The screen-space statistic densification thresholds. Per view, with `L_p` the part
/// of the loss that reaches pixel `p` and `(W/2, H/2)` the pixel-to-NDC factors:
///
/// ```text
/// mean:  | ( W/2 sum_p dL_p/dmx , H/2 sum_p dL_p/dmy ) |       (3DGS)
/// abs:   | ( W/2 sum_p |dL_p/dmx| , H/2 sum_p |dL_p/dmy| ) |   (AbsGS)
/// ```
///
/// averaged over the iterations that drew the Gaussian. The signed sum cancels when
/// pixels on two sides of a large Gaussian pull it opposite ways, so large blurry
/// Gaussians over fine detail are rarely split; the absolute sum does not cancel
/// (AbsGS, Ye et al. 2024). Thresholds differ by statistic: 3DGS uses 2e-4, the MAAF
/// release's SpeeDe3DGS backbone 7e-4 on `abs`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DensifyGradient {
    /// The view-space positional gradient `dL/d means2d` (3DGS).
    #[default]
    Mean,
    /// The sum of absolute per-pixel gradients
    /// (`maaf_splat::rasterize::AbsMeans2dGrad`).
    Abs,
}

/// Which opacity the periodic reset caps at `c = 0.01` (3DGS `reset_opacity`).
///
/// With a 3D filter a Gaussian is drawn with the opacity `sigmoid(o) * k`, where
/// `k = sqrt(det S / det(S + var I)) = prod_a sqrt(s_a^2 / (s_a^2 + var))` is the
/// filter's compensation (paper Eq. 3) on the canonical scales `s`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OpacityReset {
    /// Mip-Splatting's reset: the drawn opacity is capped,
    /// `sigmoid(o') = min(sigmoid(o) * k, c) / k`, with the widest variance the filter
    /// gives the Gaussian at any time (the smallest `k`; for the motion filter
    /// `var = s3d / (min_t nu(t))^2`), so after a reset it is drawn at `c` or more at
    /// every time and keeps receiving gradients. Without a filter `k = 1`: the same
    /// as `Raw`.
    #[default]
    Filtered,
    /// 3DGS's reset: `sigmoid(o') = min(sigmoid(o), c)`; with a filter the smallest
    /// Gaussians are then drawn below 1/255 and stop receiving gradients.
    Raw,
}

/// Sensitivity pruning (Speedy-Splat's soft and hard pruning, scheduled as SpeeDe3DGS
/// does for deformable Gaussians: from iteration 6000 every 3000, 80 % of the
/// Gaussians while densification runs, 30 % after it). Off by default (`every` = 0):
/// turning it on changes the model a run ends with, so it is a choice, not a default.
/// The score is `maaf_train::trainer::sensitivity_scores`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PruneConfig {
    /// Interval in iterations (0 = never prune by sensitivity).
    pub every: usize,
    /// First pruning iteration.
    pub from: usize,
    /// Last pruning iteration.
    pub until: usize,
    /// Fraction of the Gaussians removed at a pruning before `densify.until`
    /// (Speedy-Splat's soft pruning; densification grows them back).
    pub ratio_densifying: f64,
    /// Fraction removed at a pruning from `densify.until` on (hard pruning).
    pub ratio_after: f64,
}

impl Default for PruneConfig {
    fn default() -> Self {
        PruneConfig {
            every: 0,
            from: 6000,
            until: 30_000,
            ratio_densifying: 0.8,
            ratio_after: 0.3,
        }
    }
}

/// Per-camera colour correction of the training renders (Dynamic 3D Gaussians'
/// `cam_m`, `cam_c`): `exp(a_c) * I + b_c` per training camera `c` and channel,
/// learned with the model; evaluation renders without it. Off by default: on data
/// whose views each have their own camera (D-NeRF) it only adds freedom.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraColourConfig {
    /// Learn the corrections.
    pub enabled: bool,
    /// Adam learning rate of `a` and `b` (the reference: 1e-4).
    pub lr: f64,
}

impl Default for CameraColourConfig {
    fn default() -> Self {
        CameraColourConfig {
            enabled: false,
            lr: 1e-4,
        }
    }
}

/// Where the static initial points of a data set with training masks and no point
/// cloud lie (`static_points`; the visual hull's points are the movers').
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StaticPoints {
    /// Uniform in the box of the cameras and the hulls, with random colours.
    #[default]
    Box,
    /// On a capture dome's shell: the sphere through the cameras and the floor under
    /// the movers, coloured by the background pixels that see them
    /// ([`maaf_data::shell`]).
    Shell,
}

/// At which training times the visual hull's points are carved (`hull_times`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HullTimes {
    /// At up to `HullOptions::steps` times spread over the training frames, the
    /// points carrying their time: movers for a model whose Gaussians live at times.
    #[default]
    All,
    /// The whole hull share at the earliest training time: for a model that starts
    /// from the first frame and tracks it (`model.kind = "track"`), which uses no
    /// other frame's points.
    First,
}

/// Which pixels of a training view the objective sees (`loss_region`). `background`
/// and `foreground` need foreground masks of the training views (the Dynamic 3D
/// Gaussians layout's `seg/`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LossRegion {
    /// Every pixel.
    #[default]
    All,
    /// The pixels the view's mask calls background, each weighted by its background
    /// share `1 - m`: what a run's background layer is fitted on.
    Background,
    /// The rectangle around the view's foreground mask, grown by `focus_margin`
    /// pixels: the view is rendered on that rectangle only, so an iteration costs a
    /// fraction of a full view (the whole view when its mask is empty).
    Foreground,
}

/// A static background layer fitted before the model (`backdrop`): a run of plain
/// 3D Gaussians (Deformable-3DGS's static stage) on the training views' background
/// pixels (`loss_region = background`), trained into `RUN/backdrop/` first and then
/// held fixed; the run's own model is rendered over it
/// (`C = C_model + T_model * C_background`). Needs foreground masks of the training
/// views. The layer takes the run's seed, scale, filter settings, colour correction
/// and photometric loss; the keys below are its own (its filter kind among them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackdropConfig {
    /// Iterations of the background layer's run; 0 = no background layer.
    pub iterations: usize,
    /// Its initial points (static points only, placed as `static_points` says).
    pub init_points: usize,
    /// Its Gaussian cap.
    pub max_gaussians: usize,
    /// Its last densification iteration.
    pub densify_until: usize,
    /// Its spherical-harmonics degree.
    pub sh_degree: usize,
    /// Its 3D filter (`filter.kind`'s names; the run's other filter settings). Default
    /// `mip3d`: the layer is static, so Mip-Splatting's nu, the largest f/d over the
    /// training cameras, is its sampling rate at every time; the motion-aware filter
    /// under test is the model's.
    pub filter: FilterKind,
}

impl Default for BackdropConfig {
    fn default() -> Self {
        BackdropConfig {
            iterations: 0,
            init_points: 20_000,
            max_gaussians: 30_000,
            densify_until: 3_500,
            sh_degree: 0,
            filter: FilterKind::Mip3d,
        }
    }
}

impl BackdropConfig {
    /// Whether the run has a background layer.
    pub fn enabled(&self) -> bool {
        self.iterations > 0
    }
}
