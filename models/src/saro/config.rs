//! Configuration of the SaRO representation: sizes, schedule constants and learning
//! rates (SaRO-GS `arguments/__init__.py`, `configs/dnerf/*.json`).

use serde::{Deserialize, Serialize};

use crate::kplane::KPlaneConfig;

/// Learning rates of SaRO-GS for D-NeRF (`arguments/__init__.py`, `configs/dnerf/*.json`,
/// `SaROGaussian.training_setup` / `update_learning_rate`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SaroLr {
    /// Centres at iteration 0, times the scene extent (1.6e-4).
    pub position_init: f64,
    /// Centres at the end of the decay, times the scene extent (1.6e-6).
    pub position_final: f64,
    /// Length of every decay (`position_lr_max_steps` = 30 000).
    pub max_steps: usize,
    /// SH DC (2.5e-3); the rest uses `feature / 20`.
    pub feature: f64,
    /// Opacity logit (0.05).
    pub opacity: f64,
    /// Log-scale (3e-3 in the D-NeRF configs).
    pub scaling: f64,
    /// Quaternion (1e-3).
    pub rotation: f64,
    /// Temporal centre (`trbfc_lr` 1e-6).
    pub t_centre: f64,
    /// MLPs, start (1.6e-4).
    pub mlp_init: f64,
    /// MLPs, end (1.6e-7).
    pub mlp_final: f64,
    /// Planes, start (3.2e-3). The reference's schedule is not scaled by the extent
    /// (`update_learning_rate` overrides the extent-scaled initial value every step).
    pub plane_init: f64,
    /// Planes, end (3.2e-6).
    pub plane_final: f64,
    /// Adam L2 weight decay on MLPs and planes (8e-7).
    pub weight_decay: f64,
}

impl Default for SaroLr {
    fn default() -> Self {
        SaroLr {
            position_init: 1.6e-4,
            position_final: 1.6e-6,
            max_steps: 30_000,
            feature: 2.5e-3,
            opacity: 0.05,
            scaling: 3e-3,
            rotation: 1e-3,
            t_centre: 1e-6,
            mlp_init: 1.6e-4,
            mlp_final: 1.6e-7,
            plane_init: 3.2e-3,
            plane_final: 3.2e-6,
            weight_decay: 8e-7,
        }
    }
}

/// Configuration of the SaRO representation (a serde struct; missing fields take the
/// defaults).
///
/// CPU defaults vs SaRO-GS D-NeRF: MLP hidden width 64 (reference 128), time texels 64
/// (reference 128), 32 channels and 64 x 64 spatial planes as the reference, SH degree
/// 3 with the SH residual head as the reference. The MLPs dominate the cost (see
/// `cost_report` in the tests), and halving the width cuts it about 3x.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SaroConfig {
    /// Residual field sizes.
    pub field: KPlaneConfig,
    /// Hidden width H of the residual MLPs (two hidden layers each; the lifespan MLP
    /// uses H and H/2).
    pub hidden: usize,
    /// Frequencies of the time embedding (`deform_time_encode` = 4 -> 9 inputs).
    pub time_freqs: usize,
    /// SH degree (0..=3); K = (degree + 1)^2 coefficients per colour channel.
    pub sh_degree: usize,
    /// Predict an SH residual (`dsh: true` in the D-NeRF configs).
    pub sh_residual: bool,
    /// Shortest lifespan in frames (`min_interval` 0.5).
    pub min_interval: f64,
    /// Frames of the sequence (`duration`): `m = min_interval / duration`. `None`
    /// (the default) takes the number of distinct training times of the data set,
    /// which is how SaRO-GS's per-scene configs set it (lego 50, hook and hellwarrior
    /// 100, mutant 150, jumpingjacks and trex 200); the trainer records the value it
    /// used in `config.json`.
    pub duration: Option<f64>,
    /// Temporal-integral prune threshold (`min_intergral` 0.0025).
    pub min_integral: f64,
    /// Iterations rendered as static 3D Gaussians (`static_iteration` 1000).
    pub static_iterations: usize,
    /// SaRO-GS's adaptive optimisation ("AO" of the paper's title): every this many
    /// iterations of the dynamic stage the per-Gaussian scale `I_max / I` (I the
    /// temporal integral) is recomputed; it multiplies the learning rates of centre,
    /// opacity, temporal centre, rotation and SH DC (and of the log-scale while
    /// densifying) and the densification gradient, so Gaussians that live for a short
    /// time learn and densify as fast as long-lived ones (`update_learning_rate`,
    /// `iteration % 50 == 0`). 0 (the default) turns it off; 50 is SaRO-GS.
    ///
    /// Off by default because, measured here, it is not stable: on the generated
    /// multi-view scene (`maaf generate --rig multiview`, 3000 iterations at 1/4) a
    /// short-lived Gaussian's log-scale learning rate grew 168x and its scale reached
    /// e^20 within 40 steps, the projected covariance overflowed f32 and every step
    /// from iteration 1141 was skipped; on mutant (3000 iterations) it doubled the
    /// Gaussian count (23 362 vs 10 994) for +0.5 dB at 1x and -0.55 dB at 1/4x.
    pub adaptive_every: usize,
    /// Keep the adaptive learning rates after the densification window
    /// (`use_intergral_afterdensify`: false in the D-NeRF configs, true in the
    /// Neural 3D Video ones).
    pub adaptive_after_densify: bool,
    /// Apply the adaptive scale to the log-scale's learning rate while densifying
    /// (SaRO-GS `scale_intergral`, true in its D-NeRF runs). Off, the scale keeps its
    /// plain learning rate while centre, opacity, temporal centre, rotation and SH DC
    /// still get the adaptive one: a log-scale step of `lr * I_max / I` (up to ~350x
    /// the plain rate at the shortest lifespans) moves the scale by `e^1` per step.
    pub adaptive_log_scale: bool,
    /// Weight of L_SR (`lambda_dscale_reg` 8e-6): the one place it is set; the model
    /// declares the `l_sr` term with it ([`crate::Representation::regularisers`]).
    pub lambda_sr: f64,
    /// Learning rates.
    pub lr: SaroLr,
}

