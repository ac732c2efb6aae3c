//! Scale anisotropy: penalises Gaussians whose longest axis is more than `BOUND`
//! times their shortest, the needles that poke out of a surface when seen from a
//! new view (PhysGaussian, Xie et al., CVPR 2024, Sec. 4: the anisotropy
//! regulariser).
//!
//! ```text
//! A = (1/N) sum_i max(q_i, r) - r,   q_i = max_a s_ia / min_a s_ia,   r = BOUND
//! dA/ds_i,max = 1 / (N s_i,min),   dA/ds_i,min = -s_i,max / (N s_i,min^2)   where q_i > r
//! ```
//!
//! on the deformed, activated scales `s` `[N, 3]` ([`TermCtx::gaussians`], before the
//! 3D filter); rows with `q_i <= r` add nothing. With ties the first axis is the
//! maximum (or minimum). `A = 0` with no Gaussian.

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};

use crate::loss::{Term, TermCtx};

/// Name of the term in a config's `terms` and in `log.csv`.
pub const NAME: &str = "scale_anisotropy";

/// The ratio `r` of the longest to the shortest axis allowed without penalty.
pub const BOUND: f64 = 10.0;

/// The scale anisotropy term (module docs), weighted by `weight`, with `r = BOUND`.
#[derive(Clone, Debug)]
pub struct ScaleAnisotropy {
    /// Weight in the objective.
    pub weight: f64,
}

impl<T: Float> Term<T> for ScaleAnisotropy {
    fn name(&self) -> &str {
        NAME
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        scale_anisotropy(ctx.gaussians().scales, BOUND)
    }
}

/// `A(s)` of the module docs for positive scales `[N, 3]` and bound `r`, rank 0.
pub fn scale_anisotropy<'t, T: Float>(scales: Var<'t, T>, bound: f64) -> Var<'t, T> {
    scales.tape().apply1(AnisotropyOp { bound }, &[scales])
}

/// The fused op behind [`scale_anisotropy`].
struct AnisotropyOp {
    bound: f64,
}

/// The axes of the largest and the smallest entry of a row (first on ties).
fn extremes<T: Float>(row: &[T]) -> (usize, usize) {
    let (mut hi, mut lo) = (0, 0);
    for (a, &v) in row.iter().enumerate() {
        if v > row[hi] {
            hi = a;
        }
        if v < row[lo] {
            lo = a;
        }
    }
    (hi, lo)
}

impl<T: Float> Op<T> for AnisotropyOp {
    type Saved = ();

    fn name(&self) -> String {
        NAME.into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let s = inputs[0];
        assert_eq!(
            s.shape().last(),
            Some(&3),
            "{NAME}: scales must be [N, 3], got {:?}",
            s.shape()
        );
        let r = T::of(self.bound);
        let mut sum = T::zero();
        for row in s.data().chunks_exact(3) {
            let (hi, lo) = extremes(row);
            let q = row[hi] / row[lo];
            if q > r {
                sum += q - r;
            }
        }
        let n = T::of((s.len() / 3).max(1) as f64);
        (vec![Tensor::scalar(sum / n)], ())
    }

    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let s = c.inputs[0];
        let g = c.grad_outputs[0].item() / T::of((s.len() / 3).max(1) as f64);
        let r = T::of(self.bound);
        let mut d = Tensor::zeros(s.shape());
        for (row, out) in s
            .data()
            .chunks_exact(3)
            .zip(d.data_mut().chunks_exact_mut(3))
        {
            let (hi, lo) = extremes(row);
            if row[hi] / row[lo] > r {
                out[hi] += g / row[lo];
                out[lo] -= g * row[hi] / (row[lo] * row[lo]);
            }
        }
        vec![Some(d)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::Tape;
    use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    /// The formula as a plain loop in f64.
    fn slow(s: &[f64], r: f64) -> f64 {
        let rows: Vec<&[f64]> = s.chunks(3).collect();
        let mut sum = 0.0;
        for row in &rows {
            let max = row.iter().cloned().fold(f64::MIN, f64::max);
            let min = row.iter().cloned().fold(f64::MAX, f64::min);
            sum += (max / min).max(r) - r;
        }
        sum / rows.len().max(1) as f64
    }

    /// Scales spanning two decades, so some rows are above the bound and some below.
    fn scales(seed: u64) -> Tensor<f64> {
        random_tensor::<f64>(&[30, 3], -2.0, 0.0, seed).map(|x| 10f64.powf(x))
    }

    #[test]
    fn forward_matches_the_loop_reference() {
        let s = scales(1);
        let tape = Tape::new();
        let a = scale_anisotropy(tape.var(s.clone()), BOUND).value().item();
        let want = slow(s.data(), BOUND);
        assert!(want > 0.0, "the sample must have rows above the bound");
        assert!((a - want).abs() < 1e-12 * want, "{a} vs {want}");
        // A sphere and a 10:1 needle cost nothing; a 20:1 needle costs 10 per row.
        let t = Tensor::from_vec(vec![1.0, 1.0, 1.0, 0.1, 1.0, 0.5, 2.0, 0.1, 1.0], &[3, 3]);
        let a = scale_anisotropy(tape.var(t), BOUND).value().item();
        assert!((a - 10.0 / 3.0).abs() < 1e-12, "{a}");
        let empty = scale_anisotropy(tape.var(Tensor::<f64>::zeros(&[0, 3])), BOUND);
        assert_eq!(empty.value().item(), 0.0);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let s = scales(2);
        // No row within the step of the kink q = r or of a tie between two axes.
        for row in s.data().chunks(3) {
            let mut v = row.to_vec();
            v.sort_by(f64::total_cmp);
            assert!(v[1] - v[0] > 1e-4 && v[2] - v[1] > 1e-4);
            assert!((v[2] / v[0] - BOUND).abs() > 1e-3);
        }
        let r = gradcheck(
            |_, v| scale_anisotropy(v[0], BOUND),
            &[s],
            &GradcheckConfig::default().with_tol(1e-8, 1e-6),
        );
        assert!(r.passed(), "{r}");
    }
}
