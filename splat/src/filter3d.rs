//! The Mip-Splatting 3D smoothing filter folded into scales and opacity
//! (docs/conventions.md; Mip-Splatting `get_scaling_with_3D_filter`,
//! `get_opacity_with_3D_filter`).

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};

/// Folds a per-Gaussian isotropic variance `var_i` into activated scales and opacity:
///
/// ```text
/// s'_ij = sqrt(s_ij^2 + var_i)                       (Sigma' = Sigma + var_i I)
/// o'_i  = o_i * sqrt( prod_j s_ij^2 / prod_j (s_ij^2 + var_i) )
///       = o_i * sqrt( det Sigma / det Sigma' )
/// ```
///
/// Inputs: `scales [N,3]`, `opacity [N]`; `var [N]` is a constant held by the op (no
/// gradient). Outputs: `scales' [N,3]`, `opacity' [N]`. Only `s^2` enters, so a scale
/// may be zero or negative (Deformable-3DGS adds its residual to the activated
/// scale); `var_i = 0` leaves Gaussian i unchanged even at `s = 0`.
///
/// The variance is `s3d / nu_i^2` with `s3d = 0.2` as in Mip-Splatting's code
/// (`filter_3D = distance / focal * sqrt(0.2)` is a standard deviation, squared here);
/// the paper writes the filter as `(s / nu) I`, the code squares it, and maaf follows
/// the code. Gradient (hand-written), with `r_ij = s_ij^2 / (s_ij^2 + var_i)` and
/// `c_i = sqrt(prod_j r_ij)`:
/// `ds_ij = g_s'_ij s_ij / s'_ij + g_o'_i o_i sign(s_ij) sqrt(prod_{k != j} r_ik) var_i
/// / (s_ij^2 + var_i)^(3/2)` (the same as `c_i var_i / (s_ij (s_ij^2 + var_i))`
/// without dividing by `s_ij`, so `s_ij = 0` gives the zero subgradient, not NaN),
/// `do_i = g_o'_i c_i`.
pub struct Filter3dOp<T: Float> {
    /// Per-Gaussian variance `var_i >= 0` (world units squared).
    pub var: Tensor<T>,
}

impl<T: Float> Op<T> for Filter3dOp<T> {
    type Saved = ();

    fn name(&self) -> String {
        "apply_3d_filter".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (s, o) = (inputs[0], inputs[1]);
        let n = o.len();
        assert_eq!(s.shape(), &[n, 3], "apply_3d_filter: scales must be [N,3]");
        assert_eq!(self.var.len(), n, "apply_3d_filter: var must be [N]");
        let mut s_out = vec![T::zero(); 3 * n];
        let mut o_out = vec![T::zero(); n];
        for i in 0..n {
            let v = self.var.data()[i];
            let r = ratios(&s.data()[3 * i..3 * i + 3], v);
            for j in 0..3 {
                let sj = s.data()[3 * i + j];
                s_out[3 * i + j] = (sj * sj + v).sqrt();
            }
            o_out[i] = o.data()[i] * (r[0] * r[1] * r[2]).sqrt();
        }
        (
            vec![
                Tensor::from_vec(s_out, &[n, 3]),
                Tensor::from_vec(o_out, &[n]),
            ],
            (),
        )
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (s, o) = (ctx.inputs[0], ctx.inputs[1]);
        let s_out = ctx.outputs[0];
        let (v_scales_out, v_opacities_out) = (&ctx.grad_outputs[0], &ctx.grad_outputs[1]);
        let n = o.len();
        let mut v_scales = vec![T::zero(); 3 * n];
        let mut v_opacities = vec![T::zero(); n];
        for i in 0..n {
            let v = self.var.data()[i];
            let oi = o.data()[i];
            let si = &s.data()[3 * i..3 * i + 3];
            // c_i recomputed (not o'_i / o_i) so that o_i = 0 is fine.
            let r = ratios(si, v);
            v_opacities[i] = v_opacities_out.data()[i] * (r[0] * r[1] * r[2]).sqrt();
            for j in 0..3 {
                let (sj, out) = (si[j], s_out.data()[3 * i + j]);
                let d_scale = if out > T::zero() { sj / out } else { T::zero() };
                let sign = if sj > T::zero() {
                    T::one()
                } else if sj < T::zero() {
                    -T::one()
                } else {
                    T::zero()
                };
                let s2v = sj * sj + v;
                let d_c = if v > T::zero() {
                    sign * (r[(j + 1) % 3] * r[(j + 2) % 3]).sqrt() * v / (s2v * s2v.sqrt())
                } else {
                    T::zero()
                };
                v_scales[3 * i + j] =
                    v_scales_out.data()[3 * i + j] * d_scale + v_opacities_out.data()[i] * oi * d_c;
            }
        }
        vec![
            Some(Tensor::from_vec(v_scales, &[n, 3])),
            Some(Tensor::from_vec(v_opacities, &[n])),
        ]
    }
}

