//! Invariants: determinism across thread counts, the f32 (4-pixel lanes) gradients
//! agree with the f64 (one-lane, finite-difference-checked) ones, out-of-view
//! Gaussians change nothing, non-finite inputs are reported with the op name and
//! never rendered.
#![allow(clippy::unwrap_used)]

mod common;

use maaf_autodiff::{Tape, TapeError, Tensor};
use maaf_splat::{AlphaCutoff, Filter2d, GaussianVars, RenderSettings, SplatFloat, render};

/// Renders `scene` and backpropagates a fixed weighted loss; returns the image and
/// every parameter gradient.
fn forward_backward<T: SplatFloat>(
    scene: &common::Scene<T>,
    w: u32,
    h: u32,
    alpha_cutoff: AlphaCutoff,
) -> Vec<Tensor<T>> {
    let cam = common::camera(w, h);
    let t = Tape::<T>::new();
    let g = GaussianVars {
        means: t.param("means", scene.means.clone()),
        scales: t.param("scales", scene.scales.clone()),
        quats: t.param("quats", scene.quats.clone()),
        opacity: t.param("opacity", scene.opacity.clone()),
        sh: t.param("sh", scene.sh.clone()),
    };
    let s = RenderSettings {
        background: [1.0, 1.0, 1.0],
        alpha_cutoff,
        ..RenderSettings::default()
    };
    let out = render(&t, &g, &cam, &s);
    let weights = Tensor::from_vec(
        (0..(w * h * 3) as usize)
            .map(|i| T::of(((i * 7919) % 13) as f64 / 13.0 - 0.4))
            .collect(),
        &[h as usize, w as usize, 3],
    );
    let wv = t.constant(weights);
    let loss = (out.image * wv).sum() + out.alpha.mean() + out.depth.mean();
    let image = out.image.value().clone();
    let m2 = out.means2d;
    let grads = t.backward(loss).unwrap();
    let mut v = vec![image, grads.wrt(m2).unwrap().clone()];
    for name in ["means", "scales", "quats", "opacity", "sh"] {
        v.push(grads.param(name).unwrap().clone());
    }
    v
}

#[test]
fn bit_identical_across_thread_counts() {
    let scene = common::random_scene::<f32>(400, 3, 42).extend(&common::hard_cases(3));
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| forward_backward(&scene, 97, 75, AlphaCutoff::Hard))
    };
    let one = run(1);
    let two = run(2);
    let three = run(3);
    for (k, ((a, b), c)) in one.iter().zip(&two).zip(&three).enumerate() {
        let bits = |t: &Tensor<f32>| t.data().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(a),
            bits(b),
            "output {k} differs between 1 and 2 threads"
        );
        assert_eq!(
            bits(a),
            bits(c),
            "output {k} differs between 1 and 3 threads"
        );
    }
}

/// The f32 path composites 4 pixels per step (`wide::f32x4`), the f64 path one
/// (the path the gradchecks cover). On the same scene, both cutoffs, an image with
/// partial edge tiles, the image and every gradient agree to f32 accuracy: each
/// output within `1e-4 max|f64|` (the f32 sums carry ~1e-6 relative rounding; a lane
/// that drops or doubles a term is off by O(1)).
#[test]
fn f32_lanes_match_f64_one_lane() {
    let scene = common::random_scene::<f64>(300, 3, 17);
    for cut in [AlphaCutoff::Smooth, AlphaCutoff::Hard] {
        let wide = forward_backward(&scene.cast::<f32>(), 53, 41, cut);
        let one = forward_backward(&scene, 53, 41, cut);
        for (k, (a, b)) in wide.iter().zip(&one).enumerate() {
            let scale = b.data().iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale > 0.0, "output {k} is all zero");
            let worst = a
                .data()
                .iter()
                .zip(b.data())
                .map(|(x, y)| (f64::from(*x) - y).abs())
                .fold(0.0, f64::max);
            assert!(
                worst <= 1e-4 * scale,
                "{cut:?} output {k}: max |f32 - f64| = {worst:e}, max |f64| = {scale:e}"
            );
        }
    }
}

