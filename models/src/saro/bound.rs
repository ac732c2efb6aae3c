//! A SaRO model bound on a tape: the time-independent work of one step (field
//! features, lifespans, L_SR) and the deformation at any time t (module docs of
//! [`super`] give the formulas).

use std::sync::Arc;

use maaf_autodiff::nn::MlpVars;
use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::ops::concat;
use maaf_autodiff::{Float, Tensor, Var};
use maaf_splat::GaussianVars;
use maaf_splat::compositing::drawable;

use super::SaroModel;
use super::residuals::{ApplyResiduals, SaroInput, saro_input};
use crate::Bound;
use crate::params::BoundParams;

/// Name under which SaRO provides its scale-residual regulariser
/// `L_SR = ||Delta log s (t = mu_t)||_2` (SaRO-GS `helper_train.py::getloss`).
pub const L_SR: &str = "l_sr";

/// A SaRO model bound on a tape (see [`Bound`]).
pub struct SaroBound<'t, T: Float> {
    time_freqs: usize,
    xyz: Var<'t, T>,
    log_scale: Var<'t, T>,
    rotation: Var<'t, T>,
    opacity: Var<'t, T>,
    sh: Var<'t, T>,
    dynamic: Option<DynamicVars<'t, T>>,
}

struct DynamicVars<'t, T: Float> {
    t_centre: Var<'t, T>,
    features: Var<'t, T>,
    lifespan: Var<'t, T>,
    t_centre_detached: Arc<Vec<f64>>,
    motion: MlpVars<'t, T>,
    rot: MlpVars<'t, T>,
    sh: Option<MlpVars<'t, T>>,
    l_sr: Var<'t, T>,
}

impl<'t, T: Float> SaroBound<'t, T> {
    /// Binds `model` on the tape of `p`. The field query and sg(mu_t) are read from
    /// the model's stored values (stop-gradient inputs).
    pub(super) fn new(model: &SaroModel<T>, p: &BoundParams<'t, T>) -> Self {
        let ids = &model.ids;
        let n = model.num_rows();
        let sh = match ids.sh_rest {
            Some(rest) => concat(&[p.get(ids.sh_dc), p.get(rest)], 1),
            None => p.get(ids.sh_dc),
        };
        let opacity = p.get(ids.opacity).sigmoid();
        let dynamic = model.is_dynamic().then(|| {
            let tape = p.get(ids.xyz).tape();
            let planes = ids.planes.map(|id| p.get(id));
            let features = model.field_features(&planes);
            let life = ids.life.bind(p);
            let lifespan = model.lifespan_of(&life, features);
            // L_SR: the scale residual at Dt = 0, i.e. PE(0), on every row.
            let h0 = saro_input(
                features,
                SaroInput::every_row(n, 0.0, model.config.time_freqs),
            );
            let rot = ids.rot.bind(p);
            let l_sr = tape.apply1(Norm2, &[rot.forward(h0).slice(1, 4, 7)]);
            DynamicVars {
                t_centre: p.get(ids.t_centre),
                features,
                lifespan,
                t_centre_detached: Arc::new(model.t_centre_f64()),
                motion: ids.motion.bind(p),
                rot,
                sh: ids.sh.as_ref().map(|m| m.bind(p)),
                l_sr,
            }
        });
        SaroBound {
            time_freqs: model.config.time_freqs,
            xyz: p.get(ids.xyz),
            log_scale: p.get(ids.log_scale),
            rotation: p.get(ids.rotation),
            opacity,
            sh,
            dynamic,
        }
    }

    /// Lifespans l \[N] (None in the static stage).
    pub fn lifespan(&self) -> Option<Var<'t, T>> {
        self.dynamic.as_ref().map(|d| d.lifespan)
    }

    /// Field features \[N, C] (None in the static stage).
    pub fn features(&self) -> Option<Var<'t, T>> {
        self.dynamic.as_ref().map(|d| d.features)
    }

    /// `L_SR` (None in the static stage).
    pub fn l_sr(&self) -> Option<Var<'t, T>> {
        self.dynamic.as_ref().map(|d| d.l_sr)
    }
}

impl<'t, T: Float> Bound<'t, T> for SaroBound<'t, T> {
    fn deform(&self, time: f64) -> GaussianVars<'t, T> {
        let Some(d) = &self.dynamic else {
            return GaussianVars {
                means: self.xyz,
                scales: self.log_scale.exp(),
                quats: self.rotation,
                opacity: self.opacity,
                sh: self.sh,
            };
        };
        // w(t) = exp(-4 ((t - mu_t) / l)^2), gradient to mu_t and (via l) the field.
        let dt = d.t_centre.scale(-1.0).add_scalar(time);
        let w = (dt / d.lifespan).square().scale(-4.0).exp();
        let opacity = self.opacity * w;
        // The residual MLPs run only for the Gaussians that exist at t: one whose
        // opacity o(t) has no support (`255 o <= 1`) is never drawn (the 2D and 3D
        // filters only lower opacity), so its residuals are zero and its gradients
        // are exactly those of the full evaluation.
        let present: Arc<[usize]> = present_rows(&opacity.value()).into();
        let dt = present
            .iter()
            .map(|&i| time - d.t_centre_detached[i])
            .collect();
        let h = saro_input(
            d.features,
            SaroInput {
                rows: present.clone(),
                dt,
                freqs: self.time_freqs,
            },
        );
        let mut inputs = vec![
            self.xyz,
            self.rotation,
            self.log_scale,
            d.motion.forward(h),
            d.rot.forward(h),
        ];
        if let Some(m) = &d.sh {
            inputs.extend([self.sh, m.forward(h)]);
        }
        let out = self
            .xyz
            .tape()
            .apply(ApplyResiduals { rows: present }, &inputs);
        let (means, quats, scales) = (out[0], out[1], out[2]);
        let sh = out.get(3).copied().unwrap_or(self.sh);
        GaussianVars {
            means,
            scales,
            quats,
            opacity,
            sh,
        }
    }

    fn regularisers(&self) -> Vec<(String, Var<'t, T>)> {
        match &self.dynamic {
            Some(d) => vec![(L_SR.to_string(), d.l_sr)],
            None => Vec::new(),
        }
    }
}

/// Rows whose opacity `o` can reach the image ([`maaf_splat::compositing::drawable`],
/// the renderer's own rule).
pub fn present_rows<T: Float>(opacity: &Tensor<T>) -> Vec<usize> {
    drawable(opacity.data())
        .into_iter()
        .enumerate()
        .filter_map(|(i, d)| d.then_some(i))
        .collect()
}

/// `||x||_2` over all elements, with the subgradient 0 at x = 0 (as
/// `torch.linalg.vector_norm`): backward `g x / ||x||`. L_SR needs it because the
/// scale residual is exactly zero at initialisation, where `sqrt(sum x^2)` has an
/// infinite derivative.
pub struct Norm2;

impl<T: Float> Op<T> for Norm2 {
    type Saved = ();
    fn name(&self) -> String {
        "norm2".into()
    }
    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let s: T = x[0].data().iter().map(|&v| v * v).sum();
        (vec![Tensor::scalar(s.sqrt())], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let norm = c.outputs[0].item();
        let g = c.grad_outputs[0].item();
        let k = if norm > T::zero() {
            g / norm
        } else {
            T::zero()
        };
        vec![Some(c.inputs[0].map(|v| v * k))]
    }
}
