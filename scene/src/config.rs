//! Training configuration (serde, every value exposed; defaults follow the SaRO-GS
//! D-NeRF configs and the paper's protocol unless noted).

use std::collections::BTreeMap;

use maaf_data::Background;
use maaf_filter::{FilterConfig, FilterKind};
use serde::{Deserialize, Serialize};

use maaf_models::{ModelConfig, TrackConfig};

use crate::Error;
use crate::budget::WallBudget;

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

/// Everything a training run needs besides the data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Iterations (`batch` views per iteration).
    pub iterations: usize,
    /// A wall time for the whole run (`"10m"`; `maaf train --budget`): a new run
    /// measures a short warm-up and trains the schedule scaled by one factor
    /// ([`TrainConfig::scaled_schedule`]) chosen to finish in it. `None`: the schedule
    /// as written.
    pub budget: Option<WallBudget>,
    /// Training views per iteration. Each view is rendered at its own time from one
    /// binding of the model (SaRO's field and lifespans are queried once per
    /// iteration), and the gradient is the mean of the views' objectives: SaRO-GS
    /// `train.py` with `batch` (its D-NeRF and N3D configs use 4; Deformable-3DGS and
    /// 3DGS use 1). 1 is the default here because it costs least per iteration.
    pub batch: usize,
    /// Training scale relative to the source images (0.25 = 200x200 from 800x800).
    pub train_scale: f64,
    /// Seed of initialisation, view order and densification noise.
    pub seed: u64,
    /// Initial random points inside the scene bounds.
    pub init_points: usize,
    /// Share of `init_points` placed on the visual hulls of the foreground masks when
    /// the data set has masks and no point cloud (the Panoptic layout), in [0, 1]; the
    /// rest are random static points ([`maaf_data::visual_hull`]). 0 starts the
    /// movers from random points too.
    pub hull_fraction: f64,
    /// D-SSIM weight lambda in `(1 - lambda) L1 + lambda D-SSIM`.
    pub lambda_dssim: f64,
    /// The colour the data's transparent pixels are composited on for training,
    /// validation and evaluation, and the model is rendered on (`"black"`, `"white"`
    /// or `"r,g,b"`). Black by default, the paper's D-NeRF protocol
    /// ([`Background::default`]); `maaf train --background` overrides it. A trainer
    /// refuses a data set opened on another background.
    pub background: Background,
    /// Render each training view on a uniformly random background colour and
    /// composite its ground truth on the same colour from the images' alpha
    /// (nerfstudio's `background_color = "random"`), so empty space is learnt as
    /// transparent rather than as the background's colour. Off by default: the
    /// paper's and the released code's D-NeRF runs train on a constant background.
    /// Validation and evaluation use the data set's background either way.
    pub random_background: bool,
    /// Where the static initial points lie ([`StaticPoints`]).
    pub static_points: StaticPoints,
    /// At which training times the hull points are carved ([`HullTimes`]).
    pub hull_times: HullTimes,
    /// Per-camera colour correction of the training renders ([`CameraColourConfig`]).
    pub camera_colour: CameraColourConfig,
    /// Which pixels of a training view the objective sees ([`LossRegion`]).
    pub loss_region: LossRegion,
    /// Pixels (at the training scale) added around the foreground mask's rectangle
    /// with `loss_region = foreground`.
    pub focus_margin: u32,
    /// The static background layer ([`BackdropConfig`]; off by default).
    pub backdrop: BackdropConfig,
    /// Further loss terms by name with their weights, `{"opacity_entropy": 0.001}`:
    /// the built-in regularisers (`maaf_train::loss::builtin`) or terms the training
    /// program registered (`maaf_train::loss::TermRegistry`). Added after the
    /// photometric loss and the model's regularisers, in name order.
    pub terms: BTreeMap<String, f64>,
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
    /// Keep as the run's model (`model/`) the state with the best validation PSNR
    /// (`val_psnr`, every `val_every` iterations, on the data set's validation split,
    /// never the test split) instead of the last one, which stays in
    /// `checkpoints/iter_N`: SaRO-GS `train.py` keeps its best evaluation, but by
    /// test PSNR. Off by default.
    pub keep_best: bool,
    /// Scan every forward value and cotangent for NaN/Inf (slower; names the op).
    pub validate: bool,
    /// Largest share of skipped (non-finite) steps a run may have before it is
    /// stopped as diverged, in [0, 1].
    pub max_skipped_fraction: f64,
    /// Iterations before `max_skipped_fraction` applies (a few early skips are noise).
    pub skip_grace: usize,
    /// The 4D representation: its kind (`"kind": "saro"`) and settings.
    pub model: ModelConfig,
    /// The 3D smoothing filter (kind and KDE parameters).
    pub filter: FilterConfig,
    /// Densification.
    pub densify: DensifyConfig,
    /// Sensitivity pruning (off unless `prune.every` > 0).
    pub prune: PruneConfig,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            iterations: 20_000,
            budget: None,
            batch: 1,
            train_scale: 0.25,
            seed: 0,
            init_points: 10_000,
            hull_fraction: 0.5,
            lambda_dssim: 0.2,
            background: Background::default(),
            random_background: false,
            static_points: StaticPoints::Box,
            hull_times: HullTimes::All,
            camera_colour: CameraColourConfig::default(),
            loss_region: LossRegion::All,
            focus_margin: 8,
            backdrop: BackdropConfig::default(),
            terms: BTreeMap::new(),
            sh_degree_every: 1000,
            checkpoint_every: 5000,
            log_every: 100,
            val_every: 500,
            val_views: 3,
            keep_best: false,
            validate: false,
            max_skipped_fraction: 0.05,
            skip_grace: 20,
            model: ModelConfig::default(),
            filter: FilterConfig::default(),
            densify: DensifyConfig::default(),
            prune: PruneConfig::default(),
        }
    }
}

