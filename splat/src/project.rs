//! The EWA projection of 3D Gaussians to screen space with the frustum clamp and the
//! 2D filter (docs/conventions.md).

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};
use rayon::prelude::*;

use crate::Camera;
use crate::compositing::support_sigmas;
use crate::math::{M3, mul3, mul3tv, mul3v, sym_from6, transpose3};

/// The screen-space low-pass ("2D filter") added to every projected covariance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Filter2d {
    /// 3DGS dilation: `cov2d + 0.3 I` (px^2), opacity unchanged (Inria
    /// `computeCov2D`; gsplat `rasterize_mode="classic"`).
    Classic,
    /// Mip-Splatting 2D Mip filter: `cov2d + 0.1 I` and opacity times
    /// `sqrt(det cov2d / det(cov2d + 0.1 I))` (Mip-Splatting `computeCov2D`,
    /// `kernel_size = 0.1`; gsplat "antialiased" with `eps2d = 0.1`).
    #[default]
    Mip,
}

impl Filter2d {
    /// Variance added to the 2D covariance diagonal, in px^2 (0.3 classic, 0.1 Mip).
    pub fn variance(self) -> f64 {
        match self {
            Filter2d::Classic => 0.3,
            Filter2d::Mip => 0.1,
        }
    }

    /// Whether opacity is multiplied by `sqrt(det / det_dilated)`.
    pub fn compensates(self) -> bool {
        matches!(self, Filter2d::Mip)
    }
}

/// Default near plane: Gaussians with camera depth `z <= 0.2` are culled (Inria
/// `in_frustum`, also the depth test of Mip-Splatting's 3D filter).
pub const NEAR_PLANE: f64 = 0.2;

/// Frustum-clamp margin: the Jacobian is evaluated at `x/z` clamped to
/// `[-(cx/fx + 0.3 tan_x), (W-cx)/fx + 0.3 tan_x]` with `tan_x = W/(2 fx)` (gsplat
/// `_persp_proj`), which is `+-1.3 tan(fov_x/2)` for a centred principal point
/// (Inria `computeCov2D`).
pub const FRUSTUM_MARGIN: f64 = 0.3;

/// EWA projection of 3D Gaussians (Zwicker et al. 2002, as in 3DGS / gsplat):
///
/// ```text
/// t      = R mu + t_cam                                   (camera space, OpenCV)
/// means2d = (fx t.x/t.z + cx, fy t.y/t.z + cy)            (unclamped t)
/// J      = [[fx/z, 0, -fx x'/z^2], [0, fy/z, -fy y'/z^2]]  x' = z clamp(x/z), y' likewise
/// cov2d  = J R Sigma R^T J^T + k I                        k = Filter2d::variance()
/// conic  = cov2d^{-1} packed as (A, B, C) = ([0][0], [0][1], [1][1])
/// opac'  = o * sqrt(max(det(cov2d - k I), 0) / det cov2d)  (Mip), o (classic)
/// depth  = t.z
/// radius = ceil(k sqrt(lambda_max)),  lambda_max = m + sqrt(max(0.1, m^2 - det)), m = tr/2
///          k = sqrt(2 ln(255 opac'))  (support_sigmas; gsplat's opacity-aware extent)
/// ```
///
/// Inputs: `means [N,3]`, `cov3d [N,6]`, `opacity [N]`. Outputs: `means2d [N,2]`,
/// `conics [N,3]`, `opacity [N]`, `depths [N]`, `radii [N]` (integers stored as `T`,
/// not differentiable; 0 = culled). A Gaussian is culled (all outputs 0) when
/// `t.z <= near`, when `opac' <= 1/255` (its alpha never reaches the threshold) or
/// when no pixel centre lies within `radius` of its mean on both axes.
/// Non-finite inputs are not culled: they propagate to the outputs so validate mode
/// names this op.
pub struct ProjectEwa<T: Float> {
    rot: M3<T>,
    trans: [T; 3],
    fx: T,
    fy: T,
    cx: T,
    cy: T,
    lim_x: (T, T),
    lim_y: (T, T),
    width: u32,
    height: u32,
    near: T,
    kernel: T,
    compensate: bool,
}

