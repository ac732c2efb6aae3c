//! Model flow: the screen-space motion of a run's own Gaussians, rendered like colour.
//!
//! For Gaussian `k` with centre `mu_k(t)`, its projected displacement from `t` to
//! `t + 1` is `d_k = pi(mu_k(t + 1)) - pi(mu_k(t))` (pixels, `pi` the pinhole
//! projection of [`Camera::project`]). The flow of pixel `p` is the displacement
//! alpha-composited with the colour weights of frame `t`,
//! `w_k(p) = alpha_k(p) prod_{j < k} (1 - alpha_j(p))`, divided by the accumulated
//! opacity `A(p) = sum_k w_k(p)`:
//!
//! `F(p) = sum_k w_k(p) d_k / A(p)`   (0 where `A(p) < MIN_ALPHA`),
//!
//! the expected motion of the surface seen at `p` (the background does not move). The
//! division makes a single opaque translating Gaussian give its exact displacement,
//! which the renderer's per-Gaussian opacity cap of 0.99 would otherwise shrink.
//!
//! Channel 2 (validity) has the meaning of the exact flow's ([`maaf_data::flow`]): 1
//! when the surface seen at `p` in frame `t` is still visible in frame `t + 1`. It is
//! a forward depth-consistency test. With camera-space depths `z_k` of the centres,
//! the renderer's alpha-weighted depth `D(p) = sum_k w_k(p) z_k` and the composited
//! depth change `dZ(p) = sum_k w_k(p) (z_k(t + 1) - z_k(t))`, the surface seen at `p`
//! is predicted at depth `Z^(p) = (D_t(p) + dZ(p)) / A_t(p)` in frame `t + 1`, landing
//! in the pixel `q = floor(p + (0.5, 0.5) + F(p))` (the pixel
//! [`crate::metrics::temporal::warp_forward`] reads). Frame `t + 1` is rendered from
//! the Gaussians at `t + 1`, which gives `A_{t+1}` and `Z_{t+1}(q) = D_{t+1}(q) /
//! A_{t+1}(q)`. Then
//!
//! - `A_t(p) < MIN_ALPHA` (background at `t`): valid iff `A_{t+1}(p) < MIN_ALPHA`
//!   (it still sees nothing; the background does not move);
//! - otherwise valid iff `q` is inside the image, `A_{t+1}(q) >= MIN_ALPHA` and
//!   `|Z_{t+1}(q) - Z^(p)| <= DEPTH_TOLERANCE * Z^(p)`.
//!
//! A surface covered in `t + 1` by something in front of it (`Z_{t+1}(q)` well below
//! `Z^(p)`), one that moves out of the image, and one that vanishes (nothing drawn at
//! `q`, or only something behind it) are invalid, as in the exact flow, and
//! [`crate::metrics::temporal::warp_forward`] keeps frame `t` there for both flows.
//!
//! The sums are obtained from the renderer itself (the same tile rasteriser, cutoffs
//! and 2D filter as the colour render): two renders with degree-0 SH colours set to the
//! non-negative parts `(max(dx, 0), max(-dx, 0), max(dy, 0))` and
//! `(max(-dy, 0), max(dz, 0), max(-dz, 0))` on a black background, so the colour clamp
//! at 0 never acts, plus one render of the Gaussians at `t + 1` for `A_{t+1}` and
//! `D_{t+1}`.

use glam::DVec3;
use maaf_autodiff::Tensor;
use maaf_splat::sh::SH_C0;
use maaf_splat::{Camera, RenderSettings, render_tensors};

/// Accumulated opacity below which a pixel is treated as background (flow 0).
pub const MIN_ALPHA: f32 = 1e-4;

/// Relative depth tolerance `tau` of the validity test: the depth seen at the landing
/// pixel in frame `t + 1` may differ from the predicted one by `tau` times the latter
/// (5 %: an occluder must be at least 5 % closer to the camera to count).
pub const DEPTH_TOLERANCE: f64 = 0.05;

/// Row `k` of a `[N, 3]` tensor of centres as a point.
fn point(m: &Tensor<f32>, k: usize) -> DVec3 {
    let r = &m.data()[3 * k..3 * k + 3];
    DVec3::new(f64::from(r[0]), f64::from(r[1]), f64::from(r[2]))
}

/// Projected displacement `pi(next_k) - pi(now_k)` of every centre, pixels; `(0, 0)`
/// when either centre is not in front of the camera.
pub fn screen_displacements(
    camera: &Camera,
    now: &Tensor<f32>,
    next: &Tensor<f32>,
) -> Vec<[f64; 2]> {
    (0..now.shape()[0])
        .map(|k| {
            match (
                camera.project(point(now, k)),
                camera.project(point(next, k)),
            ) {
                (Some(a), Some(b)) => [b.0 - a.0, b.1 - a.1],
                _ => [0.0, 0.0],
            }
        })
        .collect()
}