impl Default for SaroConfig {
    fn default() -> Self {
        SaroConfig {
            field: KPlaneConfig::default(),
            hidden: 64,
            time_freqs: 4,
            sh_degree: 3,
            sh_residual: true,
            min_interval: 0.5,
            duration: None,
            min_integral: 0.0025,
            static_iterations: 1000,
            adaptive_every: 0,
            adaptive_after_densify: false,
            adaptive_log_scale: true,
            lambda_sr: 8e-6,
            lr: SaroLr::default(),
        }
    }
}

impl SaroConfig {
    /// SH coefficients per colour channel, `(degree + 1)^2`.
    pub fn sh_coeffs(&self) -> usize {
        (self.sh_degree + 1) * (self.sh_degree + 1)
    }

    /// Width of the time embedding: `1 + 2 * time_freqs`.
    pub fn pe_dim(&self) -> usize {
        1 + 2 * self.time_freqs
    }

    /// Shortest lifespan `m = min_interval / duration` (duration 1 if unresolved).
    pub fn min_lifespan(&self) -> f64 {
        self.min_interval / self.duration.unwrap_or(1.0).max(1.0)
    }
}

impl SaroConfig {
    /// Checks every size and rate, naming the field and its allowed range.
    pub fn validate(&self) -> Result<(), String> {
        let f = &self.field;
        let bad = |field: &str, range: &str, v: &dyn std::fmt::Display| {
            Err(format!("model.{field} = {v}: must be {range}"))
        };
        if !(2..=4096).contains(&f.spatial_res) || !f.spatial_res.is_power_of_two() {
            return bad(
                "field.spatial_res",
                "a power of two in 2..=4096",
                &f.spatial_res,
            );
        }
        if !(1..=4096).contains(&f.time_res) {
            return bad("field.time_res", "in 1..=4096", &f.time_res);
        }
        if !(1..=256).contains(&f.channels) {
            return bad("field.channels", "in 1..=256", &f.channels);
        }
        if !(1..=4096).contains(&self.hidden) {
            return bad("hidden", "in 1..=4096", &self.hidden);
        }
        if self.time_freqs > 16 {
            return bad("time_freqs", "in 0..=16", &self.time_freqs);
        }
        if self.sh_degree > 3 {
            return bad("sh_degree", "in 0..=3", &self.sh_degree);
        }
        if let Some(d) = self.duration
            && !(d.is_finite() && d >= 1.0)
        {
            return bad("duration", "a number of frames >= 1", &d);
        }
        let non_negative = [
            ("min_interval", self.min_interval),
            ("min_integral", self.min_integral),
            ("lambda_sr", self.lambda_sr),
            ("lr.position_init", self.lr.position_init),
            ("lr.position_final", self.lr.position_final),
            ("lr.feature", self.lr.feature),
            ("lr.opacity", self.lr.opacity),
            ("lr.scaling", self.lr.scaling),
            ("lr.rotation", self.lr.rotation),
            ("lr.t_centre", self.lr.t_centre),
            ("lr.mlp_init", self.lr.mlp_init),
            ("lr.mlp_final", self.lr.mlp_final),
            ("lr.plane_init", self.lr.plane_init),
            ("lr.plane_final", self.lr.plane_final),
            ("lr.weight_decay", self.lr.weight_decay),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "a finite number >= 0", &v);
            }
        }
        Ok(())
    }
}