impl<T: Float> ProjectEwa<T> {
    /// The projection for `camera` with a 2D filter and a near plane.
    pub fn new(camera: &Camera, filter: Filter2d, near: f64) -> Self {
        let r = camera.rotation();
        let t = camera.translation();
        let rot = [
            [T::of(r.x_axis.x), T::of(r.y_axis.x), T::of(r.z_axis.x)],
            [T::of(r.x_axis.y), T::of(r.y_axis.y), T::of(r.z_axis.y)],
            [T::of(r.x_axis.z), T::of(r.y_axis.z), T::of(r.z_axis.z)],
        ];
        let (w, h) = (camera.width as f64, camera.height as f64);
        let tx = camera.tan_half_fov_x();
        let ty = camera.tan_half_fov_y();
        ProjectEwa {
            rot,
            trans: [T::of(t.x), T::of(t.y), T::of(t.z)],
            fx: T::of(camera.fx),
            fy: T::of(camera.fy),
            cx: T::of(camera.cx),
            cy: T::of(camera.cy),
            lim_x: (
                T::of(camera.cx / camera.fx + FRUSTUM_MARGIN * tx),
                T::of((w - camera.cx) / camera.fx + FRUSTUM_MARGIN * tx),
            ),
            lim_y: (
                T::of(camera.cy / camera.fy + FRUSTUM_MARGIN * ty),
                T::of((h - camera.cy) / camera.fy + FRUSTUM_MARGIN * ty),
            ),
            width: camera.width,
            height: camera.height,
            near: T::of(near),
            kernel: T::of(filter.variance()),
            compensate: filter.compensates(),
        }
    }
}

/// One projected Gaussian (forward result row).
struct Row<T> {
    m2: [T; 2],
    con: [T; 3],
    op: T,
    dep: T,
    rad: T,
    saved: ProjSaved<T>,
}

/// Per-Gaussian values the forward keeps for the backward.
#[derive(Clone, Copy)]
pub struct ProjSaved<T> {
    visible: bool,
    t: [T; 3],
    /// Clamped x/z and y/z and whether each was clamped.
    u: (T, bool),
    v: (T, bool),
    /// Undilated 2D covariance (a, b, c).
    cov: [T; 3],
    comp: T,
}

/// Pixel-centre range `[lo, hi]` (inclusive indices) of centres within `r` of `m`,
/// clamped to `[0, size)`; `None` when empty. Pixel `i` has its centre at `i + 0.5`.
pub(crate) fn pixel_range(m: f64, r: f64, size: u32) -> Option<(u32, u32)> {
    let lo = (m - r - 0.5).ceil().max(0.0);
    let hi = (m + r - 0.5).floor().min(size as f64 - 1.0);
    (lo <= hi).then_some((lo as u32, hi as u32))
}

impl<T: Float> ProjectEwa<T> {
    fn jacobian(&self, t: [T; 3], xc: T, yc: T) -> [[T; 3]; 2] {
        let z = t[2];
        let z2 = z * z;
        [
            [self.fx / z, T::zero(), -self.fx * xc / z2],
            [T::zero(), self.fy / z, -self.fy * yc / z2],
        ]
    }
}

fn clamp_flag<T: Float>(x: T, lo: T, hi: T) -> (T, bool) {
    if x < -lo {
        (-lo, true)
    } else if x > hi {
        (hi, true)
    } else {
        (x, false)
    }
}

impl<T: Float> Op<T> for ProjectEwa<T> {
    type Saved = Vec<ProjSaved<T>>;

