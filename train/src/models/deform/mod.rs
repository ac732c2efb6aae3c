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
//! Ours, not the reference's: the head starts at zero (PyTorch's default
//! initialisation there), so the first dynamic iteration renders the warmed-up
//! scene unchanged instead of a random deformation of it.

mod bound;
mod config;
#[cfg(test)]
mod tests;

use maaf_autodiff::nn::Mlp;
use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, Tensor};

use super::{Bound, CanonicalIds, InitialGaussians, PointCloud, Representation};
use crate::params::{BoundParams, MlpParams, ParamId, ParamStore, Rows};

pub use bound::DeformBound;
pub use config::{DeformConfig, DeformLr};

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
            },
            dynamic: false,
            #[cfg(test)]
            detach_norm: false,
        }
    }

    /// Whether the network is used (iteration >= `warm_up`).
    pub fn is_dynamic(&self) -> bool {
        self.dynamic
    }

    /// Forces the stage (normally set by [`Representation::set_iteration`]).
    pub fn set_dynamic(&mut self, on: bool) {
        self.dynamic = on;
    }

    /// Scalars of the deformation network (time network included).
    pub fn network_params(&self) -> usize {
        let p = &self.params;
        let mut n = self.ids.trunk.num_params(p);
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
    /// `train.py`: `if iteration < opt.warm_up: d_xyz = 0`).
    fn set_iteration(&mut self, iteration: usize) {
        self.dynamic = iteration >= self.config.warm_up;
    }
}
