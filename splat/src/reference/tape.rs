//! The pipeline stages built from differentiable primitives of `maaf-autodiff`
//! (`check_vjp` references for the hand-written backwards).

use maaf_autodiff::ops::concat;
use maaf_autodiff::{Float, Tape, Tensor, Var};

use crate::Camera;
use crate::compositing::SMOOTH_TAPER_WIDTH;
use crate::project::{FRUSTUM_MARGIN, Filter2d};
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
            let terms: Vec<Var<'t, T>> = (0..3).map(|j| r[a][j] * r[b][j] * col(s2, j)).collect();
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
            (mu[0].scale(w(i, 0)) + mu[1].scale(w(i, 1)) + mu[2].scale(w(i, 2))).add_scalar(m[i][3])
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
    let a = j00.square() * sc[0][0] + (j00 * j02 * sc[0][2]).scale(2.0) + j02.square() * sc[2][2];
    let b =
        j00 * j11 * sc[0][1] + j00 * j12 * sc[0][2] + j02 * j11 * sc[2][1] + j02 * j12 * sc[2][2];
    let c = j11.square() * sc[1][1] + (j11 * j12 * sc[1][2]).scale(2.0) + j12.square() * sc[2][2];
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
/// `(depth, index)` order; no culling (use in-view test scenes with positive
/// opacities: the taper takes `ln(255 o)`).
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
    let scalar =
        |v: Var<'t, T>, i: usize, j: usize| v.slice(0, i, i + 1).slice(1, j, j + 1).reshape(&[1]);
    let mut trans = t.constant(Tensor::full(&[np], T::one()));
    let mut img = t.constant(Tensor::zeros(&[np, 3]));
    let mut dep = t.constant(Tensor::zeros(&[np]));
    for &i in &order {
        let dx = px - scalar(means2d, i, 0);
        let dy = py - scalar(means2d, i, 1);
        let (a, b, c) = (
            scalar(conics, i, 0),
            scalar(conics, i, 1),
            scalar(conics, i, 2),
        );
        let power = (a * dx.square() + c * dy.square()).scale(0.5) + b * dx * dy;
        let o = opacity.slice(0, i, i + 1);
        // q = relu(1 - r / width) with the headroom r = ln(255 o) - power.
        let q = (power - o.scale(255.0).ln())
            .scale(1.0 / SMOOTH_TAPER_WIDTH)
            .add_scalar(1.0)
            .relu();
        let win = q.square().scale(-1.0).add_scalar(1.0).relu().square();
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
