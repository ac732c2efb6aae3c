//! The field query and the lifespans of a SaRO model: one place that turns the stored
//! values into the detached field query, samples the planes, and maps features to
//! lifespans, shared by binding, the no-gradient lifespans and the centre pass.

use std::sync::Arc;

use maaf_autodiff::nn::MlpVars;
use maaf_autodiff::{Float, Tape, Tensor, Var};

use super::SaroModel;
use crate::kplane::{FieldQuery, PlaneSample};

impl<T: Float> SaroModel<T> {
    /// Number of Gaussians (rows of the per-Gaussian parameters).
    pub(super) fn num_rows(&self) -> usize {
        self.params.value(self.ids.xyz).rows()
    }

    /// sg(mu_t) per Gaussian, as f64.
    pub(super) fn t_centre_f64(&self) -> Vec<f64> {
        self.params
            .value(self.ids.t_centre)
            .data()
            .iter()
            .map(|&v| Float::to_f64(v))
            .collect()
    }

    /// The detached field query from the stored sg(x), sg(mu_t), sg(exp(log s)).
    pub fn field_query(&self) -> FieldQuery {
        let p = &self.params;
        let scales = p.value(self.ids.log_scale).map(|v| v.exp());
        self.field.query(
            p.value(self.ids.xyz).data(),
            p.value(self.ids.t_centre).data(),
            scales.data(),
        )
    }

    /// Field features `F(sg(x), sg(mu_t), sg(s))` \[N, C] from the six `planes` (vars on
    /// one tape, [`crate::kplane::PLANE_NAMES`] order).
    pub(super) fn field_features<'t>(&self, planes: &[Var<'t, T>; 6]) -> Var<'t, T> {
        let sample = PlaneSample::new(&self.field, Arc::new(self.field_query()));
        #[cfg(test)]
        let sample = if self.corrupt_field_backward {
            sample.corrupted()
        } else {
            sample
        };
        planes[0].tape().apply1(sample, planes)
    }

    /// `l = (1 - m)(1 - sigmoid(z)) + m = 1 - (1 - m) sigmoid(z)`, `z = MLP_l(f)`, \[N].
    pub(super) fn lifespan_of<'t>(
        &self,
        life: &MlpVars<'t, T>,
        features: Var<'t, T>,
    ) -> Var<'t, T> {
        let m = self.config.min_lifespan();
        life.forward(features)
            .sigmoid()
            .scale(-(1.0 - m))
            .add_scalar(1.0)
            .reshape(&[self.num_rows()])
    }

    /// The field features \[N, C] of the stored parameters, without a gradient.
    pub(super) fn features_now(&self) -> Tensor<T> {
        let tape = Tape::<T>::new();
        let planes = self
            .ids
            .planes
            .map(|id| tape.constant(self.params.value(id).clone()));
        // The binding ends the borrow of the tape before the tape is dropped.
        #[allow(clippy::let_and_return)]
        let f = self.field_features(&planes).value().clone();
        f
    }

    /// Lifespans `l` \[N] from the current parameters (no gradient), in f64:
    /// `1 - (1 - m) sigmoid(MLP_l(f))`.
    pub fn lifespans(&self) -> Vec<f64> {
        let tape = Tape::<T>::new();
        let features = tape.constant(self.features_now());
        let z = self
            .ids
            .life
            .bind_constants(&self.params, &tape)
            .forward(features);
        let m = self.config.min_lifespan();
        let s = z.sigmoid();
        let v = s.value();
        v.data()
            .iter()
            .map(|&s| 1.0 - (1.0 - m) * Float::to_f64(s))
            .collect()
    }

    /// Temporal integral of each Gaussian's opacity factor over t in \[0, 1] (SaRO-GS
    /// `get_intergral`, the code's "Eq 22"):
    /// `I = l sqrt(pi)/2 \[Q(2 sqrt2 (1 - mu_t)/l) - Q(2 sqrt2 (0 - mu_t)/l)]`, with the
    /// logistic approximation of the normal CDF
    /// `Q(x) = 1 - 1/(1 + exp(0.070565902 x^3 + 1.5976 x))`.
    pub fn temporal_integral(&self) -> Vec<f64> {
        let q = |x: f64| 1.0 - 1.0 / (1.0 + (0.070_565_902 * x * x * x + 1.5976 * x).exp());
        let r = 2.0 * std::f64::consts::SQRT_2;
        self.lifespans()
            .iter()
            .zip(self.t_centre_f64())
            .map(|(&l, mu)| {
                l * std::f64::consts::PI.sqrt() / 2.0
                    * (q(r * (1.0 - mu) / l) - q(r * (0.0 - mu) / l))
            })
            .collect()
    }

    /// SaRO-GS's adaptive-optimisation scale per Gaussian (`update_learning_rate`):
    /// `inv = 1 / I` normalised by its smallest value, i.e. `I_max / I`, with `I` the
    /// [`Self::temporal_integral`]. Integrals at or below `min_integral` (or not
    /// finite), which SaRO-GS prunes at this point and maaf prunes at the next
    /// densification, count as `min_integral` (at least 1e-12) so the scale stays
    /// finite.
    pub fn adaptive_scale(&self) -> Vec<T> {
        let floor = self.config.min_integral.max(1e-12);
        let integral: Vec<f64> = self
            .temporal_integral()
            .into_iter()
            .map(|i| if i.is_finite() && i > floor { i } else { floor })
            .collect();
        let max = integral.iter().copied().fold(floor, f64::max);
        integral.iter().map(|&i| T::of(max / i)).collect()
    }
}
