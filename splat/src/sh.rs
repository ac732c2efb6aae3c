//! View-dependent colour from real spherical harmonics, degrees 0-3, with the
//! Inria/gsplat constants and sign conventions (Sloan 2013; Inria `auxiliary.h`
//! `SH_C0..SH_C3`, gsplat `_eval_sh_bases_fast`).

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};
use rayon::prelude::*;

/// `Y_0^0 = 1 / (2 sqrt(pi))`.
pub const SH_C0: f64 = 0.282_094_791_773_878_14;
/// Degree-1 constant `sqrt(3) / (2 sqrt(pi))`.
pub const SH_C1: f64 = 0.488_602_511_902_919_9;
/// Degree-2 constants (Inria `SH_C2`).
pub const SH_C2: [f64; 5] = [
    1.092_548_430_592_079_2,
    -1.092_548_430_592_079_2,
    0.315_391_565_252_520_05,
    -1.092_548_430_592_079_2,
    0.546_274_215_296_039_6,
];
/// Degree-3 constants (Inria `SH_C3`).
pub const SH_C3: [f64; 7] = [
    -0.590_043_589_926_643_5,
    2.890_611_442_640_554,
    -0.457_045_799_464_465_8,
    0.373_176_332_590_115_4,
    -0.457_045_799_464_465_8,
    1.445_305_721_320_277,
    -0.590_043_589_926_643_5,
];

/// Number of SH coefficients per channel for `degree`: `(degree + 1)^2`.
pub fn num_coeffs(degree: usize) -> usize {
    (degree + 1) * (degree + 1)
}

/// The 16 basis values at the unit direction `(x, y, z)` (entries past the degree in
/// use are ignored by callers):
/// `b0 = C0; b1..3 = C1 (-y, z, -x); b4..8 = C2 (xy, yz, 2z^2-x^2-y^2, xz, x^2-y^2);
/// b9..15 = C3 (y(3x^2-y^2), xyz, y(4z^2-x^2-y^2), z(2z^2-3x^2-3y^2), x(4z^2-x^2-y^2),
/// z(x^2-y^2), x(x^2-3y^2))`.
pub fn sh_basis<T: Float>(d: [T; 3]) -> [T; 16] {
    let [x, y, z] = d;
    let c = |v: f64| T::of(v);
    let (xx, yy, zz) = (x * x, y * y, z * z);
    [
        c(SH_C0),
        -c(SH_C1) * y,
        c(SH_C1) * z,
        -c(SH_C1) * x,
        c(SH_C2[0]) * x * y,
        c(SH_C2[1]) * y * z,
        c(SH_C2[2]) * (c(2.0) * zz - xx - yy),
        c(SH_C2[3]) * x * z,
        c(SH_C2[4]) * (xx - yy),
        c(SH_C3[0]) * y * (c(3.0) * xx - yy),
        c(SH_C3[1]) * x * y * z,
        c(SH_C3[2]) * y * (c(4.0) * zz - xx - yy),
        c(SH_C3[3]) * z * (c(2.0) * zz - c(3.0) * xx - c(3.0) * yy),
        c(SH_C3[4]) * x * (c(4.0) * zz - xx - yy),
        c(SH_C3[5]) * z * (xx - yy),
        c(SH_C3[6]) * x * (xx - c(3.0) * yy),
    ]
}

/// Gradient of each basis function of [`sh_basis`] with respect to `(x, y, z)`.
fn sh_basis_grad<T: Float>(d: [T; 3]) -> [[T; 3]; 16] {
    let [x, y, z] = d;
    let c = |v: f64| T::of(v);
    let o = T::zero();
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (c1, c2, c3) = (c(SH_C1), SH_C2, SH_C3);
    [
        [o, o, o],
        [o, -c1, o],
        [o, o, c1],
        [-c1, o, o],
        [c(c2[0]) * y, c(c2[0]) * x, o],
        [o, c(c2[1]) * z, c(c2[1]) * y],
        [c(-2.0 * c2[2]) * x, c(-2.0 * c2[2]) * y, c(4.0 * c2[2]) * z],
        [c(c2[3]) * z, o, c(c2[3]) * x],
        [c(2.0 * c2[4]) * x, c(-2.0 * c2[4]) * y, o],
        [c(6.0 * c3[0]) * x * y, c(3.0 * c3[0]) * (xx - yy), o],
        [c(c3[1]) * y * z, c(c3[1]) * x * z, c(c3[1]) * x * y],
        [
            c(-2.0 * c3[2]) * x * y,
            c(c3[2]) * (c(4.0) * zz - xx - c(3.0) * yy),
            c(8.0 * c3[2]) * y * z,
        ],
        [
            c(-6.0 * c3[3]) * x * z,
            c(-6.0 * c3[3]) * y * z,
            c(c3[3]) * (c(6.0) * zz - c(3.0) * xx - c(3.0) * yy),
        ],
        [
            c(c3[4]) * (c(4.0) * zz - c(3.0) * xx - yy),
            c(-2.0 * c3[4]) * x * y,
            c(8.0 * c3[4]) * x * z,
        ],
        [
            c(2.0 * c3[5]) * x * z,
            c(-2.0 * c3[5]) * y * z,
            c(c3[5]) * (xx - yy),
        ],
        [c(3.0 * c3[6]) * (xx - yy), c(-6.0 * c3[6]) * x * y, o],
    ]
}