/// Camera-space depth change `z_k(t + 1) - z_k(t)` of every centre (`z` as the
/// renderer's depth: the third coordinate of `R mu + t`).
pub fn depth_changes(camera: &Camera, now: &Tensor<f32>, next: &Tensor<f32>) -> Vec<f64> {
    (0..now.shape()[0])
        .map(|k| camera.to_camera(point(next, k)).z - camera.to_camera(point(now, k)).z)
        .collect()
}

/// Model flow `[H, W, 3]` (see the module doc: displacement in channels 0 and 1,
/// depth-consistency validity in channel 2) of the Gaussians `now` at time `t` and
/// `next` at `t + 1` (each `[means, scales, quats, opacity, sh]` as
/// [`maaf_scene::forward::gaussians_at`] returns them, the same rows in the same order),
/// seen from `camera` with the colour render's `settings` (2D filter, near plane,
/// cutoff).
///
/// # Panics
/// When `now` and `next` do not have the same number of rows.
pub fn model_flow(
    now: &[Tensor<f32>; 5],
    next: &[Tensor<f32>; 5],
    camera: &Camera,
    settings: &RenderSettings,
) -> Tensor<f32> {
    let [means, scales, quats, opacity, _] = now;
    let n = means.shape()[0];
    assert_eq!(
        next[0].shape()[0],
        n,
        "model_flow: the frames at t and t + 1 must hold the same Gaussians"
    );
    let d = screen_displacements(camera, means, &next[0]);
    let dz = depth_changes(camera, means, &next[0]);
    let settings = RenderSettings {
        background: [0.0; 3],
        sh_degree: 0,
        ..settings.clone()
    };
    // Degree-0 SH whose colour `SH_C0 * dc + 0.5` is the given non-negative value.
    let colours = |pick: &dyn Fn(usize) -> [f64; 3]| {
        let data: Vec<f32> = (0..n)
            .flat_map(|k| pick(k).map(|c| ((c - 0.5) / SH_C0) as f32))
            .collect();
        Tensor::from_vec(data, &[n, 1, 3])
    };
    let pos = colours(&|k| [d[k][0].max(0.0), (-d[k][0]).max(0.0), d[k][1].max(0.0)]);
    let neg = colours(&|k| [(-d[k][1]).max(0.0), dz[k].max(0.0), (-dz[k]).max(0.0)]);
    let a = render_tensors(means, scales, quats, opacity, &pos, camera, &settings);
    let b = render_tensors(means, scales, quats, opacity, &neg, camera, &settings);
    let black = Tensor::from_vec(vec![0.0f32; n * 3], &[n, 1, 3]);
    let [nm, ns, nq, no, _] = next;
    let c = render_tensors(nm, ns, nq, no, &black, camera, &settings);
    let (h, w) = (camera.height as usize, camera.width as usize);
    let mut out = vec![0.0f32; h * w * 3];
    for (i, px) in out.chunks_exact_mut(3).enumerate() {
        let alpha = a.alpha.data()[i];
        let (pa, pb) = (&a.image.data()[3 * i..3 * i + 3], &b.image.data()[3 * i..]);
        if alpha < MIN_ALPHA {
            px[2] = f32::from(u8::from(c.alpha.data()[i] < MIN_ALPHA));
            continue;
        }
        px[0] = (pa[0] - pa[1]) / alpha;
        px[1] = (pa[2] - pb[0]) / alpha;
        let predicted =
            (f64::from(a.depth.data()[i]) + f64::from(pb[1]) - f64::from(pb[2])) / f64::from(alpha);
        let qx = ((i % w) as f64 + 0.5 + f64::from(px[0])).floor();
        let qy = ((i / w) as f64 + 0.5 + f64::from(px[1])).floor();
        // Written so that a NaN also fails every test and marks the pixel invalid.
        if !(qx >= 0.0 && qy >= 0.0 && qx < w as f64 && qy < h as f64) {
            continue;
        }
        let q = qy as usize * w + qx as usize;
        let seen_alpha = c.alpha.data()[q];
        if seen_alpha < MIN_ALPHA {
            continue;
        }
        let seen = f64::from(c.depth.data()[q]) / f64::from(seen_alpha);
        px[2] = f32::from(u8::from(
            (seen - predicted).abs() <= DEPTH_TOLERANCE * predicted,
        ));
    }
    Tensor::from_vec(out, &[h, w, 3])
}

#[cfg(test)]
mod tests;
