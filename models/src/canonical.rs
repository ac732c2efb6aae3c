//! The canonical 3DGS tensors of a representation's [`ParamStore`] and the
//! densification plumbing that reads and writes them (docs/architecture.md, "Where
//! things plug in").
//!
//! Every representation names four of its stored parameters as the canonical 3D
//! Gaussians ([`CanonicalIds`]); densification, the opacity reset and the filters need
//! nothing else, so they work on the store with those ids ([`ParamStore::canonical`],
//! [`ParamStore::set_canonical_rows`], [`ParamStore::cap_opacity`]) and no
//! representation implements them.

use maaf_autodiff::scalar::{logit, sigmoid};
use maaf_autodiff::{Float, Tensor};

use crate::params::{ParamId, ParamStore};

/// Which parameters of a store hold the canonical 3DGS tensors, in 3DGS's
/// parametrisation: centres `[N,3]`, log-scales `[N,3]`, unnormalised quaternions
/// `[N,4]` (w, x, y, z) and opacity logits `[N]`. Densification reads them (scale
/// threshold, split sampling, opacity prune) and writes them (split halves, opacity
/// reset) through the [`ParamStore`] helpers of this module.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CanonicalIds {
    /// Centres.
    pub means: ParamId,
    /// Log-scales (`scale = exp`).
    pub log_scales: ParamId,
    /// Quaternions.
    pub quats: ParamId,
    /// Opacity logits (`opacity = sigmoid`).
    pub opacity_logits: ParamId,
}

/// Canonical (undeformed) per-Gaussian values, activated, as plain tensors: what
/// densification reads.
#[derive(Clone, Debug)]
pub struct Canonical<T: Float> {
    /// Centres \[N,3].
    pub means: Tensor<T>,
    /// Activated scales \[N,3].
    pub scales: Tensor<T>,
    /// Unnormalised quaternions \[N,4] (w,x,y,z).
    pub quats: Tensor<T>,
    /// Activated base opacity \[N] (without any temporal factor).
    pub opacity: Tensor<T>,
}

impl<T: Float> ParamStore<T> {
    /// The canonical values of the parameters `ids` names, activated: scales
    /// `exp(log_scale)`, opacity `sigmoid(logit)`.
    pub fn canonical(&self, ids: CanonicalIds) -> Canonical<T> {
        Canonical {
            means: self.value(ids.means).clone(),
            scales: self.value(ids.log_scales).map(|v| v.exp()),
            quats: self.value(ids.quats).clone(),
            opacity: self.value(ids.opacity_logits).map(sigmoid),
        }
    }

    /// Overwrites the canonical centres and **activated** scales (stored as
    /// `ln(scale)`) of `rows`, once a row selection has created them (e.g. the two
    /// halves of a split). `means` and `scales` are \[rows.len(), 3].
    pub fn set_canonical_rows(
        &mut self,
        ids: CanonicalIds,
        rows: &[usize],
        means: &Tensor<T>,
        scales: &Tensor<T>,
    ) {
        assert_eq!(
            means.shape(),
            &[rows.len(), 3],
            "set_canonical_rows: means shape"
        );
        assert_eq!(
            scales.shape(),
            &[rows.len(), 3],
            "set_canonical_rows: scales shape"
        );
        for (j, &r) in rows.iter().enumerate() {
            for a in 0..3 {
                self.value_mut(ids.means).data_mut()[3 * r + a] = means.data()[3 * j + a];
                self.value_mut(ids.log_scales).data_mut()[3 * r + a] =
                    scales.data()[3 * j + a].ln();
            }
        }
    }

