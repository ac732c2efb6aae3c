//! Deformable 3D Gaussians (Yang et al., CVPR 2024; code
//! ingra14m/Deformable-3D-Gaussians), the base representation of the paper's
//! plug-in experiment (Sec. 5, Tab. 6-7 on SpeeDe3DGS, which builds on it).
//!
//! Canonical 3D Gaussians (centre x, log-scale, quaternion q, opacity logit, SH) and
//! one deformation MLP `D`. At time t (`gaussian_renderer.render`,
//! `DeformNetwork.forward`):
//!
//! - `e_x = PE(sg(x))` (10 frequencies, 63 values), `e_t = T(PE(t))` with the time
//!   network `T: 13 -> 256 -> 30` (D-NeRF's `is_blender` setting);
//! - `h = relu(W_i h + b_i)` for `depth` layers from `h_0 = [e_x, e_t]`, with
//!   `[e_x, e_t, h]` fed on after layer `depth / 2` (the skip);
//! - `[dx, dq, ds] = W_head h + b_head`;
//! - `mu(t) = x + dx`, `q(t) = q / |q| + dq` (normalised again by the renderer),
//!   `s(t) = exp(log s) + ds` (the residual is added to the *activated* scale, as the
//!   reference does; the renderer only uses `s^2`), opacity and SH unchanged.
//!
//! `sg` = stop-gradient: the network sees the canonical centre as a constant, so
//! the centre's gradient comes only through `mu(t) = x + dx`. For iterations
//! `< warm_up` the model renders the canonical Gaussians (no network).
//!
//! With `group_flow.groups > 0`, from iteration `group_flow.at` on the Gaussians
//! follow SpeeDe3DGS's GroupFlow instead of the MLP (module `group_flow` gives the
//! fit): Gaussian i of group g, with stored centre x and knot-0 offset o (the MLP's
//! `dx` at t = 0 when the groups were fitted), sits at
//! `mu(t) = x + R_g(t) (sg(x) + o - n_g) + n_g + T_g(t) - sg(x)` (the reference's
//! `x + d_xyz` with `d_xyz` computed from the detached centre), scale
//! `exp(log s) + ds_0` and quaternion `r_g(t) (q / |q| + dq_0)`, where `ds_0`, `dq_0`
//! are the MLP's residuals at t = 0 when the groups were fitted and `r_g(t)` the
//! group's turn (maaf's: the reference drops the residuals, and turns the quaternion
//! only with `gflow_local_rot`; on mutant dropping them cost 20 dB at the switch).
//! The nodes `n_g` = fitted centroid + a trained offset.
//!
//! maaf's, not the reference's: the head starts at zero (PyTorch's default
//! initialisation there), so the first dynamic iteration renders the warmed-up
//! scene unchanged instead of a random deformation of it.

mod bound;
mod config;
mod group_flow;
mod grouped;
mod rigid_fit;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_group_flow;

use std::sync::Arc;

use maaf_autodiff::nn::Mlp;
use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, Tape, Tensor};

use super::{Bound, CanonicalIds, InitialGaussians, PointCloud, Representation, TrainingHooks};
use crate::params::{BoundParams, MlpParams, ParamId, ParamStore, Rows};

pub use bound::DeformBound;
pub use config::{DeformConfig, DeformLr, GroupFlowConfig};
pub use group_flow::GroupFlow;
pub use grouped::{Grouped, KnotZero};

/// Where each parameter sits in the store.
#[derive(Clone, Debug, PartialEq)]
pub struct DeformIds {
    /// Canonical centres \[N,3].
    pub xyz: ParamId,
    /// Log-scales \[N,3].
    pub log_scale: ParamId,
    /// Quaternions \[N,4] (w, x, y, z), unnormalised.
    pub rotation: ParamId,
    /// Opacity logits \[N].
    pub opacity: ParamId,
    /// SH DC \[N,1,3].
    pub sh_dc: ParamId,
    /// Higher SH bands \[N,K-1,3], absent at degree 0.
    pub sh_rest: Option<ParamId>,
    /// Time network `PE(t) -> time_width -> time_out` (absent when `time_width` is 0).
    pub time_net: Option<MlpParams>,
    /// Layers up to and including the skip layer `depth / 2` (with `skip`), else
    /// every layer and the head.
    pub trunk: MlpParams,
    /// Layers after the skip and the 10-output head (`None` without `skip`).
    pub after_skip: Option<MlpParams>,
    /// Trained offsets of the GroupFlow nodes \[groups, 3] (with `group_flow.groups > 0`).
    pub group_nodes: Option<ParamId>,
}