    fn name(&self) -> String {
        "project_ewa".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, Self::Saved) {
        let (means, cov3d, opac) = (inputs[0], inputs[1], inputs[2]);
        let n = means.rows();
        assert_eq!(means.shape(), &[n, 3], "project_ewa: means must be [N,3]");
        assert_eq!(cov3d.shape(), &[n, 6], "project_ewa: cov3d must be [N,6]");
        assert_eq!(opac.shape(), &[n], "project_ewa: opacity must be [N]");
        let zero = T::zero();
        let mut m2 = vec![zero; 2 * n];
        let mut con = vec![zero; 3 * n];
        let mut op = vec![zero; n];
        let mut dep = vec![zero; n];
        let mut rad = vec![zero; n];
        let mut saved = vec![
            ProjSaved {
                visible: false,
                t: [zero; 3],
                u: (zero, false),
                v: (zero, false),
                cov: [zero; 3],
                comp: zero,
            };
            n
        ];
        let rt = transpose3(&self.rot);
        let one = |i: usize| -> Option<Row<T>> {
            let mu = [
                means.data()[3 * i],
                means.data()[3 * i + 1],
                means.data()[3 * i + 2],
            ];
            let tm = mul3v(&self.rot, mu);
            let t = [
                tm[0] + self.trans[0],
                tm[1] + self.trans[1],
                tm[2] + self.trans[2],
            ];
            if t[2] <= self.near {
                return None; // culled: outputs stay 0 (NaN compares false and is kept)
            }
            let z = t[2];
            let mx = self.fx * t[0] / z + self.cx;
            let my = self.fy * t[1] / z + self.cy;
            let u = clamp_flag(t[0] / z, self.lim_x.0, self.lim_x.1);
            let v = clamp_flag(t[1] / z, self.lim_y.0, self.lim_y.1);
            let j = self.jacobian(t, u.0 * z, v.0 * z);
            let sig = sym_from6(&cov3d.data()[6 * i..6 * i + 6]);
            let sc = mul3(&mul3(&self.rot, &sig), &rt);
            // cov2d = J Sc J^T with J's zero entries skipped.
            let js = |r: usize| mul3tv(&sc, j[r]);
            let (j0s, j1s) = (js(0), js(1));
            let dot = |a: [T; 3], b: [T; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            let a = dot(j0s, j[0]);
            let b = dot(j0s, j[1]);
            let c = dot(j1s, j[1]);
            let det0 = a * c - b * b;
            let (ad, cd) = (a + self.kernel, c + self.kernel);
            let det = ad * cd - b * b;
            let comp = if !self.compensate {
                T::one()
            } else if det0 > zero {
                (det0 / det).sqrt()
            } else if !det0.is_finite() {
                det0
            } else {
                zero
            };
            let op = opac.data()[i] * comp;
            let nonfinite =
                !(det.is_finite() && mx.is_finite() && my.is_finite() && op.is_finite());
            if !nonfinite && det <= zero {
                return None;
            }
            let mid = T::of(0.5) * (ad + cd);
            let lam = mid + (mid * mid - det).max(T::of(0.1)).sqrt();
            let r = (T::of(support_sigmas(op.to_f64())) * lam.sqrt()).ceil();
            if !nonfinite {
                if r <= zero {
                    return None;
                }
                let (rf, mxf, myf) = (r.to_f64(), mx.to_f64(), my.to_f64());
                if pixel_range(mxf, rf, self.width).is_none()
                    || pixel_range(myf, rf, self.height).is_none()
                {
                    return None;
                }
            }
            Some(Row {
                m2: [mx, my],
                con: [cd / det, -b / det, ad / det],
                op,
                dep: z,
                rad: if nonfinite { zero } else { r },
                saved: ProjSaved {
                    visible: !nonfinite,
                    t,
                    u,
                    v,
                    cov: [a, b, c],
                    comp,
                },
            })
        };
        let rows: Vec<Option<Row<T>>> = (0..n).into_par_iter().map(one).collect();
        for (i, row) in rows.into_iter().enumerate() {
            if let Some(r) = row {
                m2[2 * i..2 * i + 2].copy_from_slice(&r.m2);
                con[3 * i..3 * i + 3].copy_from_slice(&r.con);
                op[i] = r.op;
                dep[i] = r.dep;
                rad[i] = r.rad;
                saved[i] = r.saved;
            }
        }
        (
            vec![
                Tensor::from_vec(m2, &[n, 2]),
                Tensor::from_vec(con, &[n, 3]),
                Tensor::from_vec(op, &[n]),
                Tensor::from_vec(dep, &[n]),
                Tensor::from_vec(rad, &[n]),
            ],
            saved,
        )
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, Self::Saved>) -> Vec<Option<Tensor<T>>> {
        let (cov3d, opac) = (ctx.inputs[1], ctx.inputs[2]);
        let n = opac.len();
        let conics = ctx.outputs[1];
        let (v_means2d, v_conics, v_opacities2d, v_depths) = (
            &ctx.grad_outputs[0],
            &ctx.grad_outputs[1],
            &ctx.grad_outputs[2],
            &ctx.grad_outputs[3],
        );
        let zero = T::zero();
        let half = T::of(0.5);
        let two = T::of(2.0);
        let mut v_means = vec![zero; 3 * n];
        let mut v_cov3d = vec![zero; 6 * n];
        let mut v_opacities = vec![zero; n];
        let one = |i: usize| -> Option<([T; 3], [T; 6], T)> {
            let sv = &ctx.saved[i];
            if !sv.visible {
                return None;
            }
            let [tx, ty, tz] = sv.t;
            let [a, b, c] = sv.cov;
            // opacity' = o * comp
            let v_opacity2d = v_opacities2d.data()[i];
            let v_opacity = v_opacity2d * sv.comp;
            let v_comp = v_opacity2d * opac.data()[i];
            // conic = inverse of the dilated covariance (a+k, b; b, c+k)
            let (ca, cb, cc) = (
                conics.data()[3 * i],
                conics.data()[3 * i + 1],
                conics.data()[3 * i + 2],
            );
            let (v_conic_a, v_conic_b, v_conic_c) = (
                v_conics.data()[3 * i],
                v_conics.data()[3 * i + 1],
                v_conics.data()[3 * i + 2],
            );
            let mut v_a = -(v_conic_a * ca * ca + v_conic_b * ca * cb + v_conic_c * cb * cb);
            let mut v_c = -(v_conic_a * cb * cb + v_conic_b * cb * cc + v_conic_c * cc * cc);
            let mut v_b = -(two * v_conic_a * ca * cb
                + v_conic_b * (ca * cc + cb * cb)
                + two * v_conic_c * cb * cc);
            // comp = sqrt(det0 / det1): d comp = comp/2 (d det0/det0 - d det1/det1)
            if self.compensate && sv.comp > zero {
                let det0 = a * c - b * b;
                let (ad, cd) = (a + self.kernel, c + self.kernel);
                let det1 = ad * cd - b * b;
                let h = v_comp * half * sv.comp;
                v_a += h * (c / det0 - cd / det1);
                v_c += h * (a / det0 - ad / det1);
                v_b += h * (-two * b / det0 + two * b / det1);
            }
            // cov2d = J Sc J^T
            let j = self.jacobian(sv.t, sv.u.0 * tz, sv.v.0 * tz);
            let sig = sym_from6(&cov3d.data()[6 * i..6 * i + 6]);
            let rt = transpose3(&self.rot);
            let sc = mul3(&mul3(&self.rot, &sig), &rt);
            let v_cov2d = [[v_a, half * v_b], [half * v_b, v_c]];
            // dL/dSc = J^T G2 J
            let mut v_cov_cam = [[zero; 3]; 3];
            for p in 0..3 {
                for q in 0..3 {
                    let mut acc = zero;
                    for r in 0..2 {
                        for s in 0..2 {
                            acc += j[r][p] * v_cov2d[r][s] * j[s][q];
                        }
                    }
                    v_cov_cam[p][q] = acc;
                }
            }
            // dL/dJ = 2 G2 J Sc
            let mut v_jac = [[zero; 3]; 2];
            for r in 0..2 {
                let row = [
                    v_cov2d[r][0] * j[0][0] + v_cov2d[r][1] * j[1][0],
                    v_cov2d[r][0] * j[0][1] + v_cov2d[r][1] * j[1][1],
                    v_cov2d[r][0] * j[0][2] + v_cov2d[r][1] * j[1][2],
                ];
                let rs = mul3tv(&sc, row);
                for q in 0..3 {
                    v_jac[r][q] = two * rs[q];
                }
            }
            // dL/dSigma = R^T G_sc R, packed (off-diagonals doubled).
            let v_covar = mul3(&mul3(&rt, &v_cov_cam), &self.rot);
            let mut v_cov3d_i = [zero; 6];
            v_cov3d_i[0] = v_covar[0][0];
            v_cov3d_i[1] = v_covar[0][1] + v_covar[1][0];
            v_cov3d_i[2] = v_covar[0][2] + v_covar[2][0];
            v_cov3d_i[3] = v_covar[1][1];
            v_cov3d_i[4] = v_covar[1][2] + v_covar[2][1];
            v_cov3d_i[5] = v_covar[2][2];
            // J(t): J00 = fx/z, J02 = -fx x'/z^2, J11 = fy/z, J12 = -fy y'/z^2
            let (xc, yc) = (sv.u.0 * tz, sv.v.0 * tz);
            let z2 = tz * tz;
            let z3 = z2 * tz;
            let mut v_mean_c = [zero; 3];
            v_mean_c[2] += -v_jac[0][0] * self.fx / z2 - v_jac[1][1] * self.fy / z2
                + v_jac[0][2] * two * self.fx * xc / z3
                + v_jac[1][2] * two * self.fy * yc / z3;
            let v_xc = -v_jac[0][2] * self.fx / z2;
            let v_yc = -v_jac[1][2] * self.fy / z2;
            // x' = x when unclamped, z * lim when clamped (gradient goes to z).
            if sv.u.1 {
                v_mean_c[2] += v_xc * sv.u.0;
            } else {
                v_mean_c[0] += v_xc;
            }
            if sv.v.1 {
                v_mean_c[2] += v_yc * sv.v.0;
            } else {
                v_mean_c[1] += v_yc;
            }
            // means2d = (fx x/z + cx, fy y/z + cy)
            let (v_mx, v_my) = (v_means2d.data()[2 * i], v_means2d.data()[2 * i + 1]);
            v_mean_c[0] += v_mx * self.fx / tz;
            v_mean_c[1] += v_my * self.fy / tz;
            v_mean_c[2] += -v_mx * self.fx * tx / z2 - v_my * self.fy * ty / z2;
            v_mean_c[2] += v_depths.data()[i];
            Some((mul3tv(&self.rot, v_mean_c), v_cov3d_i, v_opacity))
        };
        let rows: Vec<_> = (0..n).into_par_iter().map(one).collect();
        for (i, row) in rows.into_iter().enumerate() {
            if let Some((v_mean, v_cov, v_op)) = row {
                v_means[3 * i..3 * i + 3].copy_from_slice(&v_mean);
                v_cov3d[6 * i..6 * i + 6].copy_from_slice(&v_cov);
                v_opacities[i] = v_op;
            }
        }
        vec![
            Some(Tensor::from_vec(v_means, &[n, 3])),
            Some(Tensor::from_vec(v_cov3d, &[n, 6])),
            Some(Tensor::from_vec(v_opacities, &[n])),
        ]
    }
}

/// The outputs of [`project_ewa`] on the tape.
pub struct Projected<'t, T: Float> {
    /// Screen-space means `[N,2]` in pixels (differentiable; its gradient is the
    /// densification statistic).
    pub means2d: Var<'t, T>,
    /// Inverse dilated 2D covariances `(A, B, C)`, `[N,3]`.
    pub conics: Var<'t, T>,
    /// Opacity after the 2D filter compensation, `[N]`.
    pub opacity: Var<'t, T>,
    /// Camera-space depth `z`, `[N]`.
    pub depths: Var<'t, T>,
    /// Screen-space radius in pixels (0 = culled), `[N]`, not differentiable.
    pub radii: Var<'t, T>,
}

/// Projects Gaussians on the tape, see [`ProjectEwa`].
pub fn project_ewa<'t, T: Float>(
    means: Var<'t, T>,
    cov3d: Var<'t, T>,
    opacity: Var<'t, T>,
    camera: &Camera,
    filter: Filter2d,
    near: f64,
) -> Projected<'t, T> {
    let out = means.tape().apply(
        ProjectEwa::new(camera, filter, near),
        &[means, cov3d, opacity],
    );
    Projected {
        means2d: out[0],
        conics: out[1],
        opacity: out[2],
        depths: out[3],
        radii: out[4],
    }
}
