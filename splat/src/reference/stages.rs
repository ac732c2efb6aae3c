//! Per-Gaussian stages of the reference: covariance, SH colour and projection, each
//! written from its formula with plain loops.

use maaf_autodiff::Float;

use crate::Camera;
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
///
/// Deliberately not [`crate::quat_to_rotmat`]: the forward-vs-reference tests compare
/// the fast path, which uses that function, against this module, so the reference
/// writes the rotation in its own (vector) form from the formula; sharing the fast
/// one would let a sign or index slip in it pass both sides unnoticed.
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