/// The Deformable-3DGS model: parameters, where each one is, and its stage.
#[derive(Clone, Debug)]
pub struct DeformModel<T: Float> {
    /// Configuration.
    pub config: DeformConfig,
    /// Every trainable tensor.
    pub params: ParamStore<T>,
    /// Where each one is.
    pub ids: DeformIds,
    dynamic: bool,
    /// Number of training frames (the GroupFlow knots follow it; 0 = unknown).
    frames: usize,
    /// The GroupFlow stage, once fitted.
    grouped: Option<Arc<Grouped>>,
    /// Group buffers of a checkpoint, kept until all of them have arrived.
    pending: Vec<(String, Tensor<T>)>,
    /// Test-only: treat `|q|` as a constant in the backward (negative control).
    #[cfg(test)]
    detach_norm: bool,
}

impl<T: Float> DeformModel<T> {
    /// Initialises from a point cloud (3DGS `create_from_pcd`): centres = points,
    /// scale = sqrt of the mean squared distance to the 3 nearest neighbours (log,
    /// clamped to \[-10, 1]), identity rotation, opacity 0.1, SH DC from the colour, zero
    /// higher bands, and a fresh network (PyTorch's default initialisation, zero head).
    pub fn from_point_cloud(cloud: &PointCloud, config: DeformConfig, seed: u64) -> Self {
        let g = InitialGaussians::<T>::from_cloud(cloud, config.sh_coeffs());
        let lr = config.lr.clone();
        let s = config.spatial_lr_scale;
        let mut p = ParamStore::new();
        let mut pg =
            |name: &str, t: Tensor<T>, lr: LrSchedule| p.add(name, t, Rows::PerGaussian, lr, 0.0);
        let xyz = pg(
            "xyz",
            g.xyz,
            LrSchedule::ExpDecay {
                init: lr.position_init * s,
                last: lr.position_final * s,
                max_steps: lr.position_max_steps,
            },
        );
        let log_scale = pg("log_scale", g.log_scale, LrSchedule::Constant(lr.scaling));
        let rotation = pg("rotation", g.rotation, LrSchedule::Constant(lr.rotation));
        let opacity = pg("opacity", g.opacity, LrSchedule::Constant(lr.opacity));
        let sh_dc = pg("sh_dc", g.sh_dc, LrSchedule::Constant(lr.feature));
        let sh_rest = (config.sh_coeffs() > 1).then(|| {
            pg(
                "sh_rest",
                g.sh_rest,
                LrSchedule::Constant(lr.feature / 20.0),
            )
        });
        let net_lr = LrSchedule::ExpDecay {
            init: lr.deform_init,
            last: lr.deform_final,
            max_steps: lr.deform_max_steps,
        };
        let seed = seed.wrapping_mul(0x9E37_79B9);
        let mut mlp = |name: &str, widths: &[usize], zero_head: bool, s: u64| {
            let net = Mlp::new(widths, zero_head, seed.wrapping_add(s));
            MlpParams::add(&mut p, name, net, &net_lr, 0.0)
        };
        let c = &config;
        let time_net = (c.time_width > 0).then(|| {
            mlp(
                "time_net",
                &[1 + 2 * c.t_freqs, c.time_width, c.time_out],
                false,
                1,
            )
        });
        let (trunk, after_skip) = match c.network_widths() {
            (trunk, Some(rest)) => (
                mlp("deform_trunk", &trunk, false, 2),
                Some(mlp("deform_head", &rest, true, 3)),
            ),
            (all, None) => (mlp("deform", &all, true, 2), None),
        };
        let group_nodes = (config.group_flow.groups > 0).then(|| {
            p.add(
                "group_nodes",
                Tensor::zeros(&[config.group_flow.groups, 3]),
                Rows::Shared,
                LrSchedule::Constant(config.group_flow.node_lr),
                0.0,
            )
        });
        DeformModel {
            config,
            params: p,
            ids: DeformIds {
                xyz,
                log_scale,
                rotation,
                opacity,
                sh_dc,
                sh_rest,
                time_net,
                trunk,
                after_skip,
                group_nodes,
            },
            dynamic: false,
            frames: 0,
            grouped: None,
            pending: Vec::new(),
            #[cfg(test)]
            detach_norm: false,
        }
    }

    /// Sets the number of training frames, which fixes the GroupFlow knots
    /// (`min(frames, group_flow.max_knots)`, at least 2).
    pub fn set_frames(&mut self, frames: usize) {
        self.frames = frames;
    }

    /// The fitted GroupFlow stage, if reached.
    pub fn grouped(&self) -> Option<&Grouped> {
        self.grouped.as_deref()
    }