    /// Opacity reset (3DGS `reset_opacity`), one cap per Gaussian:
    /// `o_i = min(o_i, logit(caps_i))` on the opacity logits (a cap of 1 or more
    /// leaves the row as it is). Returns the id of the parameter it overwrote, whose
    /// optimiser moments the trainer then zeroes (3DGS `replace_tensor_to_optimizer`):
    /// stale momentum would otherwise keep pushing the reset opacities down.
    pub fn cap_opacity(&mut self, ids: CanonicalIds, caps: &[f64]) -> ParamId {
        let id = ids.opacity_logits;
        for (v, &cap) in self.value_mut(id).data_mut().iter_mut().zip(caps) {
            if cap < 1.0 {
                *v = v.min(logit(T::of(cap)));
            }
        }
        id
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Rows;
    use maaf_autodiff::optim::LrSchedule;

    /// A store of 2 Gaussians whose canonical tensors are declared after a shared one.
    fn store() -> (ParamStore<f64>, CanonicalIds) {
        let mut s = ParamStore::new();
        let lr = LrSchedule::Constant(0.1);
        let per = Rows::PerGaussian;
        s.add(
            "w",
            Tensor::from_vec(vec![9.0], &[1]),
            Rows::Shared,
            lr.clone(),
            0.0,
        );
        let means = s.add(
            "xyz",
            Tensor::from_vec((0..6).map(f64::from).collect(), &[2, 3]),
            per,
            lr.clone(),
            0.0,
        );
        let log_scales = s.add(
            "log_scale",
            Tensor::from_vec(vec![0.0, 1.0, 2.0, -1.0, -2.0, 0.5], &[2, 3]),
            per,
            lr.clone(),
            0.0,
        );
        let quats = s.add(
            "rotation",
            Tensor::from_vec(vec![1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 0.5], &[2, 4]),
            per,
            lr.clone(),
            0.0,
        );
        let opacity_logits = s.add(
            "opacity",
            Tensor::from_vec(vec![2.0, -6.0], &[2]),
            per,
            lr,
            0.0,
        );
        let ids = CanonicalIds {
            means,
            log_scales,
            quats,
            opacity_logits,
        };
        (s, ids)
    }

    #[test]
    fn canonical_activates_scales_and_opacity() {
        let (s, ids) = store();
        let c = s.canonical(ids);
        assert_eq!(c.means.data(), s.value(ids.means).data());
        assert_eq!(c.quats.data(), s.value(ids.quats).data());
        assert_eq!(c.scales.data()[1], 1f64.exp());
        assert_eq!(c.scales.data()[5], 0.5f64.exp());
        assert_eq!(c.opacity.data(), &[sigmoid(2.0), sigmoid(-6.0)]);
    }

    #[test]
    fn set_canonical_rows_writes_means_and_log_scales_of_those_rows_only() {
        let (mut s, ids) = store();
        let means = Tensor::from_vec(vec![7.0, 8.0, 9.0], &[1, 3]);
        let scales = Tensor::from_vec(vec![1.0, 2.0, 4.0], &[1, 3]);
        s.set_canonical_rows(ids, &[1], &means, &scales);
        assert_eq!(s.value(ids.means).data(), &[0.0, 1.0, 2.0, 7.0, 8.0, 9.0]);
        let ls = s.value(ids.log_scales).data();
        assert_eq!(&ls[..3], &[0.0, 1.0, 2.0]);
        assert_eq!(&ls[3..], &[0.0, 2f64.ln(), 4f64.ln()]);
    }

    #[test]
    fn cap_opacity_lowers_only_rows_above_their_cap() {
        let (mut s, ids) = store();
        // Row 0 (sigmoid(2) = 0.88) capped at 0.01; row 1 (0.0025) below its cap.
        let id = s.cap_opacity(ids, &[0.01, 0.01]);
        assert_eq!(id, ids.opacity_logits);
        assert_eq!(s.value(id).data(), &[logit(0.01), -6.0]);
        // A cap of 1 leaves the row alone.
        let (mut s, ids) = store();
        s.cap_opacity(ids, &[1.0, 0.001]);
        assert_eq!(s.value(ids.opacity_logits).data(), &[2.0, logit(0.001)]);
    }
}
