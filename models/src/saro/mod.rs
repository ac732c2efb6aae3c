//! SaRO-GS (Yan et al., ACM MM 2024; code yjb6/SaRO-GS `scene/saro_gaussian.py`), the
//! base 4D representation of the paper (Sec. 3.2).
//!
//! Each Gaussian is a 3D Gaussian (centre, log-scale, quaternion, opacity logit, SH)
//! plus a temporal centre mu_t. At time t (`get_deformation`):
//!
//! - field features `f = F(sg(x), sg(mu_t), sg(s))` from the scale-aware K-plane field
//!   ([`super::kplane`]), `sg` = stop-gradient;
//! - lifespan `l = (1 - m)(1 - sigmoid(MLP_l(f))) + m`, `m = min_interval / duration`;
//! - `Dt = t - mu_t`, input `h = \[f, sg(PE(Dt))]`, PE = NeRF embedding with the
//!   identity and `sin, cos(2^k Dt)`, k < 4 (9 values);
//! - `mu(t) = x + MLP_x(h)`, `\[dq, ds] = MLP_r(h)`, `q(t) = q + dq` (normalised by the
//!   renderer), `s(t) = exp(log s + ds)`, `SH(t) = SH + MLP_sh(h)` (optional);
//! - opacity `sigmoid(o) * exp(-4 (Dt / l)^2)` (the code's "Eq 9").
//!
//! `L_SR = || ds at Dt = 0 ||_2` over all N x 3 entries, not squared, not averaged
//! (`helper_train.py`, `torch.linalg.vector_norm`), weight 8e-6. The residual heads
//! start at zero (docs/decisions.md), so at step 0 the deformed scene is the
//! canonical one with the temporal opacity factor. For the first `static_iterations`
//! the model renders plain 3D Gaussians (no field, no MLP, no temporal opacity).

mod bound;
mod config;
mod lifespan;
mod residuals;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_residuals;

use std::sync::Arc;

use maaf_autodiff::nn::Mlp;
use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, Tape, Tensor};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::kplane::{KPlaneField, PLANE_NAMES};
use super::{Bound, CanonicalIds, InitialGaussians, PointCloud, Representation, TrainingHooks};
use crate::params::{BoundParams, MlpParams, ParamId, ParamStore, Rows};

pub use bound::{Norm2, SaroBound};
pub use residuals::{ApplyResiduals, SaroInput, saro_input};

/// Checkpoint name of the adaptive-optimisation scale.
const ADAPTIVE: &str = "adaptive_lr_scale";
pub use config::{SaroConfig, SaroLr};

/// Where each SaRO parameter sits in the store.
#[derive(Clone, Debug, PartialEq)]
pub struct SaroIds {
    /// Canonical centres \[N,3] (`_xyz`).
    pub xyz: ParamId,
    /// Log-scales \[N,3] (`_scaling`).
    pub log_scale: ParamId,
    /// Quaternions \[N,4], w,x,y,z, unnormalised (`_rotation`).
    pub rotation: ParamId,
    /// Opacity logits \[N] (`_opacity`).
    pub opacity: ParamId,
    /// SH DC \[N,1,3] (`_features_dc`).
    pub sh_dc: ParamId,
    /// Higher SH bands \[N,K-1,3] (`_features_rest`), absent at degree 0.
    pub sh_rest: Option<ParamId>,
    /// Temporal centres \[N] (`_temporal_pos`, not squashed: `sigmoid_tcenter` false).
    pub t_centre: ParamId,
    /// The six field planes, [`PLANE_NAMES`] order.
    pub planes: [ParamId; 6],
    /// `motion_mlp`: \[f, PE] -> dx (3).
    pub motion: MlpParams,
    /// `rot_mlp`: \[f, PE] -> dq (4), d log s (3).
    pub rot: MlpParams,
    /// `shs_mlp`: \[f, PE] -> dSH (3K), when `sh_residual`.
    pub sh: Option<MlpParams>,
    /// `opacity_mlp`: f -> lifespan logit (1).
    pub life: MlpParams,
}

