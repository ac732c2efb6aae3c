//! Total variation of the rendered depth: neighbouring pixels should see the surface
//! at about the same depth (RegNeRF, Niemeyer et al., CVPR 2022, Eq. 3: the squared
//! differences of the depths of neighbouring pixels).
//!
//! ```text
//! TV = (1/(H (W-1))) sum_{y,x} (D[y,x+1] - D[y,x])^2
//!    + (1/((H-1) W)) sum_{y,x} (D[y+1,x] - D[y,x])^2
//! ```
//!
//! on the depth the renderer composites, `D = sum_i z_i alpha_i T_i` `[H, W]`
//! ([`TermCtx::depth`], in world units): the alpha-weighted depth, not the expected
//! depth `D / alpha`, which has no value where nothing is drawn. An object's
//! silhouette is therefore a depth edge too; use a small weight. A direction with
//! one pixel adds nothing. Built from tape primitives (slice, subtract, square,
//! mean), so its backward is theirs.

use maaf_autodiff::{Float, Var};

use crate::loss::{Term, TermCtx};

/// Name of the term in a config's `terms` and in `log.csv`.
pub const NAME: &str = "depth_tv";

/// The depth total-variation term (module docs), weighted by `weight`.
#[derive(Clone, Debug)]
pub struct DepthTv {
    /// Weight in the objective.
    pub weight: f64,
}

impl<T: Float> Term<T> for DepthTv {
    fn name(&self) -> &str {
        NAME
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        depth_tv(ctx.depth())
    }
}

/// `TV(D)` of the module docs for a depth image `[H, W]`, rank 0.
pub fn depth_tv<'t, T: Float>(depth: Var<'t, T>) -> Var<'t, T> {
    let shape = depth.shape();
    assert_eq!(
        shape.len(),
        2,
        "{NAME}: depth must be [H, W], got {shape:?}"
    );
    let mut total = depth
        .tape()
        .constant(maaf_autodiff::Tensor::scalar(T::zero()));
    for axis in 0..2 {
        let n = shape[axis];
        if n > 1 {
            let step = depth.slice(axis, 1, n) - depth.slice(axis, 0, n - 1);
            total = total + step.square().mean();
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
    use maaf_autodiff::{Tape, Tensor};

    /// The formula as plain loops in f64.
    fn slow(d: &[f64], h: usize, w: usize) -> f64 {
        let at = |y: usize, x: usize| d[y * w + x];
        let (mut across, mut down) = (0.0, 0.0);
        for y in 0..h {
            for x in 0..w {
                if x + 1 < w {
                    across += (at(y, x + 1) - at(y, x)).powi(2);
                }
                if y + 1 < h {
                    down += (at(y + 1, x) - at(y, x)).powi(2);
                }
            }
        }
        let mean = |s: f64, n: usize| if n > 0 { s / n as f64 } else { 0.0 };
        mean(across, h * (w - 1)) + mean(down, (h - 1) * w)
    }

    #[test]
    fn forward_matches_the_loop_reference() {
        let tape = Tape::new();
        for (h, w) in [(7, 5), (1, 6), (4, 1)] {
            let d = random_tensor::<f64>(&[h, w], 0.0, 4.0, (h * w) as u64);
            let tv = depth_tv(tape.var(d.clone())).value().item();
            let want = slow(d.data(), h, w);
            assert!(
                (tv - want).abs() < 1e-13 * want.max(1.0),
                "{h}x{w}: {tv} vs {want}"
            );
        }
        let flat = depth_tv(tape.var(Tensor::full(&[3, 3], 2.5)))
            .value()
            .item();
        assert_eq!(flat, 0.0);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let d = random_tensor::<f64>(&[6, 5], 0.0, 4.0, 9);
        let r = gradcheck(
            |_, v| depth_tv(v[0]),
            &[d],
            &GradcheckConfig::default().with_tol(1e-9, 1e-6),
        );
        assert!(r.passed(), "{r}");
    }
}
