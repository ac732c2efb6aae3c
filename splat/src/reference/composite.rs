//! The reference compositor: every pixel visits every projected Gaussian in global
//! `(depth, index)` order, no tiles.

use maaf_autodiff::{Float, Tensor};

use super::stages::{RefSplat, covariance, project, sh_colour};
use crate::Camera;
use crate::compositing::{ALPHA_MAX, ALPHA_MIN, AlphaCutoff, SMOOTH_TAPER_WIDTH, T_MIN};
use crate::render::RenderSettings;

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
                // No support radius: the alpha threshold alone decides (Inria).
                if power < T::zero() {
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
                        // Taper on the raw alpha's log headroom over 1/255.
                        let raw = s.opacity * (-power).exp();
                        if raw <= T::of(ALPHA_MIN) {
                            continue;
                        }
                        let headroom = (raw / T::of(ALPHA_MIN)).ln();
                        let u = (T::one() - headroom / T::of(SMOOTH_TAPER_WIDTH)).max(T::zero());
                        let win = (T::one() - u * u).max(T::zero());
                        raw * win * win
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