/// The SaRO-GS model: the parameters, where each one is, and the field layout.
#[derive(Clone, Debug)]
pub struct SaroModel<T: Float> {
    /// Configuration.
    pub config: SaroConfig,
    /// Scene extent: scales the position learning rate (3DGS `spatial_lr_scale`).
    pub scene_extent: f64,
    /// Every trainable tensor.
    pub params: ParamStore<T>,
    /// Where each one is.
    pub ids: SaroIds,
    /// Layout and normalisation box of the residual field.
    pub field: KPlaneField,
    dynamic: bool,
    /// The adaptive-optimisation scale `I_max / I` per Gaussian, as last computed
    /// (`None` in the static stage, before the first refresh, or when turned off).
    adaptive: Option<Arc<[T]>>,
    /// Test-only: bind the field with a deliberately wrong backward (negative control).
    #[cfg(test)]
    corrupt_field_backward: bool,
}

impl<T: Float> SaroModel<T> {
    /// Initialises from a point cloud (SaRO-GS `create_from_pcd`): centres = points,
    /// scale = sqrt of the mean squared distance to the 3 nearest neighbours (log,
    /// clamped to \[-10, 1]), identity rotation, opacity 0.1 (as a logit), SH DC from the
    /// colour and zero higher bands, mu_t ~ U(0, 1) (or the points' own times when
    /// the cloud has them, as SpacetimeGS starts its temporal centres; SaRO-GS draws
    /// them at random even then), zero planes normalised by the
    /// cloud's bounds, residual heads zero, lifespan MLP with PyTorch's default init.
    pub fn from_point_cloud(
        cloud: &PointCloud,
        config: SaroConfig,
        scene_extent: f64,
        seed: u64,
    ) -> Self {
        let n = cloud.len();
        let g = InitialGaussians::<T>::from_cloud(cloud, config.sh_coeffs());
        let mut rng = Pcg64::seed_from_u64(seed);
        let t_centre: Vec<T> = match &cloud.times {
            Some(times) => times.iter().map(|&t| T::of(t)).collect(),
            None => (0..n).map(|_| T::of(rng.random_range(0.0..1.0))).collect(),
        };
        let (lo, hi) = cloud.bounds();
        let field = KPlaneField::new(config.field.clone(), lo, hi);
        let per_gaussian = [
            g.xyz,
            g.log_scale,
            g.rotation,
            g.opacity,
            g.sh_dc,
            g.sh_rest,
            Tensor::from_vec(t_centre, &[n]),
        ];
        Self::assemble(config, scene_extent, per_gaussian, field, seed)
    }

    /// Builds the model around given per-Gaussian tensors (xyz, log_scale, rotation,
    /// opacity, sh_dc, sh_rest, t_centre) and field layout, with zero planes and fresh
    /// MLPs (zero heads). Declares every parameter in the store, in the order the
    /// checkpoints and gradient checks see them.
    pub fn assemble(
        config: SaroConfig,
        scene_extent: f64,
        per_gaussian: [Tensor<T>; 7],
        field: KPlaneField,
        seed: u64,
    ) -> Self {
        let [xyz, log_scale, rotation, opacity, sh_dc, sh_rest, t_centre] = per_gaussian;
        let lr = config.lr.clone();
        let decay = |init: f64, last: f64| LrSchedule::ExpDecay {
            init,
            last,
            max_steps: lr.max_steps,
        };
        let ext = scene_extent;
        let mut p = ParamStore::new();
        let pg =
            |p: &mut ParamStore<T>, name: &str, t, lr| p.add(name, t, Rows::PerGaussian, lr, 0.0);
        let xyz = pg(
            &mut p,
            "xyz",
            xyz,
            decay(lr.position_init * ext, lr.position_final * ext),
        );
        let log_scale = pg(
            &mut p,
            "log_scale",
            log_scale,
            LrSchedule::Constant(lr.scaling),
        );
        let rotation = pg(
            &mut p,
            "rotation",
            rotation,
            LrSchedule::Constant(lr.rotation),
        );
        let opacity = pg(&mut p, "opacity", opacity, LrSchedule::Constant(lr.opacity));
        let sh_dc = pg(&mut p, "sh_dc", sh_dc, LrSchedule::Constant(lr.feature));
        let sh_rest = (config.sh_coeffs() > 1).then(|| {
            pg(
                &mut p,
                "sh_rest",
                sh_rest,
                LrSchedule::Constant(lr.feature / 20.0),
            )
        });
        let t_centre = pg(
            &mut p,
            "t_centre",
            t_centre,
            LrSchedule::Constant(lr.t_centre),
        );
        let planes_lr = decay(lr.plane_init, lr.plane_final);
        let mut zero = field.zero_planes::<T>().into_iter();
        let planes = PLANE_NAMES.map(|name| {
            let plane = zero.next().expect("six planes");
            p.add(
                &format!("field.{name}"),
                plane,
                Rows::Shared,
                planes_lr.clone(),
                lr.weight_decay,
            )
        });
        let c = config.field.channels;
        let h = config.hidden;
        let input = c + config.pe_dim();
        let k = config.sh_coeffs();
        let seed = seed.wrapping_mul(0x9E37_79B9);
        let mlp_lr = decay(lr.mlp_init, lr.mlp_final);
        let wd = lr.weight_decay;
        let mlp = |p: &mut ParamStore<T>, name: &str, widths: &[usize], zero, s: u64| {
            let net = Mlp::new(widths, zero, seed.wrapping_add(s));
            MlpParams::add(p, name, net, &mlp_lr, wd)
        };
        let motion = mlp(&mut p, "motion_mlp", &[input, h, h, 3], true, 1);
        let rot = mlp(&mut p, "rot_mlp", &[input, h, h, 7], true, 2);
        let sh = config
            .sh_residual
            .then(|| mlp(&mut p, "sh_mlp", &[input, h, h, 3 * k], true, 3));
        let life = mlp(&mut p, "life_mlp", &[c, h, (h / 2).max(1), 1], false, 4);
        SaroModel {
            config,
            scene_extent,
            params: p,
            ids: SaroIds {
                xyz,
                log_scale,
                rotation,
                opacity,
                sh_dc,
                sh_rest,
                t_centre,
                planes,
                motion,
                rot,
                sh,
                life,
            },
            field,
            dynamic: false,
            adaptive: None,
            #[cfg(test)]
            corrupt_field_backward: false,
        }
    }