/// RGB colour from SH coefficients seen from a camera centre:
///
/// ```text
/// d = (mu - campos) / |mu - campos|
/// colour_c = max( sum_{k < (degree+1)^2} b_k(d) sh[k][c] + 0.5, 0 )
/// ```
///
/// Inputs `means [N,3]`, `sh [N,K,3]` with `K >= (degree+1)^2`; output `[N,3]`. The
/// gradient flows to the coefficients and, through `d`, to the means (as in Inria and
/// gsplat); channels clamped at 0 pass no gradient.
pub struct ShColor<T: Float> {
    /// Camera centre in world coordinates.
    pub campos: [T; 3],
    /// SH degree evaluated (0..=3).
    pub degree: usize,
}

impl<T: Float> ShColor<T> {
    fn dir(&self, m: &[T]) -> ([T; 3], T) {
        let d = [
            m[0] - self.campos[0],
            m[1] - self.campos[1],
            m[2] - self.campos[2],
        ];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        ([d[0] / n, d[1] / n, d[2] / n], n)
    }
}

impl<T: Float> Op<T> for ShColor<T> {
    type Saved = ();

    fn name(&self) -> String {
        "sh_color".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (means, sh) = (inputs[0], inputs[1]);
        let n = means.rows();
        let nk = num_coeffs(self.degree);
        assert!(self.degree <= 3, "sh_color: degree {} > 3", self.degree);
        assert!(
            sh.shape().len() == 3
                && sh.shape()[0] == n
                && sh.shape()[2] == 3
                && sh.shape()[1] >= nk,
            "sh_color: sh must be [N,K>={nk},3], got {:?}",
            sh.shape()
        );
        let k = sh.shape()[1];
        let mut out = vec![T::zero(); 3 * n];
        out.par_chunks_mut(3).enumerate().for_each(|(i, out)| {
            let (d, _) = self.dir(&means.data()[3 * i..3 * i + 3]);
            let b = sh_basis(d);
            let coeffs = &sh.data()[3 * k * i..3 * k * (i + 1)];
            for ch in 0..3 {
                let v: T = (0..nk).map(|j| b[j] * coeffs[3 * j + ch]).sum::<T>() + T::of(0.5);
                // max(v, 0) that keeps NaN (validate mode must see it)
                out[ch] = if v < T::zero() { T::zero() } else { v };
            }
        });
        (vec![Tensor::from_vec(out, &[n, 3])], ())
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (means, sh) = (ctx.inputs[0], ctx.inputs[1]);
        let out = ctx.outputs[0];
        let v_colors = &ctx.grad_outputs[0];
        let n = means.rows();
        let k = sh.shape()[1];
        let nk = num_coeffs(self.degree);
        let mut v_means = vec![T::zero(); 3 * n];
        let mut v_sh = vec![T::zero(); sh.len()];
        v_means
            .par_chunks_mut(3)
            .zip(v_sh.par_chunks_mut(3 * k))
            .zip(sh.data().par_chunks(3 * k))
            .enumerate()
            .for_each(|(i, ((v_means, v_sh), coeffs))| {
                let (d, len) = self.dir(&means.data()[3 * i..3 * i + 3]);
                let b = sh_basis(d);
                let db = sh_basis_grad(d);
                // The clamp max(v, 0) passes no gradient where it is active (v <= 0).
                let v_color: [T; 3] = std::array::from_fn(|ch| {
                    if out.data()[3 * i + ch] > T::zero() {
                        v_colors.data()[3 * i + ch]
                    } else {
                        T::zero()
                    }
                });
                // d colour_c / d sh[j][c] = b_j; d colour / d dir = sum_j (sh[j] . v_color) db_j.
                let mut v_dir = [T::zero(); 3];
                for (j, (v_coeff, c)) in v_sh
                    .chunks_exact_mut(3)
                    .zip(coeffs.chunks_exact(3))
                    .take(nk)
                    .enumerate()
                {
                    let mut wj = T::zero();
                    for ch in 0..3 {
                        v_coeff[ch] = b[j] * v_color[ch];
                        wj += c[ch] * v_color[ch];
                    }
                    for a in 0..3 {
                        v_dir[a] += wj * db[j][a];
                    }
                }
                // d = v / |v|: dv = (v_dir - d (d . v_dir)) / |v|
                let dot = d[0] * v_dir[0] + d[1] * v_dir[1] + d[2] * v_dir[2];
                for a in 0..3 {
                    v_means[a] = (v_dir[a] - d[a] * dot) / len;
                }
            });
        vec![
            Some(Tensor::from_vec(v_means, &[n, 3])),
            Some(Tensor::from_vec(v_sh, sh.shape())),
        ]
    }
}

/// Colours on the tape, see [`ShColor`]: `means [N,3]`, `sh [N,K,3]` -> `[N,3]`.
pub fn sh_color<'t, T: Float>(
    means: Var<'t, T>,
    sh: Var<'t, T>,
    campos: [f64; 3],
    degree: usize,
) -> Var<'t, T> {
    means.tape().apply1(
        ShColor {
            campos: campos.map(T::of),
            degree,
        },
        &[means, sh],
    )
}
