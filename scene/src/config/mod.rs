//! Training configuration (serde, every value exposed; defaults follow the SaRO-GS
//! D-NeRF configs and the paper's protocol unless noted).

use std::collections::BTreeMap;

use maaf_data::Background;
use maaf_filter::FilterConfig;
use serde::{Deserialize, Serialize};

use maaf_models::{ModelConfig, TrackConfig};

use crate::Error;
use crate::budget::WallBudget;

mod sections;
#[cfg(test)]
mod tests;

pub use sections::{
    BackdropConfig, CameraColourConfig, DensifyConfig, DensifyGradient, HullTimes, LossRegion,
    OpacityReset, PruneConfig, StaticPoints,
};

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