    /// Whether the dynamic stage (field + MLPs + temporal opacity) is on.
    pub fn is_dynamic(&self) -> bool {
        self.dynamic
    }

    /// Forces the stage (normally set by [`Representation::set_iteration`]).
    pub fn set_dynamic(&mut self, on: bool) {
        self.dynamic = on;
    }

    /// Binds on the tape of `params` with the concrete type (gives access to
    /// lifespans, features and L_SR; [`Representation::bind`] boxes it).
    pub fn bind_saro<'t>(&self, params: &BoundParams<'t, T>) -> SaroBound<'t, T> {
        SaroBound::new(self, params)
    }
}

impl<T: Float> Representation<T> for SaroModel<T> {
    fn name(&self) -> &str {
        "saro"
    }

    fn params(&self) -> &ParamStore<T> {
        &self.params
    }

    fn params_mut(&mut self) -> &mut ParamStore<T> {
        &mut self.params
    }

    fn canonical_ids(&self) -> CanonicalIds {
        CanonicalIds {
            means: self.ids.xyz,
            log_scales: self.ids.log_scale,
            quats: self.ids.rotation,
            opacity_logits: self.ids.opacity,
        }
    }

    fn bind<'t>(&self, params: &BoundParams<'t, T>) -> Box<dyn Bound<'t, T> + 't> {
        Box::new(self.bind_saro(params))
    }

    /// `l_sr` with `lambda_sr` (SaRO-GS `lambda_dscale_reg` 8e-6).
    fn regularisers(&self) -> Vec<(String, f64)> {
        vec![(bound::L_SR.to_string(), self.config.lambda_sr)]
    }

    /// Static stage for iterations `<= static_iterations`, dynamic after (SaRO-GS
    /// `train.py`: `if iteration > opt.static_iteration: stage = "dynamatic"`).
    ///
    /// In the dynamic stage, every `adaptive_every` iterations, the adaptive scale is
    /// recomputed from the parameters at the start of the iteration (SaRO-GS
    /// `update_learning_rate`, called before the step).
    fn set_iteration(&mut self, iteration: usize) {
        self.dynamic = iteration > self.config.static_iterations;
        let every = self.config.adaptive_every;
        if !self.dynamic || every == 0 {
            self.adaptive = None;
        } else if iteration.is_multiple_of(every) {
            self.adaptive = Some(self.adaptive_scale().into());
        }
    }

    /// `x + MLP_x(\[f, PE(t - mu_t)])` per time, with the field queried once and only
    /// the motion MLP evaluated (one small scratch tape per time, so memory stays
    /// O(N H)). In the static stage the centres do not move.
    fn centres_at_times(&self, times: &[f64]) -> Vec<Tensor<T>> {
        let xyz = self.params.value(self.ids.xyz);
        if !self.dynamic {
            return times.iter().map(|_| xyz.clone()).collect();
        }
        let features = self.features_now();
        let t_centre = self.params.value(self.ids.t_centre);
        times
            .iter()
            .map(|&time| {
                let tape = Tape::<T>::new();
                let dt = t_centre
                    .data()
                    .iter()
                    .map(|&m| time - Float::to_f64(m))
                    .collect();
                let h = saro_input(
                    tape.constant(features.clone()),
                    SaroInput {
                        rows: (0..xyz.rows()).collect(),
                        dt,
                        freqs: self.config.time_freqs,
                    },
                );
                let dx = self
                    .ids
                    .motion
                    .bind_constants(&self.params, &tape)
                    .forward(h);
                // The binding ends the borrow of the tape before the tape is dropped.
                #[allow(clippy::let_and_return)]
                let centres = (tape.constant(xyz.clone()) + dx).value().clone();
                centres
            })
            .collect()
    }

    /// SaRO's adaptive optimisation and temporal pruning ([`TrainingHooks`]).
    fn hooks(&self) -> Option<&dyn TrainingHooks<T>> {
        Some(self)
    }

    fn hooks_mut(&mut self) -> Option<&mut dyn TrainingHooks<T>> {
        Some(self)
    }
}

