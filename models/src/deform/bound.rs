//! A Deformable-3DGS model bound on a tape: the canonical Gaussians and the encoded
//! canonical centres (time-independent, once per step) and the deformation at any
//! time t (module docs of [`super`] give the formulas).

use maaf_autodiff::nn::MlpVars;
use maaf_autodiff::ops::concat;
use maaf_autodiff::{Float, Var};
use maaf_splat::GaussianVars;

use super::DeformModel;
use super::grouped::GroupMotion;
use crate::Bound;
use crate::encoding::positional_encoding;
use crate::params::BoundParams;

/// A Deformable-3DGS model bound on a tape (see [`Bound`]).
pub struct DeformBound<'t, T: Float> {
    xyz: Var<'t, T>,
    scales: Var<'t, T>,
    unit_quats: Var<'t, T>,
    opacity: Var<'t, T>,
    sh: Var<'t, T>,
    net: Option<Network<'t, T>>,
    groups: Option<GroupMotion<'t, T>>,
}

struct Network<'t, T: Float> {
    /// `PE(sg(x))` \[N, x_dim], a constant.
    x_code: Var<'t, T>,
    t_freqs: usize,
    time_net: Option<MlpVars<'t, T>>,
    trunk: MlpVars<'t, T>,
    after_skip: Option<MlpVars<'t, T>>,
}

impl<'t, T: Float> DeformBound<'t, T> {
    /// Binds `model` on the tape of `p`; the network's input `sg(x)` is read from the
    /// model's stored centres (a stop-gradient input).
    pub(super) fn new(model: &DeformModel<T>, p: &BoundParams<'t, T>) -> Self {
        let ids = &model.ids;
        let xyz = p.get(ids.xyz);
        let sh = match ids.sh_rest {
            Some(rest) => concat(&[p.get(ids.sh_dc), p.get(rest)], 1),
            None => p.get(ids.sh_dc),
        };
        let q = p.get(ids.rotation);
        let n = q.value().rows();
        let norm = q.square().sum_axis(1).sqrt().reshape(&[n, 1]);
        #[cfg(test)]
        let norm = if model.detach_norm {
            let value = norm.value().clone();
            q.tape().constant(value)
        } else {
            norm
        };
        let net = model.is_dynamic().then(|| {
            let stored: Vec<f64> = model
                .params
                .value(ids.xyz)
                .data()
                .iter()
                .map(|&v| Float::to_f64(v))
                .collect();
            let code = positional_encoding(&stored, 3, model.config.x_freqs);
            Network {
                x_code: xyz.tape().constant(code),
                t_freqs: model.config.t_freqs,
                time_net: ids.time_net.as_ref().map(|m| m.bind(p)),
                trunk: ids.trunk.bind(p),
                after_skip: ids.after_skip.as_ref().map(|m| m.bind(p)),
            }
        });
        let scales = p.get(ids.log_scale).exp();
        let unit_quats = q / norm;
        let groups = model.grouped.as_ref().map(|g| {
            let offsets = ids.group_nodes.expect("GroupFlow has its node parameter");
            GroupMotion::new(
                g.clone(),
                model.params.value(ids.xyz),
                p.get(offsets),
                [scales, unit_quats],
                model.config.group_flow.rotate_gaussians,
            )
        });
        DeformBound {
            xyz,
            scales,
            unit_quats,
            opacity: p.get(ids.opacity).sigmoid(),
            sh,
            net,
            groups,
        }
    }
}

impl<'t, T: Float> Network<'t, T> {
    /// `[dx, dq, ds]` \[N, 10] at `time`.
    fn residuals(&self, time: f64) -> Var<'t, T> {
        let tape = self.x_code.tape();
        let n = self.x_code.value().rows();
        let t_code = tape.constant(positional_encoding(&[time], 1, self.t_freqs));
        let t_feat = match &self.time_net {
            Some(net) => net.forward(t_code),
            None => t_code,
        };
        // One time row, shared by every Gaussian (its gradient sums over them).
        let input = concat(&[self.x_code, t_feat.gather_rows(&vec![0; n])], 1);
        match &self.after_skip {
            Some(rest) => {
                let h = self.trunk.forward(input).relu();
                rest.forward(concat(&[input, h], 1))
            }
            None => self.trunk.forward(input),
        }
    }
}

impl<'t, T: Float> DeformBound<'t, T> {
    /// The canonical Gaussians: stored centres, activated scales, unit quaternions.
    pub fn deform_canonical(&self) -> GaussianVars<'t, T> {
        GaussianVars {
            means: self.xyz,
            scales: self.scales,
            quats: self.unit_quats,
            opacity: self.opacity,
            sh: self.sh,
        }
    }
}

impl<'t, T: Float> Bound<'t, T> for DeformBound<'t, T> {
    fn deform(&self, time: f64) -> GaussianVars<'t, T> {
        if let Some(groups) = &self.groups {
            let motions = groups.motions(time);
            let (scales, quats) = groups.shape(&motions);
            return GaussianVars {
                means: self.xyz + groups.displacement(&motions),
                scales,
                quats,
                opacity: self.opacity,
                sh: self.sh,
            };
        }
        let Some(net) = &self.net else {
            return self.deform_canonical();
        };
        let d = net.residuals(time);
        GaussianVars {
            means: self.xyz + d.slice(1, 0, 3),
            scales: self.scales + d.slice(1, 7, 10),
            quats: self.unit_quats + d.slice(1, 3, 7),
            opacity: self.opacity,
            sh: self.sh,
        }
    }
}