/// `s_j^2 / (s_j^2 + var)` per axis, 1 when `var = 0` (no filter: the Gaussian is
/// unchanged, a zero scale included).
fn ratios<T: Float>(s: &[T], var: T) -> [T; 3] {
    std::array::from_fn(|j| {
        if var > T::zero() {
            let s2 = s[j] * s[j];
            s2 / (s2 + var)
        } else {
            T::one()
        }
    })
}

/// Applies the 3D filter on the tape: returns `(scales', opacity')` as defined on
/// [`Filter3dOp`]. `scales [N,3]` activated (any sign), `opacity [N]` activated,
/// `var [N]` constant per-Gaussian variance (`s3d / nu^2`, zero for no filtering).
pub fn apply_3d_filter<'t, T: Float>(
    scales: Var<'t, T>,
    opacity: Var<'t, T>,
    var: &Tensor<T>,
) -> (Var<'t, T>, Var<'t, T>) {
    let out = scales
        .tape()
        .apply(Filter3dOp { var: var.clone() }, &[scales, opacity]);
    (out[0], out[1])
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::Tape;
    use maaf_autodiff::check::{
        GradcheckConfig, check_vjp, gradcheck, tests_support::random_tensor,
    };

    fn inputs() -> (Tensor<f64>, Tensor<f64>, Tensor<f64>) {
        (
            random_tensor(&[5, 3], 0.05, 1.0, 1),
            random_tensor(&[5], 0.05, 0.95, 2),
            random_tensor(&[5], 0.0, 0.3, 3),
        )
    }

    #[test]
    fn gradcheck_both_outputs() {
        let (s, o, v) = inputs();
        // Smooth rational/sqrt function of O(1) inputs: central differences in f64 are
        // accurate to ~1e-9, so the default 1e-7 + 1e-5 rel tolerance applies.
        let report = gradcheck(
            |_, x| {
                let (s2, o2) = apply_3d_filter(x[0], x[1], &v);
                s2.sum() + o2.scale(3.0).sum()
            },
            &[s, o],
            &GradcheckConfig::default(),
        );
        report.assert_passed();
    }

    #[test]
    fn check_vjp_against_reference_composition() {
        let (s, o, v) = inputs();
        let report = check_vjp(
            |_, x| {
                let (a, b) = apply_3d_filter(x[0], x[1], &v);
                vec![a, b]
            },
            |t, x| {
                let (a, b) = crate::reference::tape::apply_3d_filter(t, x[0], x[1], &v);
                vec![a, b]
            },
            &[s, o],
            3,
            &GradcheckConfig::default(),
        );
        report.assert_passed();
    }

    #[test]
    fn negative_and_zero_scales_have_the_gradient_of_their_square() {
        // Negative scales (away from 0): the same smooth function of s^2, so the
        // finite differences must agree as tightly as for positive ones.
        let (s, o, v) = inputs();
        let s = s.map(|x| if x > 0.5 { -x } else { x });
        gradcheck(
            |_, x| {
                let (s2, o2) = apply_3d_filter(x[0], x[1], &v);
                s2.sum() + o2.scale(3.0).sum()
            },
            &[s.clone(), o.clone()],
            &GradcheckConfig::default(),
        )
        .assert_passed();
        // An exactly zero scale, with and without variance: finite values and
        // gradients (the opacity factor's subgradient at 0 is 0).
        let mut z = s;
        z.data_mut()[4] = 0.0;
        z.data_mut()[7] = 0.0;
        let mut var = v;
        var.data_mut()[2] = 0.0;
        let tape = Tape::<f64>::new();
        let (sv, ov) = (tape.var(z), tape.var(o.clone()));
        let (a, b) = apply_3d_filter(sv, ov, &var);
        let grads = tape.backward(a.sum() + b.sum()).expect("finite");
        let gs = grads.wrt(sv).expect("grad");
        assert!(gs.data().iter().all(|g| g.is_finite()), "{gs:?}");
        assert_eq!(gs.data()[4], 0.0);
        assert!(b.value().data().iter().all(|x| x.is_finite()));
        assert_eq!(
            b.value().data()[1],
            0.0,
            "a zero axis with var > 0 has no opacity"
        );
        assert_eq!(
            b.value().data()[2],
            o.data()[2],
            "var 0 leaves the Gaussian alone"
        );
    }

    #[test]
    fn zero_variance_is_identity() {
        let tape = Tape::<f64>::new();
        let (s, o, _) = inputs();
        let sv = tape.constant(s.clone());
        let ov = tape.constant(o.clone());
        let (a, b) = apply_3d_filter(sv, ov, &Tensor::zeros(&[5]));
        assert_eq!(*a.value(), s);
        assert_eq!(*b.value(), o);
    }
}