#[test]
fn out_of_view_gaussians_change_nothing() {
    let base = common::random_scene::<f32>(50, 2, 8);
    // Behind the camera, beyond the image borders, and tiny far away off-axis.
    let mut out = common::random_scene::<f32>(6, 2, 9);
    let places = [
        [0.0, 0.0, -9.0],
        [0.5, 0.2, -20.0],
        [30.0, 0.0, 1.0],
        [-30.0, 5.0, 0.0],
        [0.0, 25.0, 0.5],
        [0.0, -25.0, 0.5],
    ];
    for (i, p) in places.iter().enumerate() {
        out.means.data_mut()[3 * i..3 * i + 3].copy_from_slice(p);
    }
    let a = forward_backward(&base, 64, 48, AlphaCutoff::Hard);
    let b = forward_backward(&base.extend(&out), 64, 48, AlphaCutoff::Hard);
    assert_eq!(a[0], b[0], "image changed");
    let n = base.n();
    // Gradients of the in-view Gaussians are identical; the others get zero.
    for (k, (ga, gb)) in a.iter().zip(&b).enumerate().skip(1) {
        let w = ga.len() / n;
        assert_eq!(ga.data(), &gb.data()[..n * w], "gradient {k} changed");
        assert!(gb.data()[n * w..].iter().all(|&v| v == 0.0), "gradient {k}");
    }
}

#[test]
fn nan_input_is_reported_with_the_op_name() {
    let scene = common::random_scene::<f32>(10, 1, 3);
    let cam = common::camera(32, 32);
    for (param, expected_op) in [
        ("means", "project_ewa"),
        ("quats", "quat_scale_to_cov"),
        ("sh", "sh_color"),
    ] {
        let t = Tape::<f32>::new();
        let mut s = scene.clone();
        match param {
            "means" => s.means.data_mut()[4] = f32::NAN,
            "quats" => s.quats.data_mut()[0] = f32::NAN,
            _ => s.sh.data_mut()[2] = f32::NAN,
        }
        let g = GaussianVars {
            means: t.param("means", s.means.clone()),
            scales: t.param("scales", s.scales.clone()),
            quats: t.param("quats", s.quats.clone()),
            opacity: t.param("opacity", s.opacity.clone()),
            sh: t.param("sh", s.sh.clone()),
        };
        t.set_validate(true);
        let out = render(&t, &g, &cam, &RenderSettings::default());
        match t.check_finite() {
            Err(TapeError::Forward { op, .. }) => assert_eq!(op, expected_op, "{param}"),
            other => panic!("{param}: expected a forward error, got {other:?}"),
        }
        assert!(t.backward(out.image.sum()).is_err());
        // Without validate mode the image is NaN, never a silently wrong picture.
        let t2 = Tape::<f32>::new();
        let g2 = GaussianVars {
            means: t2.constant(s.means.clone()),
            scales: t2.constant(s.scales.clone()),
            quats: t2.constant(s.quats.clone()),
            opacity: t2.constant(s.opacity.clone()),
            sh: t2.constant(s.sh.clone()),
        };
        let out2 = render(&t2, &g2, &cam, &RenderSettings::default());
        assert!(
            out2.image.value().data().iter().all(|v| v.is_nan()),
            "{param}"
        );
    }
}

#[test]
fn three_d_filter_with_zero_variance_renders_the_same() {
    let scene = common::random_scene::<f32>(20, 1, 4);
    let cam = common::camera(32, 24);
    let t = Tape::<f32>::new();
    let scales = t.constant(scene.scales.clone());
    let opac = t.constant(scene.opacity.clone());
    let (s2, o2) = maaf_splat::apply_3d_filter(scales, opac, &Tensor::zeros(&[20]));
    let mk = |s, o| GaussianVars {
        means: t.constant(scene.means.clone()),
        scales: s,
        quats: t.constant(scene.quats.clone()),
        opacity: o,
        sh: t.constant(scene.sh.clone()),
    };
    let st = RenderSettings {
        filter2d: Filter2d::Classic,
        alpha_cutoff: AlphaCutoff::Hard,
        ..RenderSettings::default()
    };
    let a = render(&t, &mk(scales, opac), &cam, &st)
        .image
        .value()
        .clone();
    let b = render(&t, &mk(s2, o2), &cam, &st).image.value().clone();
    // sqrt(s^2 + 0) may round differently from s in the last bit.
    let c = maaf_autodiff::check::compare(&a, &b, 1e-6, 0.0);
    assert!(c.passed(), "max err {}", c.max_abs_err);
}
