//! Opacity entropy: pushes every Gaussian's opacity towards 0 or 1, so that none stays
//! half-transparent (SuGaR, Guédon and Lepetit, CVPR 2024, Sec. 4.1: the binary
//! entropy of the opacities; Neural Volumes' beta prior has the same aim).
//!
//! ```text
//! H = (1/N) sum_i h(o_i),   h(o) = -(o ln o + (1 - o) ln(1 - o)),
//! dH/do_i = ln((1 - o_i) / o_i) / N
//! ```
//!
//! on the deformed opacities `o` ([`TermCtx::gaussians`], before the 3D filter),
//! clamped to `[EPS, 1 - EPS]` (an f32 sigmoid rounds to exactly 0 or 1, where
//! `ln` diverges); a clamped opacity has zero gradient. `H = 0` with no Gaussian.

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};

use crate::loss::{Term, TermCtx};

/// Name of the term in a config's `terms` and in `log.csv`.
pub const NAME: &str = "opacity_entropy";

/// Opacities are clamped to `[EPS, 1 - EPS]` before the entropy.
pub const EPS: f64 = 1e-6;

/// The opacity entropy term (module docs), weighted by `weight`.
#[derive(Clone, Debug)]
pub struct OpacityEntropy {
    /// Weight in the objective.
    pub weight: f64,
}

impl<T: Float> Term<T> for OpacityEntropy {
    fn name(&self) -> &str {
        NAME
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        opacity_entropy(ctx.gaussians().opacity)
    }
}

/// `H(o)` of the module docs for opacities `[N]`, rank 0, on `o`'s tape.
pub fn opacity_entropy<'t, T: Float>(opacity: Var<'t, T>) -> Var<'t, T> {
    opacity.tape().apply1(EntropyOp, &[opacity])
}

/// The fused op behind [`opacity_entropy`]: forward and backward in one pass each.
struct EntropyOp;

/// `o` clamped to `[EPS, 1 - EPS]`, and whether it was inside (has a gradient).
fn clamped<T: Float>(o: T) -> (T, bool) {
    let (lo, hi) = (T::of(EPS), T::of(1.0 - EPS));
    if o < lo {
        (lo, false)
    } else if o > hi {
        (hi, false)
    } else {
        (o, true)
    }
}

impl<T: Float> Op<T> for EntropyOp {
    type Saved = ();

    fn name(&self) -> String {
        NAME.into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let o = inputs[0];
        let mut sum = T::zero();
        for &v in o.data() {
            let (p, _) = clamped(v);
            let q = T::one() - p;
            sum -= p * p.ln() + q * q.ln();
        }
        let n = T::of(o.len().max(1) as f64);
        (vec![Tensor::scalar(sum / n)], ())
    }

    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let o = c.inputs[0];
        let g = c.grad_outputs[0].item() / T::of(o.len().max(1) as f64);
        let d = o.map(|v| match clamped(v) {
            (p, true) => g * ((T::one() - p) / p).ln(),
            _ => T::zero(),
        });
        vec![Some(d)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::Tape;
    use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    /// The formula as a plain loop in f64, clamping included.
    fn slow(o: &[f64]) -> f64 {
        let mut sum = 0.0;
        for &v in o {
            let p = v.clamp(EPS, 1.0 - EPS);
            sum += -(p * p.ln() + (1.0 - p) * (1.0 - p).ln());
        }
        sum / o.len().max(1) as f64
    }

    #[test]
    fn forward_matches_the_loop_reference_including_the_clamped_ends() {
        let mut o = random_tensor::<f64>(&[50], 0.0, 1.0, 3);
        o.data_mut()[0] = 0.0;
        o.data_mut()[1] = 1.0;
        o.data_mut()[2] = 0.5;
        let tape = Tape::new();
        let h = opacity_entropy(tape.var(o.clone())).value().item();
        assert!(
            (h - slow(o.data())).abs() < 1e-14,
            "{h} vs {}",
            slow(o.data())
        );
        assert!(h.is_finite());
        // The maximum, ln 2, at o = 1/2; near 0 at a decided opacity.
        let half = opacity_entropy(tape.var(Tensor::full(&[3], 0.5)))
            .value()
            .item();
        assert!((half - 2f64.ln()).abs() < 1e-15);
        let empty = opacity_entropy(tape.var(Tensor::<f64>::zeros(&[0])));
        assert_eq!(empty.value().item(), 0.0);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        // Opacities away from the clamp (1e-6) by far more than the step (1e-6).
        let o = random_tensor::<f64>(&[40], 0.02, 0.98, 4);
        let r = gradcheck(
            |_, v| opacity_entropy(v[0]),
            &[o],
            &GradcheckConfig::default().with_tol(1e-9, 1e-6),
        );
        assert!(r.passed(), "{r}");
    }

    #[test]
    fn a_clamped_opacity_has_no_gradient_and_the_sign_points_away_from_one_half() {
        let tape = Tape::new();
        let o = tape.param("o", Tensor::from_vec(vec![0.0, 0.2, 0.9, 1.0], &[4]));
        let g = tape.backward(opacity_entropy(o)).expect("finite");
        let d = g.param("o").expect("gradient");
        assert_eq!(d.data()[0], 0.0);
        assert_eq!(d.data()[3], 0.0);
        // Descending the gradient lowers 0.2 and raises 0.9.
        assert!(d.data()[1] > 0.0 && d.data()[2] < 0.0, "{:?}", d.data());
        assert!((d.data()[1] - 4f64.ln() / 4.0).abs() < 1e-15);
    }
}
