//! The 3D covariance of a Gaussian from its rotation quaternion and scales, as an op
//! with a hand-written backward (docs/conventions.md).

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};
use rayon::prelude::*;

use crate::math::{M3, mul3, quat_to_rotmat, rotmat_vjp};

/// Covariance `Sigma = R S S^T R^T` from an unnormalised quaternion `q = (w,x,y,z)`
/// (`R` from [`crate::math::quat_to_rotmat`]) and activated scales
/// `S = diag(s)`. Inputs `quats [N,4]`, `scales [N,3]`; output the upper triangle
/// `[N,6] = (xx, xy, xz, yy, yz, zz)`.
///
/// Backward: with `G` the symmetric cotangent of `Sigma` (off-diagonal packed entries
/// count for both halves), `dM = 2 G M` for `M = R S`, `dR_ij = dM_ij s_j`,
/// `ds_j = sum_i dM_ij R_ij`, then through `R(q)` and the normalisation
/// `dq = (dq_hat - q_hat (q_hat . dq_hat)) / |q|`.
pub struct QuatScaleToCov;

fn normalise<T: Float>(q: &[T]) -> ([T; 4], T) {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    ([q[0] / n, q[1] / n, q[2] / n, q[3] / n], n)
}

impl<T: Float> Op<T> for QuatScaleToCov {
    type Saved = ();

    fn name(&self) -> String {
        "quat_scale_to_cov".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (q, s) = (inputs[0], inputs[1]);
        let n = q.rows();
        assert_eq!(q.shape(), &[n, 4], "quat_scale_to_cov: quats must be [N,4]");
        assert_eq!(
            s.shape(),
            &[n, 3],
            "quat_scale_to_cov: scales must be [N,3]"
        );
        let mut out = vec![T::zero(); 6 * n];
        out.par_chunks_mut(6).enumerate().for_each(|(i, o)| {
            let qi = &q.data()[4 * i..4 * i + 4];
            let r = quat_to_rotmat([qi[0], qi[1], qi[2], qi[3]]);
            let sc = &s.data()[3 * i..3 * i + 3];
            // Sigma_ab = sum_k R_ak s_k^2 R_bk
            let mut k = 0;
            for a in 0..3 {
                for b in a..3 {
                    o[k] = (0..3).map(|j| r[a][j] * sc[j] * sc[j] * r[b][j]).sum();
                    k += 1;
                }
            }
        });
        (vec![Tensor::from_vec(out, &[n, 6])], ())
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (q, s) = (ctx.inputs[0], ctx.inputs[1]);
        let v_cov3d = &ctx.grad_outputs[0];
        let n = q.rows();
        let half = T::of(0.5);
        let two = T::of(2.0);
        let mut v_quats = vec![T::zero(); 4 * n];
        let mut v_scales = vec![T::zero(); 3 * n];
        v_quats
            .par_chunks_mut(4)
            .zip(v_scales.par_chunks_mut(3))
            .enumerate()
            .for_each(|(i, (v_quats, v_scales))| {
                let qi = &q.data()[4 * i..4 * i + 4];
                let (qh, qn) = normalise(qi);
                let r = quat_to_rotmat([qi[0], qi[1], qi[2], qi[3]]);
                let sc = &s.data()[3 * i..3 * i + 3];
                let g = &v_cov3d.data()[6 * i..6 * i + 6];
                // Symmetric cotangent: packed off-diagonals are split over both halves.
                let v_covar: M3<T> = [
                    [g[0], half * g[1], half * g[2]],
                    [half * g[1], g[3], half * g[4]],
                    [half * g[2], half * g[4], g[5]],
                ];
                let mut m = [[T::zero(); 3]; 3];
                for a in 0..3 {
                    for j in 0..3 {
                        m[a][j] = r[a][j] * sc[j];
                    }
                }
                let v_m_half = mul3(&v_covar, &m);
                let mut v_rot = [[T::zero(); 3]; 3];
                for a in 0..3 {
                    for j in 0..3 {
                        let v_m = two * v_m_half[a][j];
                        v_rot[a][j] = v_m * sc[j];
                        v_scales[j] += v_m * r[a][j];
                    }
                }
                let v_qhat = rotmat_vjp(qh, &v_rot);
                let dot = (0..4).map(|k| qh[k] * v_qhat[k]).sum::<T>();
                for k in 0..4 {
                    v_quats[k] = (v_qhat[k] - qh[k] * dot) / qn;
                }
            });
        vec![
            Some(Tensor::from_vec(v_quats, &[n, 4])),
            Some(Tensor::from_vec(v_scales, &[n, 3])),
        ]
    }
}

/// Covariance on the tape, see [`QuatScaleToCov`]: `quats [N,4]`, `scales [N,3]` ->
/// `[N,6]` upper triangle.
pub fn quat_scale_to_cov<'t, T: Float>(quats: Var<'t, T>, scales: Var<'t, T>) -> Var<'t, T> {
    quats.tape().apply1(QuatScaleToCov, &[quats, scales])
}