/// The adaptive scale (per-Gaussian learning-rate and densification-statistic
/// multipliers, kept as a checkpoint buffer and resized with the rows) and the
/// temporal pruning.
impl<T: Float> TrainingHooks<T> for SaroModel<T> {
    /// The adaptive scale for centre, opacity, temporal centre, rotation and SH DC
    /// (while densifying, or always with `adaptive_after_densify`) and for the
    /// log-scale (while densifying only: SaRO-GS stops it then "to ensure stability";
    /// never with `adaptive_log_scale` off).
    fn lr_row_scale(&self, name: &str, densifying: bool) -> Option<Arc<[T]>> {
        let on = match name {
            "xyz" | "opacity" | "t_centre" | "rotation" | "sh_dc" => {
                densifying || self.config.adaptive_after_densify
            }
            "log_scale" => densifying && self.config.adaptive_log_scale,
            _ => false,
        };
        self.adaptive.clone().filter(|_| on)
    }

    /// The adaptive scale (SaRO-GS `densify_pruneclone`: `grads * inv_intergral`).
    fn densify_grad_scale(&self) -> Option<Arc<[T]>> {
        self.adaptive.clone()
    }

    /// The adaptive scale, so that a resumed run continues with the one computed
    /// before the checkpoint (it is refreshed only every `adaptive_every`).
    fn buffers(&self) -> Vec<(String, Tensor<T>)> {
        self.adaptive
            .iter()
            .map(|a| {
                (
                    ADAPTIVE.to_string(),
                    Tensor::from_vec(a.to_vec(), &[a.len()]),
                )
            })
            .collect()
    }

    fn load_buffer(&mut self, name: &str, value: Tensor<T>) -> Result<(), String> {
        let n = self.num_rows();
        if name != ADAPTIVE {
            return Err(format!("saro has no buffer `{name}`"));
        }
        if value.shape() != [n] {
            return Err(format!(
                "buffer `{name}` has shape {:?}, expected [{n}]",
                value.shape()
            ));
        }
        self.adaptive = Some(value.data().into());
        Ok(())
    }

    /// Resizes the adaptive scale (a clone or split half keeps its parent's scale
    /// until the next refresh).
    fn select_state_rows(&mut self, index: &[usize]) {
        if let Some(a) = &self.adaptive {
            self.adaptive = Some(index.iter().map(|&i| a[i]).collect());
        }
    }

    /// Gaussians whose temporal integral is below `min_integral` (SaRO-GS prunes them
    /// every 50 iterations of the dynamic stage and at each densification). Empty in
    /// the static stage, where the temporal factor is not used.
    fn short_lived(&self) -> Vec<usize> {
        if !self.dynamic {
            return Vec::new();
        }
        let min = self.config.min_integral;
        self.temporal_integral()
            .iter()
            .enumerate()
            .filter(|&(_, &i)| i.is_nan() || i < min)
            .map(|(k, _)| k)
            .collect()
    }
}
