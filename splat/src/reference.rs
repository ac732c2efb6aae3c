//! Slow, obviously-correct reference implementations (DESIGN.md section 3), written
//! independently of the fast path: no tiles, no binning, no shared kernels.
//!
//! * [`render`]: per-pixel, per-Gaussian forward oracle over all Gaussians in global
//!   `(depth, index)` order, with the same rules as the fast path (used to test it
//!   to 1e-5 in f32).
//! * [`tape`]: the same stages built from differentiable primitives of
//!   `maaf-autodiff`, used as `check_vjp` references for the hand-written backwards
//!   (the rasterizer only in [`AlphaCutoff::Smooth`] mode, which primitives can
//!   express).

use maaf_autodiff::{Float, Tensor};

use crate::Camera;
use crate::rasterize::{
    ALPHA_MAX, ALPHA_MIN, AlphaCutoff, SMOOTH_TAPER_START, SUPPORT_POWER, T_MIN,
};
use crate::render::RenderSettings;
use crate::sh::{SH_C0, SH_C1, SH_C2, SH_C3};

type Mat<T> = [[T; 3]; 3];

fn matmul<T: Float>(a: &Mat<T>, b: &Mat<T>) -> Mat<T> {
    let mut c = [[T::zero(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                c[i][j] += a[i][k] * b[k][j];
            }
        }
    }
    c
}