/// Most training views one iteration may batch (each view's render stays on the tape
/// until the backward).
pub const MAX_BATCH: usize = 64;

/// Largest number of initial points or Gaussians a config may ask for (a CPU run
/// beyond this would not fit in memory or time).
pub const MAX_GAUSSIANS_CAP: usize = 10_000_000;

/// One-line error for `field` = `value` outside `range`.
fn bad(field: &str, value: &dyn std::fmt::Display, range: &str) -> Error {
    Error::Input(format!("config: {field} = {value}: must be {range}"))
}

/// `Ok` if `v` is finite and in `lo..=hi`, else the error naming `field`.
fn in_range(field: &str, v: f64, lo: f64, hi: f64) -> Result<(), Error> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(bad(field, &v, &format!("a number in [{lo}, {hi}]")))
    }
}

/// `Ok` if `v` is in `lo..=hi`, else the error naming `field`.
fn count(field: &str, v: usize, lo: usize, hi: usize) -> Result<(), Error> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        let range = if hi == usize::MAX {
            format!("an integer >= {lo}")
        } else {
            format!("an integer in {lo}..={hi}")
        };
        Err(bad(field, &v, &range))
    }
}

impl TrainConfig {
    /// The configuration of this run's background layer ([`BackdropConfig`]):
    /// plain 3D Gaussians (Deformable-3DGS that never leaves its static stage) at
    /// `backdrop.sh_degree`, fitted on the background pixels (`loss_region =
    /// background`) for `backdrop.iterations` from `backdrop.init_points` random
    /// points (no visual-hull points), densified until `backdrop.densify_until` up
    /// to `backdrop.max_gaussians`; one view per iteration, no extra terms and no
    /// sensitivity pruning. Seed, scale, filter, colour correction, photometric loss,
    /// the rest of the densification and the logging keys are the run's.
    pub fn backdrop_layer(&self) -> TrainConfig {
        let b = &self.backdrop;
        TrainConfig {
            iterations: b.iterations,
            batch: 1,
            init_points: b.init_points,
            hull_fraction: 0.0,
            terms: BTreeMap::new(),
            loss_region: LossRegion::Background,
            backdrop: BackdropConfig::default(),
            filter: FilterConfig {
                kind: b.filter.clone(),
                ..self.filter.clone()
            },
            model: ModelConfig::Deform(maaf_models::DeformConfig {
                warm_up: usize::MAX,
                sh_degree: b.sh_degree,
                ..maaf_models::DeformConfig::default()
            }),
            densify: DensifyConfig {
                until: b.densify_until.min(b.iterations),
                from: self.densify.from.min(b.densify_until.min(b.iterations)),
                max_gaussians: b.max_gaussians,
                ..self.densify.clone()
            },
            prune: PruneConfig::default(),
            ..self.clone()
        }
    }

