//! Visible weights of single Gaussians, the input of the popping measure
//! ([`crate::metrics::popping`]) that `maaf eval --temporal` adds to each scale.
//!
//! `W_k = sum_p alpha_k(p) T_k(p)` is a sum over pixels *per Gaussian*, the transpose of
//! what the rasteriser composites. Its backward computes exactly that transpose: with
//! degree-0 colours `c_k`, the rendered red channel is `C(p) = sum_k alpha_k(p) T_k(p)
//! c_k + T(p) b`, so seeding every pixel of it with 1 gives `dL/dc_k = W_k`, and the
//! gradient of the SH DC coefficient is `SH_C0 W_k`. The colours are set to 0.5
//! (coefficient 0), inside the colour clamp at 0, so the clamp passes the gradient
//! unchanged. The weights come from the same tile rasteriser, cutoffs and 2D filter as
//! the colour render.

use maaf_autodiff::{Tape, Tensor};
use maaf_splat::sh::SH_C0;
use maaf_splat::{Camera, GaussianVars, RenderSettings, render};

/// Visible weight `W_k` (pixels) of every Gaussian of `frame` (`[means, scales, quats,
/// opacity, sh]` as [`maaf_scene::forward::gaussians_at`] returns them) seen from `camera`
/// with the colour render's `settings`; 0 for a Gaussian that draws no pixel.
pub fn visible_weights(
    frame: &[Tensor<f32>; 5],
    camera: &Camera,
    settings: &RenderSettings,
) -> Vec<f64> {
    let [means, scales, quats, opacity, _] = frame;
    let n = means.shape()[0];
    let tape = Tape::new();
    let dc = tape.var(Tensor::from_vec(vec![0.0f32; n * 3], &[n, 1, 3]));
    let g = GaussianVars {
        means: tape.constant(means.clone()),
        scales: tape.constant(scales.clone()),
        quats: tape.constant(quats.clone()),
        opacity: tape.constant(opacity.clone()),
        sh: dc,
    };
    let settings = RenderSettings {
        sh_degree: 0,
        ..settings.clone()
    };
    let out = render(&tape, &g, camera, &settings);
    let pixels = camera.width as usize * camera.height as usize;
    let red: Vec<f32> = (0..pixels).flat_map(|_| [1.0, 0.0, 0.0]).collect();
    let seed = Tensor::from_vec(red, &out.image.shape());
    let grads = tape
        .backward_from(&[(out.image, seed)])
        .expect("visible_weights: the render of finite Gaussians is finite");
    match grads.wrt(dc) {
        Some(g) => (0..n).map(|k| f64::from(g.data()[3 * k]) / SH_C0).collect(),
        None => vec![0.0; n],
    }
}

#[cfg(test)]
mod tests {
    use maaf_splat::render_tensors;

    use super::*;

    /// Four overlapping Gaussians of different depths, sizes and opacities in front of
    /// a 40x32 camera, plus one behind it.
    fn scene() -> [Tensor<f32>; 5] {
        let means = vec![
            0.0, 0.0, 4.0, 0.3, 0.1, 5.0, -0.4, 0.2, 3.0, 0.1, -0.3, 6.0, 0.0, 0.0, -3.0,
        ];
        let scales = vec![
            0.4, 0.3, 0.3, 0.6, 0.2, 0.4, 0.1, 0.25, 0.1, 0.8, 0.8, 0.5, 0.3, 0.3, 0.3,
        ];
        let quats = vec![
            1.0, 0.0, 0.0, 0.0, 0.9, 0.1, 0.3, 0.0, 0.7, 0.0, 0.0, 0.7, 1.0, 0.2, 0.0, 0.1, 1.0,
            0.0, 0.0, 0.0,
        ];
        [
            Tensor::from_vec(means, &[5, 3]),
            Tensor::from_vec(scales, &[5, 3]),
            Tensor::from_vec(quats, &[5, 4]),
            Tensor::from_vec(vec![0.9, 0.5, 0.3, 0.95, 0.9], &[5]),
            Tensor::from_vec(vec![0.0; 15], &[5, 1, 3]),
        ]
    }

    /// A camera at the origin looking down +z (OpenCV axes), 40x32 pixels.
    fn camera() -> Camera {
        let eye = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        Camera::new(40, 32, 30.0, 30.0, 20.0, 16.0, eye).expect("camera")
    }

    #[test]
    fn weights_equal_the_image_of_each_gaussian_alone_coloured_white() {
        // Independent of the backward: W_k is also the summed forward render in which
        // Gaussian k has colour 1 and every other colour 0 on a black background.
        let frame = scene();
        let settings = RenderSettings {
            background: [0.0; 3],
            ..RenderSettings::default()
        };
        let w = visible_weights(&frame, &camera(), &settings);
        let one = ((1.0 - 0.5) / SH_C0) as f32;
        let zero = (-0.5 / SH_C0) as f32;
        for (k, &weight) in w.iter().enumerate() {
            let dc: Vec<f32> = (0..5)
                .flat_map(|j| [if j == k { one } else { zero }; 3])
                .collect();
            let sh = Tensor::from_vec(dc, &[5, 1, 3]);
            let [m, s, q, o, _] = &frame;
            let image = render_tensors(m, s, q, o, &sh, &camera(), &settings).image;
            let summed: f64 = image.data().iter().step_by(3).map(|&v| f64::from(v)).sum();
            assert!(
                (weight - summed).abs() <= 1e-4 * summed.max(1.0),
                "Gaussian {k}: weight {weight} against its lone image {summed}"
            );
        }
        assert!(w[..4].iter().all(|&x| x > 1.0), "in-view weights {w:?}");
        assert_eq!(w[4], 0.0, "a Gaussian behind the camera draws nothing");
    }

    #[test]
    fn a_gaussian_switched_off_between_frames_pops_and_uncovers_the_one_behind() {
        let settings = RenderSettings::default();
        let now = scene();
        let mut next = scene();
        // The front Gaussian (z = 3) fades to a tenth in one step.
        next[3].data_mut()[2] = 0.03;
        let w: Vec<Vec<f64>> = [&now, &next]
            .iter()
            .map(|f| visible_weights(f, &camera(), &settings))
            .collect();
        let mut m = crate::metrics::popping::PoppingMetrics::default();
        m.push_step(&w[0], &w[1], 40 * 32);
        assert!(
            w[0][2] > 2.0 * w[1][2],
            "its weight {} -> {}",
            w[0][2],
            w[1][2]
        );
        // It pops; the Gaussians behind it gain weight, but by less than half.
        assert_eq!(m.pops, vec![1], "weights {w:?}");
        assert!(m.mass[0] > 0.0);
    }
}
