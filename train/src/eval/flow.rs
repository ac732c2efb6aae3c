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
//! Channel 2 (validity) is 1 everywhere: the model has no occlusion test, and
//! [`crate::metrics::temporal::warp_forward`] already keeps frame `t` where a flow
//! leaves the image.
//!
//! The sum is obtained from the renderer itself (the same tile rasteriser, cutoffs and
//! 2D filter as the colour render): two renders with degree-0 SH colours set to the
//! non-negative parts `(max(dx, 0), max(-dx, 0), max(dy, 0))` and
//! `(max(-dy, 0), 0, 0)` on a black background, so the colour clamp at 0 never acts.

use glam::DVec3;
use maaf_autodiff::Tensor;
use maaf_splat::sh::SH_C0;
use maaf_splat::{Camera, RenderSettings, render_tensors};

/// Accumulated opacity below which a pixel is treated as background (flow 0).
pub const MIN_ALPHA: f32 = 1e-4;

/// Projected displacement `pi(next_k) - pi(now_k)` of every centre, pixels; `(0, 0)`
/// when either centre is not in front of the camera.
pub fn screen_displacements(
    camera: &Camera,
    now: &Tensor<f32>,
    next: &Tensor<f32>,
) -> Vec<[f64; 2]> {
    let point = |m: &Tensor<f32>, k: usize| {
        let r = &m.data()[3 * k..3 * k + 3];
        DVec3::new(f64::from(r[0]), f64::from(r[1]), f64::from(r[2]))
    };
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

/// Model flow `[H, W, 3]` (see the module doc) of the Gaussians `now`
/// (`[means, scales, quats, opacity, sh]` as [`crate::forward::gaussians_at`] returns
/// them, at time `t`) whose centres at `t + 1` are `next_means` `[N, 3]`, seen from
/// `camera` with the colour render's `settings` (2D filter, near plane, cutoff).
pub fn model_flow(
    now: &[Tensor<f32>; 5],
    next_means: &Tensor<f32>,
    camera: &Camera,
    settings: &RenderSettings,
) -> Tensor<f32> {
    let [means, scales, quats, opacity, _] = now;
    let n = means.shape()[0];
    let d = screen_displacements(camera, means, next_means);
    let settings = RenderSettings {
        background: [0.0; 3],
        sh_degree: 0,
        ..settings.clone()
    };
    // Degree-0 SH whose colour `SH_C0 * dc + 0.5` is the given non-negative value.
    let colours = |pick: &dyn Fn(&[f64; 2]) -> [f64; 3]| {
        let data: Vec<f32> = d
            .iter()
            .flat_map(|dk| pick(dk).map(|c| ((c - 0.5) / SH_C0) as f32))
            .collect();
        Tensor::from_vec(data, &[n, 1, 3])
    };
    let pos = colours(&|dk| [dk[0].max(0.0), (-dk[0]).max(0.0), dk[1].max(0.0)]);
    let neg = colours(&|dk| [(-dk[1]).max(0.0), 0.0, 0.0]);
    let a = render_tensors(means, scales, quats, opacity, &pos, camera, &settings);
    let b = render_tensors(means, scales, quats, opacity, &neg, camera, &settings);
    let (h, w) = (camera.height as usize, camera.width as usize);
    let mut out = vec![0.0f32; h * w * 3];
    for (i, px) in out.chunks_exact_mut(3).enumerate() {
        let alpha = a.alpha.data()[i];
        let (pa, pb) = (&a.image.data()[3 * i..3 * i + 3], &b.image.data()[3 * i..]);
        if alpha >= MIN_ALPHA {
            px[0] = (pa[0] - pa[1]) / alpha;
            px[1] = (pa[2] - pb[0]) / alpha;
        }
        px[2] = 1.0;
    }
    Tensor::from_vec(out, &[h, w, 3])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera at the origin looking down +z (OpenCV axes), `size x size` pixels.
    fn camera(size: u32) -> Camera {
        let f = size as f64;
        let eye = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let c = f / 2.0;
        Camera::new(size, size, f, f, c, c, eye).expect("camera")
    }

    /// One flat, wide, nearly opaque Gaussian at depth `z` in the image-plane-parallel
    /// plane (scale 0.6 x 0.6 x 1e-4, opacity 0.99), grey colour.
    fn flat_gaussian(x: f32, y: f32, z: f32) -> [Tensor<f32>; 5] {
        [
            Tensor::from_vec(vec![x, y, z], &[1, 3]),
            Tensor::from_vec(vec![0.6, 0.6, 1e-4], &[1, 3]),
            Tensor::from_vec(vec![1.0, 0.0, 0.0, 0.0], &[1, 4]),
            Tensor::from_vec(vec![0.99], &[1]),
            Tensor::from_vec(vec![0.0; 3], &[1, 1, 3]),
        ]
    }

    /// A plane translating parallel to the image at depth `z` by `(dx, dy)` in world
    /// units moves every point it images by exactly `(f dx / z, f dy / z)` pixels: the
    /// model flow must equal that wherever the Gaussian covers the pixel.
    #[test]
    fn a_translating_plane_gives_its_exact_flow() {
        let cam = camera(48);
        let (z, dx, dy) = (4.0f32, 0.05f32, -0.03f32);
        let now = flat_gaussian(0.1, -0.05, z);
        let next = Tensor::from_vec(vec![0.1 + dx, -0.05 + dy, z], &[1, 3]);
        let settings = RenderSettings::default();
        let flow = model_flow(&now, &next, &cam, &settings);
        let want = [48.0 * dx / z, 48.0 * dy / z];
        let alpha =
            render_tensors(&now[0], &now[1], &now[2], &now[3], &now[4], &cam, &settings).alpha;
        let mut covered = 0;
        for (i, px) in flow.data().chunks_exact(3).enumerate() {
            assert_eq!(px[2], 1.0);
            if alpha.data()[i] > 0.5 {
                covered += 1;
                assert!(
                    (px[0] - want[0]).abs() < 1e-4,
                    "dx {} vs {}",
                    px[0],
                    want[0]
                );
                assert!(
                    (px[1] - want[1]).abs() < 1e-4,
                    "dy {} vs {}",
                    px[1],
                    want[1]
                );
            } else if alpha.data()[i] < MIN_ALPHA {
                assert_eq!((px[0], px[1]), (0.0, 0.0), "background moves");
            }
        }
        assert!(covered > 200, "the Gaussian covers only {covered} pixels");
    }

    /// Two overlapping Gaussians moving in opposite directions: where both cover a
    /// pixel the flow is the weighted mean of their displacements, the front one's
    /// weight `a1` and the back one's `(1 - a1) a2` (written out per pixel here from
    /// the two single-Gaussian alpha maps, independently of the two-render encoding).
    /// Negative control: the unweighted mean of the displacements is far from it.
    #[test]
    fn overlapping_gaussians_composite_with_the_colour_weights() {
        let cam = camera(40);
        let settings = RenderSettings::default();
        let front = flat_gaussian(0.0, 0.0, 3.0);
        let back = flat_gaussian(0.2, 0.1, 5.0);
        let cat = |i: usize| {
            let (a, b) = (front[i].data(), back[i].data());
            let mut shape = front[i].shape().to_vec();
            shape[0] = 2;
            Tensor::from_vec([a, b].concat(), &shape)
        };
        let both: [Tensor<f32>; 5] = [cat(0), cat(1), cat(2), cat(3), cat(4)];
        let next = Tensor::from_vec(vec![0.03, 0.0, 3.0, 0.15, 0.14, 5.0], &[2, 3]);
        let flow = model_flow(&both, &next, &cam, &settings);
        let d = screen_displacements(&cam, &both[0], &next);
        let single = |g: &[Tensor<f32>; 5]| {
            render_tensors(&g[0], &g[1], &g[2], &g[3], &g[4], &cam, &settings).alpha
        };
        let (a1, a2) = (single(&front), single(&back));
        let (mut checked, mut unweighted_off) = (0, 0.0f64);
        for i in 0..40 * 40 {
            let w1 = f64::from(a1.data()[i]);
            let w2 = (1.0 - w1) * f64::from(a2.data()[i]);
            if w1 + w2 < 0.05 {
                continue;
            }
            checked += 1;
            for (c, (d0, d1)) in d[0].iter().zip(&d[1]).enumerate() {
                let want = (w1 * d0 + w2 * d1) / (w1 + w2);
                let got = f64::from(flow.data()[3 * i + c]);
                assert!(
                    (got - want).abs() < 2e-4,
                    "pixel {i} channel {c}: {got} vs {want}"
                );
                if w1 > 0.05 && w2 > 0.05 {
                    // Negative control: ignoring the weights would be caught.
                    let plain = (d0 + d1) / 2.0;
                    unweighted_off = unweighted_off.max((got - plain).abs());
                }
            }
        }
        assert!(checked > 300, "only {checked} pixels checked");
        assert!(
            unweighted_off > 0.05,
            "the scene cannot tell weighted from plain means"
        );
    }
}