    /// What this config's schedule leaves out because the run is shorter than it (a
    /// short run of a 20 000-iteration schedule): densification that never starts, a
    /// 3D filter never refreshed after the first iteration. One line each, for a
    /// warning; empty when the schedule fits.
    pub fn schedule_warnings(&self) -> Vec<String> {
        let n = self.iterations;
        let d = &self.densify;
        let densifies = d.from < n && d.from < d.until;
        let mut warnings = Vec::new();
        if !densifies && d.from < d.until {
            warnings.push(format!(
                "densification starts at iteration {} (densify.from), not before this run's end at {n}: the run keeps its {} initial Gaussians; scale densify.from / until to the run",
                d.from, self.init_points
            ));
        }
        let refresh = &self.filter.refresh;
        let refreshes = refresh.start < n as u64 || (refresh.after_densify && densifies);
        if self.filter.kind != maaf_filter::FilterKind::None && !refreshes {
            warnings.push(format!(
                "the 3D filter is refreshed from iteration {} (filter.refresh.start), not before this run's end at {n}: it stays as computed before the first iteration",
                refresh.start
            ));
        }
        warnings
    }

    /// Checks every setting before any work starts; the error is one line naming the
    /// field, its value and the allowed range.
    pub fn validate(&self) -> Result<(), Error> {
        count("iterations", self.iterations, 1, 100_000_000)?;
        count("batch", self.batch, 1, MAX_BATCH)?;
        if !(self.train_scale.is_finite() && self.train_scale > 0.0 && self.train_scale <= 1.0) {
            return Err(bad(
                "train_scale",
                &self.train_scale,
                "in (0, 1] (a downsampling of the source images)",
            ));
        }
        count("init_points", self.init_points, 1, MAX_GAUSSIANS_CAP)?;
        in_range("hull_fraction", self.hull_fraction, 0.0, 1.0)?;
        in_range("lambda_dssim", self.lambda_dssim, 0.0, 1.0)?;
        in_range("camera_colour.lr", self.camera_colour.lr, 0.0, 1.0)?;
        let b = &self.backdrop;
        if b.enabled() {
            count("backdrop.init_points", b.init_points, 1, MAX_GAUSSIANS_CAP)?;
            count(
                "backdrop.max_gaussians",
                b.max_gaussians,
                b.init_points,
                MAX_GAUSSIANS_CAP,
            )?;
            count("backdrop.sh_degree", b.sh_degree, 0, 3)?;
            if self.budget.is_some() {
                return Err(bad(
                    "budget",
                    &self.budget.map_or(0.0, WallBudget::seconds),
                    "unset with a background layer (the budget's planner times the model's steps, not the layer's)",
                ));
            }
            if self.random_background {
                return Err(bad(
                    "random_background",
                    &true,
                    "false with a background layer (the layer is drawn on the data set's background)",
                ));
            }
        }
        for (name, &weight) in &self.terms {
            if let Some(problem) = crate::name_problem(name) {
                return Err(Error::Input(format!("config: terms: {problem}")));
            }
            if !(weight.is_finite() && weight >= 0.0) {
                return Err(bad(
                    &format!("terms.{name}"),
                    &weight,
                    "a finite weight >= 0",
                ));
            }
        }
        count("sh_degree_every", self.sh_degree_every, 1, usize::MAX)?;
        count("checkpoint_every", self.checkpoint_every, 1, usize::MAX)?;
        count("log_every", self.log_every, 1, usize::MAX)?;
        if !self.val_every.is_multiple_of(self.log_every) {
            return Err(bad(
                "val_every",
                &self.val_every,
                &format!(
                    "0 or a multiple of log_every = {} (validation goes on a log row)",
                    self.log_every
                ),
            ));
        }
        if self.val_every > 0 {
            count("val_views", self.val_views, 1, 10_000)?;
        } else if self.keep_best {
            return Err(bad(
                "keep_best",
                &true,
                "false when val_every = 0 (the best state is chosen by the validation PSNR)",
            ));
        }
        in_range("max_skipped_fraction", self.max_skipped_fraction, 0.0, 1.0)?;
        let d = &self.densify;
        if d.from > d.until {
            return Err(bad(
                "densify.from",
                &d.from,
                &format!("<= densify.until = {}", d.until),
            ));
        }
        let positive = [
            ("densify.grad_threshold", d.grad_threshold),
            ("densify.percent_dense", d.percent_dense),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(field, &v, "a finite number > 0"));
            }
        }
        let off_or_positive = [
            ("densify.max_world_size", d.max_world_size),
            ("densify.max_screen_size", d.max_screen_size),
        ];
        for (field, v) in off_or_positive {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, &v, "a finite number >= 0 (0 = off)"));
            }
        }
        in_range("densify.min_opacity", d.min_opacity, 0.0, 1.0)?;
        count(
            "densify.max_gaussians",
            d.max_gaussians,
            self.init_points,
            MAX_GAUSSIANS_CAP,
        )
        .map_err(|_| {
            bad(
                "densify.max_gaussians",
                &d.max_gaussians,
                &format!(
                    "in init_points ({})..={MAX_GAUSSIANS_CAP}",
                    self.init_points
                ),
            )
        })?;
        let p = &self.prune;
        if p.every > 0 && p.from > p.until {
            return Err(bad(
                "prune.from",
                &p.from,
                &format!("<= prune.until = {}", p.until),
            ));
        }
        in_range("prune.ratio_densifying", p.ratio_densifying, 0.0, 0.99)?;
        in_range("prune.ratio_after", p.ratio_after, 0.0, 0.99)?;
        self.model
            .validate()
            .map_err(|e| Error::Input(format!("config: {e}")))?;
        if let ModelConfig::Track(track) = &self.model {
            self.check_first_frame(track)?;
        }
        self.filter
            .validate()
            .map_err(|e| Error::Input(format!("config: filter: {e}")))
    }

    /// With the tracking model the set of Gaussians may change only in frame 0
    /// ([`TrackConfig::first_frame_end`] iterations; Dynamic 3D Gaussians densifies
    /// and resets opacities in its first timestep only, and tracks every Gaussian
    /// after it): refuses a `densify.until` (densification and opacity reset) or
    /// `prune.until` past it, and an opacity reset at its last iteration, which would
    /// leave every opacity at the reset value with its learning rate frozen.
    fn check_first_frame(&self, track: &TrackConfig) -> Result<(), Error> {
        let end = track.first_frame_end(self.iterations);
        let range = format!(
            "<= {end}, the last iteration of frame 0 with model.kind track (model.first_frame_iterations = {} of iterations = {}): the Gaussians are tracked after it",
            track.first_frame_iterations, self.iterations
        );
        let d = &self.densify;
        if (d.every > 0 || d.opacity_reset_every > 0) && d.until > end {
            return Err(bad("densify.until", &d.until, &range));
        }
        if self.prune.every > 0 && self.prune.until > end {
            return Err(bad("prune.until", &self.prune.until, &range));
        }
        let every = d.opacity_reset_every;
        if every > 0 && d.until >= end && end.is_multiple_of(every) {
            return Err(bad(
                "densify.opacity_reset_every",
                &every,
                &format!(
                    "no divisor of {end}, the last iteration of frame 0 with model.kind track, while densify.until reaches it (a reset there leaves every opacity at the reset value, frozen after frame 0); lower densify.until"
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The backdrop layer is a static, single-view-per-step run on the background
    /// pixels whose filter is `backdrop.filter` (the static one unless set), with the
    /// run's other filter settings.
    #[test]
    fn the_backdrop_layer_is_static_with_its_own_filter_kind() {
        let mut run: TrainConfig = serde_json::from_str(
            r#"{"filter": {"kind": "motion", "s3d": 0.3}, "backdrop": {"iterations": 50}}"#,
        )
        .expect("parses");
        let layer = run.backdrop_layer();
        assert_eq!(layer.filter.kind, FilterKind::Mip3d);
        assert_eq!(layer.filter.s3d, 0.3);
        assert_eq!(layer.loss_region, LossRegion::Background);
        assert_eq!((layer.iterations, layer.batch), (50, 1));
        assert!(!layer.backdrop.enabled());
        run.backdrop.filter = FilterKind::None;
        assert_eq!(run.backdrop_layer().filter.kind, FilterKind::None);
    }

    /// A run shorter than its schedule is told what it skips; the full schedule and a
    /// filterless run's refreshes are not.
    #[test]
    fn short_runs_are_told_what_their_schedule_skips() {
        assert!(TrainConfig::default().schedule_warnings().is_empty());
        let short = TrainConfig {
            iterations: 20,
            ..TrainConfig::default()
        };
        let warnings = short.schedule_warnings();
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].contains("densify.from") && warnings[0].contains("at 20"));
        assert!(warnings[1].contains("filter.refresh.start"));
        let mut unfiltered = short.clone();
        unfiltered.filter.kind = maaf_filter::FilterKind::None;
        assert_eq!(unfiltered.schedule_warnings().len(), 1);
        // Densification inside the run refreshes the filter after it.
        let mut densifying = short;
        densifying.densify.from = 5;
        assert!(densifying.schedule_warnings().is_empty());
    }

    /// Each bad value is refused with its field's name; the defaults pass.
    #[test]
    fn every_bad_setting_names_its_field() {
        TrainConfig::default()
            .validate()
            .expect("defaults are valid");
        type Change = Box<dyn Fn(&mut TrainConfig)>;
        let cases: Vec<(&str, Change)> = vec![
            ("iterations", Box::new(|c| c.iterations = 0)),
            ("batch", Box::new(|c| c.batch = 0)),
            ("train_scale", Box::new(|c| c.train_scale = -1.0)),
            ("train_scale", Box::new(|c| c.train_scale = f64::NAN)),
            ("init_points", Box::new(|c| c.init_points = 0)),
            ("hull_fraction", Box::new(|c| c.hull_fraction = 1.5)),
            ("lambda_dssim", Box::new(|c| c.lambda_dssim = 2.0)),
            (
                "terms.depth_tv",
                Box::new(|c| {
                    c.terms.insert("depth_tv".into(), f64::NAN);
                }),
            ),
            ("checkpoint_every", Box::new(|c| c.checkpoint_every = 0)),
            ("log_every", Box::new(|c| c.log_every = 0)),
            ("val_every", Box::new(|c| c.val_every = 150)),
            (
                "max_skipped_fraction",
                Box::new(|c| c.max_skipped_fraction = 1.5),
            ),
            (
                "densify.max_gaussians",
                Box::new(|c| c.densify.max_gaussians = 0),
            ),
            ("densify.from", Box::new(|c| c.densify.from = 20_000)),
            (
                "prune.from",
                Box::new(|c| {
                    c.prune.every = 100;
                    c.prune.from = 40_000;
                }),
            ),
            (
                "prune.ratio_densifying",
                Box::new(|c| c.prune.ratio_densifying = 1.0),
            ),
            (
                "prune.ratio_after",
                Box::new(|c| c.prune.ratio_after = -0.1),
            ),
            (
                "densify.min_opacity",
                Box::new(|c| c.densify.min_opacity = -0.1),
            ),
        ];
        for (field, change) in cases {
            let mut c = TrainConfig::default();
            change(&mut c);
            let msg = c.validate().expect_err(field).to_string();
            assert!(
                msg.starts_with(&format!("config: {field} = ")),
                "{field}: {msg}"
            );
            assert!(!msg.contains('\n'), "{msg}");
        }
    }

    #[test]
    fn the_tracking_model_densifies_and_prunes_only_in_frame_zero() {
        let mut c = TrainConfig {
            model: ModelConfig::default_of("track").expect("built in"),
            iterations: 10_000,
            ..TrainConfig::default()
        };
        // Frame 0 is the first 0.2 x 10 000 = 2000 iterations.
        let msg = c.validate().expect_err("default densify.until").to_string();
        assert!(
            msg.starts_with(
                "config: densify.until = 15000: must be <= 2000, the last iteration of frame 0"
            ),
            "{msg}"
        );
        // The default reset every 2000 iterations would come at the last iteration
        // of frame 0 and leave the opacities there.
        c.densify.until = 2000;
        let msg = c.validate().expect_err("a reset at 2000").to_string();
        assert!(
            msg.starts_with(
                "config: densify.opacity_reset_every = 2000: must be no divisor of 2000"
            ),
            "{msg}"
        );
        c.densify.opacity_reset_every = 1000;
        c.densify.until = 1999;
        c.validate()
            .expect("densification within frame 0, the last reset at 1000");
        c.prune.every = 100;
        let msg = c.validate().expect_err("default prune.until").to_string();
        assert!(
            msg.starts_with("config: prune.until = 30000: must be <= 2000"),
            "{msg}"
        );
        c.prune.until = 1500;
        c.prune.from = 1000;
        c.validate().expect("pruning within frame 0");
    }

    #[test]
    fn a_term_name_must_be_a_log_column_of_its_own() {
        for (name, says) in [
            ("l1", "reserved"),
            ("total", "reserved"),
            ("a,b", "not a term name"),
            ("", "not a term name"),
        ] {
            let mut c = TrainConfig::default();
            c.terms.insert(name.into(), 0.1);
            let msg = c.validate().expect_err(name).to_string();
            assert!(msg.starts_with("config: terms: "), "{msg}");
            assert!(msg.contains(says), "{name}: {msg}");
        }
        let mut c = TrainConfig::default();
        c.terms.insert("my_term_2".into(), 0.0);
        c.validate()
            .expect("any registered-looking name with a weight >= 0");
    }
}