fn transpose<T: Float>(a: &Mat<T>) -> Mat<T> {
    let mut c = [[T::zero(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[j][i];
        }
    }
    c
}

/// Rotation from a unit quaternion via `R = (w^2 - |v|^2) I + 2 v v^T + 2 w [v]_x`.
fn rotation<T: Float>(w: T, v: [T; 3]) -> Mat<T> {
    let two = T::of(2.0);
    let vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let cross = [
        [T::zero(), -v[2], v[1]],
        [v[2], T::zero(), -v[0]],
        [-v[1], v[0], T::zero()],
    ];
    let mut r = [[T::zero(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let diag = if i == j { w * w - vv } else { T::zero() };
            r[i][j] = diag + two * v[i] * v[j] + two * w * cross[i][j];
        }
    }
    r
}

/// 3D covariance `R diag(s^2) R^T` for an unnormalised quaternion `(w,x,y,z)`.
pub fn covariance<T: Float>(q: [T; 4], s: [T; 3]) -> [[T; 3]; 3] {
    let norm = q.iter().map(|&x| x * x).sum::<T>().sqrt();
    let r = rotation(q[0] / norm, [q[1] / norm, q[2] / norm, q[3] / norm]);
    let d = [
        [s[0] * s[0], T::zero(), T::zero()],
        [T::zero(), s[1] * s[1], T::zero()],
        [T::zero(), T::zero(), s[2] * s[2]],
    ];
    matmul(&matmul(&r, &d), &transpose(&r))
}

/// SH colour `max(sum_k b_k(d) sh_k + 0.5, 0)` for a unit direction `d`.
pub fn sh_colour<T: Float>(d: [T; 3], coeffs: &[[T; 3]], degree: usize) -> [T; 3] {
    let [x, y, z] = d;
    let k = |c: f64| T::of(c);
    let mut basis = vec![k(SH_C0)];
    if degree >= 1 {
        basis.extend([-k(SH_C1) * y, k(SH_C1) * z, -k(SH_C1) * x]);
    }
    if degree >= 2 {
        basis.extend([
            k(SH_C2[0]) * x * y,
            k(SH_C2[1]) * y * z,
            k(SH_C2[2]) * (k(2.0) * z * z - x * x - y * y),
            k(SH_C2[3]) * x * z,
            k(SH_C2[4]) * (x * x - y * y),
        ]);
    }
    if degree >= 3 {
        let (x2, y2, z2) = (x * x, y * y, z * z);
        basis.extend([
            k(SH_C3[0]) * (k(3.0) * x2 * y - y2 * y),
            k(SH_C3[1]) * x * y * z,
            k(SH_C3[2]) * (k(4.0) * z2 * y - x2 * y - y2 * y),
            k(SH_C3[3]) * (k(2.0) * z2 * z - k(3.0) * x2 * z - k(3.0) * y2 * z),
            k(SH_C3[4]) * (k(4.0) * z2 * x - x2 * x - y2 * x),
            k(SH_C3[5]) * (x2 * z - y2 * z),
            k(SH_C3[6]) * (x2 * x - k(3.0) * y2 * x),
        ]);
    }
    let mut out = [T::zero(); 3];
    for (c, o) in out.iter_mut().enumerate() {
        let v = basis.iter().zip(coeffs).map(|(b, s)| *b * s[c]).sum::<T>() + k(0.5);
        *o = v.max(T::zero());
    }
    out
}

/// One projected Gaussian of the reference.
#[derive(Clone, Copy, Debug)]
pub struct RefSplat<T> {
    /// Pixel-space mean.
    pub mean: [T; 2],
    /// Inverse of the dilated 2D covariance.
    pub conic: [[T; 2]; 2],
    /// Opacity after compensation.
    pub opacity: T,
    /// Camera depth.
    pub depth: T,
    /// Colour.
    pub colour: [T; 3],
}

/// `(mean2d, conic, opacity, depth)` of one projected Gaussian.
pub type Projected2d<T> = ([T; 2], [[T; 2]; 2], T, T);

/// Projects Gaussian `(mean, cov3d, opacity)` for `camera`; `None` when behind the
/// near plane or degenerate.
pub fn project<T: Float>(
    mean: [T; 3],
    cov: &Mat<T>,
    opacity: T,
    camera: &Camera,
    settings: &RenderSettings,
) -> Option<Projected2d<T>> {
    let m = camera.world_to_camera;
    let w: Mat<T> = [
        [T::of(m[0][0]), T::of(m[0][1]), T::of(m[0][2])],
        [T::of(m[1][0]), T::of(m[1][1]), T::of(m[1][2])],
        [T::of(m[2][0]), T::of(m[2][1]), T::of(m[2][2])],
    ];
    let mut t = [T::of(m[0][3]), T::of(m[1][3]), T::of(m[2][3])];
    for i in 0..3 {
        for j in 0..3 {
            t[i] += w[i][j] * mean[j];
        }
    }
    if t[2] <= T::of(settings.near) {
        return None;
    }
    let (fx, fy, cx, cy) = (
        T::of(camera.fx),
        T::of(camera.fy),
        T::of(camera.cx),
        T::of(camera.cy),
    );
    let (wd, ht) = (T::of(camera.width as f64), T::of(camera.height as f64));
    let tanx = wd / (T::of(2.0) * fx);
    let tany = ht / (T::of(2.0) * fy);
    let m03 = T::of(0.3);
    let xr = (t[0] / t[2])
        .max(-(cx / fx + m03 * tanx))
        .min((wd - cx) / fx + m03 * tanx);
    let yr = (t[1] / t[2])
        .max(-(cy / fy + m03 * tany))
        .min((ht - cy) / fy + m03 * tany);
    let z = t[2];
    // 2x3 Jacobian of (fx x/z, fy y/z) at the clamped point, as a 3x3 with a zero row.
    let j: Mat<T> = [
        [fx / z, T::zero(), -fx * xr / z],
        [T::zero(), fy / z, -fy * yr / z],
        [T::zero(), T::zero(), T::zero()],
    ];
    let jw = matmul(&j, &w);
    let full = matmul(&matmul(&jw, cov), &transpose(&jw));
    let k = T::of(settings.filter2d.variance());
    let c0 = [[full[0][0], full[0][1]], [full[1][0], full[1][1]]];
    let det0 = c0[0][0] * c0[1][1] - c0[0][1] * c0[1][0];
    let c1 = [[c0[0][0] + k, c0[0][1]], [c0[1][0], c0[1][1] + k]];
    let det1 = c1[0][0] * c1[1][1] - c1[0][1] * c1[1][0];
    if det1 <= T::zero() {
        return None;
    }
    let conic = [
        [c1[1][1] / det1, -c1[0][1] / det1],
        [-c1[1][0] / det1, c1[0][0] / det1],
    ];
    let o = if settings.filter2d.compensates() {
        opacity * (det0.max(T::zero()) / det1).sqrt()
    } else {
        opacity
    };
    let mean2 = [fx * t[0] / z + cx, fy * t[1] / z + cy];
    Some((mean2, conic, o, z))
}

/// Reference render of activated parameters: returns `(image [H,W,3], alpha [H,W],
/// depth [H,W])`. Every pixel visits every projected Gaussian in global
/// `(depth, index)` order.
pub fn render<T: Float>(
    means: &Tensor<T>,
    scales: &Tensor<T>,
    quats: &Tensor<T>,
    opacity: &Tensor<T>,
    sh: &Tensor<T>,
    camera: &Camera,
    settings: &RenderSettings,
) -> (Tensor<T>, Tensor<T>, Tensor<T>) {
    let n = opacity.len();
    let k = sh.shape()[1];
    let nk = (settings.sh_degree + 1) * (settings.sh_degree + 1);
    let cam = camera.center();
    let mut splats: Vec<(usize, RefSplat<T>)> = Vec::new();
    for i in 0..n {
        let mu = [
            means.data()[3 * i],
            means.data()[3 * i + 1],
            means.data()[3 * i + 2],
        ];
        let q = [
            quats.data()[4 * i],
            quats.data()[4 * i + 1],
            quats.data()[4 * i + 2],
            quats.data()[4 * i + 3],
        ];
        let s = [
            scales.data()[3 * i],
            scales.data()[3 * i + 1],
            scales.data()[3 * i + 2],
        ];
        let cov = covariance(q, s);
        let Some((mean, conic, o, depth)) = project(mu, &cov, opacity.data()[i], camera, settings)
        else {
            continue;
        };
        let d = [
            mu[0] - T::of(cam.x),
            mu[1] - T::of(cam.y),
            mu[2] - T::of(cam.z),
        ];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let coeffs: Vec<[T; 3]> = (0..nk)
            .map(|j| {
                let base = (i * k + j) * 3;
                [sh.data()[base], sh.data()[base + 1], sh.data()[base + 2]]
            })
            .collect();
        let colour = sh_colour(
            [d[0] / len, d[1] / len, d[2] / len],
            &coeffs,
            settings.sh_degree,
        );
        splats.push((
            i,
            RefSplat {
                mean,
                conic,
                opacity: o,
                depth,
                colour,
            },
        ));
    }
    splats.sort_by(|a, b| {
        a.1.depth
            .partial_cmp(&b.1.depth)
            .unwrap_or(std::cmp::Ordering::Equal)
            .then(a.0.cmp(&b.0))
    });
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut image = vec![T::zero(); h * w * 3];
    let mut alpha = vec![T::zero(); h * w];
    let mut depth = vec![T::zero(); h * w];
    for y in 0..h {
        for x in 0..w {
            let q = [T::of(x as f64 + 0.5), T::of(y as f64 + 0.5)];
            let mut trans = T::one();
            let mut acc = [T::zero(); 3];
            let mut dacc = T::zero();
            for (_, s) in &splats {
                let d = [q[0] - s.mean[0], q[1] - s.mean[1]];
                let mut power = T::zero();
                for a in 0..2 {
                    for b in 0..2 {
                        power += d[a] * s.conic[a][b] * d[b];
                    }
                }
                power *= T::of(0.5);
                if power < T::zero() || power > T::of(SUPPORT_POWER) {
                    continue;
                }
                let al = match settings.alpha_cutoff {
                    AlphaCutoff::Hard => {
                        let raw = s.opacity * (-power).exp();
                        if raw < T::of(ALPHA_MIN) {
                            continue;
                        }
                        raw.min(T::of(ALPHA_MAX))
                    }
                    AlphaCutoff::Smooth => {
                        let u = ((power - T::of(SMOOTH_TAPER_START))
                            / T::of(SUPPORT_POWER - SMOOTH_TAPER_START))
                        .max(T::zero());
                        let win = (T::one() - u * u).max(T::zero());
                        s.opacity * (-power).exp() * win * win
                    }
                };
                if al <= T::zero() {
                    continue;
                }
                let after = trans * (T::one() - al);
                if settings.alpha_cutoff == AlphaCutoff::Hard && after < T::of(T_MIN) {
                    break;
                }
                for c in 0..3 {
                    acc[c] += s.colour[c] * al * trans;
                }
                dacc += s.depth * al * trans;
                trans = after;
            }
            let p = y * w + x;
            for c in 0..3 {
                image[3 * p + c] = acc[c] + trans * T::of(settings.background[c]);
            }
            alpha[p] = T::one() - trans;
            depth[p] = dacc;
        }
    }
    (
        Tensor::from_vec(image, &[h, w, 3]),
        Tensor::from_vec(alpha, &[h, w]),
        Tensor::from_vec(depth, &[h, w]),
    )
}

/// The pipeline stages built from differentiable primitives (check_vjp references).
pub mod tape {
    use maaf_autodiff::ops::concat;
    use maaf_autodiff::{Float, Tape, Tensor, Var};

    use crate::Camera;
    use crate::project::{FRUSTUM_MARGIN, Filter2d};
    use crate::rasterize::{SMOOTH_TAPER_START, SUPPORT_POWER};
    use crate::sh::{SH_C0, SH_C1, SH_C2, SH_C3};

    fn col<'t, T: Float>(x: Var<'t, T>, j: usize) -> Var<'t, T> {
        x.slice(1, j, j + 1)
    }

    /// `(sqrt(s^2 + var), o sqrt(prod s^2 / prod (s^2 + var)))` from primitives.
    pub fn apply_3d_filter<'t, T: Float>(
        t: &'t Tape<T>,
        scales: Var<'t, T>,
        opacity: Var<'t, T>,
        var: &Tensor<T>,
    ) -> (Var<'t, T>, Var<'t, T>) {
        let n = var.len();
        let v = t.constant(var.clone().reshaped(&[n, 1]));
        let s2 = scales.square();
        let s2v = s2 + v;
        let ratio = s2 / s2v;
        let prod = col(ratio, 0) * col(ratio, 1) * col(ratio, 2);
        (s2v.sqrt(), opacity * prod.sqrt().reshape(&[n]))
    }

    /// Packed covariance `[N,6]` from `quats [N,4]` and `scales [N,3]`.
    pub fn quat_scale_to_cov<'t, T: Float>(quats: Var<'t, T>, scales: Var<'t, T>) -> Var<'t, T> {
        let n = quats.shape()[0];
        let norm = quats.square().sum_axis(1).sqrt().reshape(&[n, 1]);
        let q = quats / norm;
        let (w, x, y, z) = (col(q, 0), col(q, 1), col(q, 2), col(q, 3));
        let one = |v: Var<'t, T>| v.add_scalar(1.0);
        let r = [
            [
                one((y.square() + z.square()).scale(-2.0)),
                (x * y - w * z).scale(2.0),
                (x * z + w * y).scale(2.0),
            ],
            [
                (x * y + w * z).scale(2.0),
                one((x.square() + z.square()).scale(-2.0)),
                (y * z - w * x).scale(2.0),
            ],
            [
                (x * z - w * y).scale(2.0),
                (y * z + w * x).scale(2.0),
                one((x.square() + y.square()).scale(-2.0)),
            ],
        ];
        let s2 = scales.square();
        let mut cols = Vec::new();
        for a in 0..3 {
            for b in a..3 {
                let terms: Vec<Var<'t, T>> =
                    (0..3).map(|j| r[a][j] * r[b][j] * col(s2, j)).collect();
                cols.push(terms[0] + terms[1] + terms[2]);
            }
        }
        concat(&cols, 1)
    }

    /// `clamp(u, -lo, hi)` from relu: `u - relu(u - hi) + relu(-lo - u)`.
    fn clamp<'t, T: Float>(u: Var<'t, T>, lo: f64, hi: f64) -> Var<'t, T> {
        u - u.add_scalar(-hi).relu() + (-u).add_scalar(-lo).relu()
    }

    /// EWA projection from primitives for Gaussians all in front of the camera:
    /// returns `[means2d [N,2], conics [N,3], opacity [N], depths [N]]`.
    pub fn project<'t, T: Float>(
        t: &'t Tape<T>,
        means: Var<'t, T>,
        cov6: Var<'t, T>,
        opacity: Var<'t, T>,
        camera: &Camera,
        filter: Filter2d,
    ) -> Vec<Var<'t, T>> {
        let n = means.shape()[0];
        let m = camera.world_to_camera;
        let w = |i: usize, j: usize| m[i][j];
        let mu = [col(means, 0), col(means, 1), col(means, 2)];
        let tc: Vec<Var<'t, T>> = (0..3)
            .map(|i| {
                (mu[0].scale(w(i, 0)) + mu[1].scale(w(i, 1)) + mu[2].scale(w(i, 2)))
                    .add_scalar(m[i][3])
            })
            .collect();
        let idx = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];
        let sig = |a: usize, b: usize| col(cov6, idx[a][b]);
        // Sc = W Sigma W^T, entry by entry.
        let mut sc: Vec<Vec<Var<'t, T>>> = Vec::new();
        for p in 0..3 {
            let mut row = Vec::new();
            for q in 0..3 {
                let mut acc: Option<Var<'t, T>> = None;
                for a in 0..3 {
                    for b in 0..3 {
                        let term = sig(a, b).scale(w(p, a) * w(q, b));
                        acc = Some(match acc {
                            None => term,
                            Some(v) => v + term,
                        });
                    }
                }
                row.push(acc.expect("nine terms"));
            }
            sc.push(row);
        }
        let (fx, fy) = (camera.fx, camera.fy);
        let (tanx, tany) = (camera.tan_half_fov_x(), camera.tan_half_fov_y());
        let z = tc[2];
        let inv_z = z.powf(-1.0);
        let u = clamp(
            tc[0] * inv_z,
            camera.cx / fx + FRUSTUM_MARGIN * tanx,
            (camera.width as f64 - camera.cx) / fx + FRUSTUM_MARGIN * tanx,
        );
        let v = clamp(
            tc[1] * inv_z,
            camera.cy / fy + FRUSTUM_MARGIN * tany,
            (camera.height as f64 - camera.cy) / fy + FRUSTUM_MARGIN * tany,
        );
        let j00 = inv_z.scale(fx);
        let j02 = (u * inv_z).scale(-fx);
        let j11 = inv_z.scale(fy);
        let j12 = (v * inv_z).scale(-fy);
        let a =
            j00.square() * sc[0][0] + (j00 * j02 * sc[0][2]).scale(2.0) + j02.square() * sc[2][2];
        let b = j00 * j11 * sc[0][1]
            + j00 * j12 * sc[0][2]
            + j02 * j11 * sc[2][1]
            + j02 * j12 * sc[2][2];
        let c =
            j11.square() * sc[1][1] + (j11 * j12 * sc[1][2]).scale(2.0) + j12.square() * sc[2][2];
        let k = filter.variance();
        let ad = a.add_scalar(k);
        let cd = c.add_scalar(k);
        let det1 = ad * cd - b.square();
        let conics = concat(&[cd / det1, -b / det1, ad / det1], 1);
        let op = if filter.compensates() {
            let det0 = a * c - b.square();
            opacity * (det0 / det1).sqrt().reshape(&[n])
        } else {
            let _ = t;
            opacity.scale(1.0)
        };
        let mx = (tc[0] * inv_z).scale(fx).add_scalar(camera.cx);
        let my = (tc[1] * inv_z).scale(fy).add_scalar(camera.cy);
        vec![concat(&[mx, my], 1), conics, op, z.reshape(&[n])]
    }

    /// SH colour from primitives: `relu(sum_k b_k(d) sh[:,k,:] + 0.5)`, `[N,3]`.
    pub fn sh_color<'t, T: Float>(
        t: &'t Tape<T>,
        means: Var<'t, T>,
        sh: Var<'t, T>,
        campos: [f64; 3],
        degree: usize,
    ) -> Var<'t, T> {
        let n = means.shape()[0];
        let cam = t.constant(Tensor::from_f64(&campos, &[3]));
        let d = means - cam;
        let len = d.square().sum_axis(1).sqrt().reshape(&[n, 1]);
        let d = d / len;
        let (x, y, z) = (col(d, 0), col(d, 1), col(d, 2));
        let c0 = x.scale(0.0).add_scalar(SH_C0);
        let mut basis = vec![c0];
        if degree >= 1 {
            basis.extend([y.scale(-SH_C1), z.scale(SH_C1), x.scale(-SH_C1)]);
        }
        if degree >= 2 {
            let (xx, yy, zz) = (x.square(), y.square(), z.square());
            basis.extend([
                (x * y).scale(SH_C2[0]),
                (y * z).scale(SH_C2[1]),
                (zz.scale(2.0) - xx - yy).scale(SH_C2[2]),
                (x * z).scale(SH_C2[3]),
                (xx - yy).scale(SH_C2[4]),
            ]);
        }
        if degree >= 3 {
            let (xx, yy, zz) = (x.square(), y.square(), z.square());
            basis.extend([
                (y * (xx.scale(3.0) - yy)).scale(SH_C3[0]),
                (x * y * z).scale(SH_C3[1]),
                (y * (zz.scale(4.0) - xx - yy)).scale(SH_C3[2]),
                (z * (zz.scale(2.0) - xx.scale(3.0) - yy.scale(3.0))).scale(SH_C3[3]),
                (x * (zz.scale(4.0) - xx - yy)).scale(SH_C3[4]),
                (z * (xx - yy)).scale(SH_C3[5]),
                (x * (xx - yy.scale(3.0))).scale(SH_C3[6]),
            ]);
        }
        let mut acc: Option<Var<'t, T>> = None;
        for (k, b) in basis.into_iter().enumerate() {
            let coeff = sh.slice(1, k, k + 1).reshape(&[n, 3]);
            let term = b * coeff;
            acc = Some(match acc {
                None => term,
                Some(a) => a + term,
            });
        }
        acc.expect("degree 0 has one term").add_scalar(0.5).relu()
    }

    /// Smooth-cutoff compositing from primitives on an `H x W` image: returns
    /// `[image [H,W,3], alpha [H,W], depth [H,W]]`. Gaussians are composited in
    /// `(depth, index)` order; no culling (use in-view test scenes).
    #[allow(clippy::too_many_arguments)]
    pub fn rasterize_smooth<'t, T: Float>(
        t: &'t Tape<T>,
        means2d: Var<'t, T>,
        conics: Var<'t, T>,
        colors: Var<'t, T>,
        opacity: Var<'t, T>,
        depths: Var<'t, T>,
        width: usize,
        height: usize,
        background: [f64; 3],
    ) -> Vec<Var<'t, T>> {
        let n = opacity.shape()[0];
        let np = width * height;
        let px: Vec<f64> = (0..np).map(|p| (p % width) as f64 + 0.5).collect();
        let py: Vec<f64> = (0..np).map(|p| (p / width) as f64 + 0.5).collect();
        let px = t.constant(Tensor::from_f64(&px, &[np]));
        let py = t.constant(Tensor::from_f64(&py, &[np]));
        let mut order: Vec<usize> = (0..n).collect();
        {
            let d = depths.value();
            order.sort_by(|&a, &b| {
                d.data()[a]
                    .partial_cmp(&d.data()[b])
                    .unwrap_or(std::cmp::Ordering::Equal)
                    .then(a.cmp(&b))
            });
        }
        let scalar = |v: Var<'t, T>, i: usize, j: usize| {
            v.slice(0, i, i + 1).slice(1, j, j + 1).reshape(&[1])
        };
        let mut trans = t.constant(Tensor::full(&[np], T::one()));
        let mut img = t.constant(Tensor::zeros(&[np, 3]));
        let mut dep = t.constant(Tensor::zeros(&[np]));
        let span = SUPPORT_POWER - SMOOTH_TAPER_START;
        for &i in &order {
            let dx = px - scalar(means2d, i, 0);
            let dy = py - scalar(means2d, i, 1);
            let (a, b, c) = (
                scalar(conics, i, 0),
                scalar(conics, i, 1),
                scalar(conics, i, 2),
            );
            let power = (a * dx.square() + c * dy.square()).scale(0.5) + b * dx * dy;
            let q = power
                .add_scalar(-SMOOTH_TAPER_START)
                .scale(1.0 / span)
                .relu();
            let win = q.square().scale(-1.0).add_scalar(1.0).relu().square();
            let o = opacity.slice(0, i, i + 1);
            let alpha = o * (-power).exp() * win;
            let wgt = alpha * trans;
            let colour = colors.slice(0, i, i + 1); // [1,3]
            img = img + wgt.reshape(&[np, 1]) * colour;
            dep = dep + wgt * depths.slice(0, i, i + 1);
            trans = trans * (-alpha).add_scalar(1.0);
        }
        let bg = t.constant(Tensor::from_f64(&background, &[1, 3]));
        let img = img + trans.reshape(&[np, 1]) * bg;
        vec![
            img.reshape(&[height, width, 3]),
            (-trans).add_scalar(1.0).reshape(&[height, width]),
            dep.reshape(&[height, width]),
        ]
    }
}