    /// Fits the groups to the MLP's motion now (normally at iteration
    /// `group_flow.at`, from [`Representation::set_iteration`]), with one knot per
    /// training frame up to `max_knots` (`max_knots` when the frames are unknown).
    pub fn fit_groups(&mut self) {
        self.grouped = None;
        let cap = self.config.group_flow.max_knots;
        let knots = if self.frames == 0 {
            cap
        } else {
            self.frames.min(cap)
        }
        .max(2);
        let times: Vec<f64> = (0..knots).map(|k| k as f64 / (knots - 1) as f64).collect();
        let centres = Representation::centres_at_times(self, &times);
        let tape = Tape::new();
        let params = self.params.bind_constants(&tape);
        let bound = self.bind_deform(&params);
        let at0 = bound.deform(0.0);
        let canonical = bound.deform_canonical();
        let groups = self.config.group_flow.groups;
        let fitted = Grouped::fit(
            &KnotZero {
                stored: self.params.value(self.ids.xyz),
                scales: &canonical.scales.value(),
                unit_quats: &canonical.quats.value(),
                scales_at_0: &at0.scales.value(),
                quats_at_0: &at0.quats.value(),
            },
            &centres,
            groups,
        );
        drop(bound);
        drop(params);
        self.grouped = Some(Arc::new(fitted));
    }

    /// Whether the network is used (iteration >= `warm_up`, before GroupFlow).
    pub fn is_dynamic(&self) -> bool {
        self.dynamic && self.grouped.is_none()
    }

    /// Forces the stage (normally set by [`Representation::set_iteration`]).
    pub fn set_dynamic(&mut self, on: bool) {
        self.dynamic = on;
    }

    /// Scalars of the deformation network (time network included).
    pub fn network_params(&self) -> usize {
        let p = &self.params;
        let mut n = self.ids.trunk.num_params(p);
        n += self.ids.group_nodes.map_or(0, |id| p.value(id).len());
        n += self.ids.after_skip.as_ref().map_or(0, |m| m.num_params(p));
        n + self.ids.time_net.as_ref().map_or(0, |m| m.num_params(p))
    }

    /// Binds on the tape of `params` with the concrete type.
    pub fn bind_deform<'t>(&self, params: &BoundParams<'t, T>) -> DeformBound<'t, T> {
        DeformBound::new(self, params)
    }
}

impl<T: Float> Representation<T> for DeformModel<T> {
    fn name(&self) -> &str {
        "deform"
    }

    fn label(&self) -> String {
        let name = Representation::<T>::name(self);
        match self.config.group_flow.groups {
            0 => name.into(),
            g => format!("{name} + GroupFlow ({g} groups)"),
        }
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
        Box::new(self.bind_deform(params))
    }

    /// Static for iterations `< warm_up`, deformed from then on (Deformable-3DGS
    /// `train.py`: `if iteration < opt.warm_up: d_xyz = 0`); with GroupFlow, the groups
    /// are fitted at iteration `group_flow.at` (SpeeDe3DGS `train.py`:
    /// `if iteration == opt.gflow_iteration: do_group_flow`), or at the first
    /// iteration after it that finds them unfitted: a branch from a checkpoint past
    /// `at` of a run without GroupFlow (a restored GroupFlow checkpoint has loaded its
    /// saved groups before this is called, so it is not fitted again).
    fn set_iteration(&mut self, iteration: usize) {
        self.dynamic = iteration >= self.config.warm_up;
        let g = &self.config.group_flow;
        if g.groups > 0 && iteration >= g.at && self.grouped.is_none() {
            self.fit_groups();
        }
    }

    /// GroupFlow's tables, once fitted ([`TrainingHooks`]).
    fn hooks(&self) -> Option<&dyn TrainingHooks<T>> {
        Some(self)
    }

    fn hooks_mut(&mut self) -> Option<&mut dyn TrainingHooks<T>> {
        Some(self)
    }
}

/// GroupFlow's tables: per-Gaussian state outside the store (each Gaussian's group and
/// knot-0 residuals), resized with the rows, counted in the model's size and carried
/// in checkpoints as buffers. Nothing before the groups are fitted.
impl<T: Float> TrainingHooks<T> for DeformModel<T> {
    fn select_state_rows(&mut self, index: &[usize]) {
        if let Some(g) = &mut self.grouped {
            Arc::make_mut(g).select_rows(index);
        }
    }

    /// The GroupFlow tables once fitted.
    fn state_scalars(&self) -> usize {
        self.grouped.as_ref().map_or(0, |g| g.num_scalars())
    }

    fn buffers(&self) -> Vec<(String, Tensor<T>)> {
        self.grouped
            .as_ref()
            .map_or_else(Vec::new, |g| g.to_buffers())
    }

    /// Collects the GroupFlow buffers; the stage is restored once all have arrived.
    fn load_buffer(&mut self, name: &str, value: Tensor<T>) -> Result<(), String> {
        if !Grouped::BUFFERS.contains(&name) {
            return Err(format!("deform has no buffer `{name}`"));
        }
        self.pending.retain(|(n, _)| n != name);
        self.pending.push((name.to_string(), value));
        if self.pending.len() == Grouped::BUFFERS.len() {
            let n = self.params.value(self.ids.xyz).rows();
            let g = Grouped::from_buffers(std::mem::take(&mut self.pending), n)?;
            self.grouped = Some(Arc::new(g));
        }
        Ok(())
    }
}
