//! Image metrics pinned against scikit-image 0.26 (fixtures generated once by
//! `fixtures/make_metric_fixtures.py`; no Python at test time).

use maaf_autodiff::Tensor;
use maaf_scene::metrics::{
    ImageMetrics, MetricError, error_map, image_metrics, mean_metrics, psnr, ssim,
};

struct Case {
    name: String,
    gt: Tensor<f64>,
    render: Tensor<f64>,
    psnr: f64,
    ssim: f64,
}

/// Parses `metric_fixtures.txt` (format in the generator's docstring). Each image is
/// `k / d` in f64, exactly what numpy computed.
fn cases() -> Vec<Case> {
    let text = include_str!("fixtures/metric_fixtures.txt");
    let mut out = Vec::new();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    while let Some(line) = lines.next() {
        let name = line.strip_prefix("case ").expect("case line").to_string();
        let mut field = |key: &str| -> Vec<String> {
            let l = lines.next().expect("truncated fixture");
            let mut it = l.split_whitespace();
            assert_eq!(it.next(), Some(key), "{name}: expected `{key}`");
            it.map(str::to_string).collect()
        };
        let shape: Vec<usize> = field("shape")
            .iter()
            .map(|s| s.parse().expect("dim"))
            .collect();
        let mut image = |key: &str| {
            let v = field(key);
            let d: f64 = v[0].parse().expect("denominator");
            let data: Vec<f64> = v[1..]
                .iter()
                .map(|k| k.parse::<f64>().expect("int") / d)
                .collect();
            Tensor::from_vec(data, &shape)
        };
        let gt = image("gt");
        let render = image("render");
        let psnr = field("psnr")[0].parse().expect("psnr");
        let ssim = field("ssim")[0].parse().expect("ssim");
        assert_eq!(field("end").len(), 0);
        out.push(Case {
            name,
            gt,
            render,
            psnr,
            ssim,
        });
    }
    out
}

#[test]
fn psnr_and_ssim_match_scikit_image() {
    let cases = cases();
    assert_eq!(cases.len(), 6);
    for c in &cases {
        let p = psnr(&c.render, &c.gt).expect("psnr");
        let s = ssim(&c.render, &c.gt).expect("ssim");
        // Same formulas in f64 on bit-identical inputs; only the summation order
        // differs (scipy filters axis by axis, numpy sums pairwise), which moves the
        // results by ~1e-14. 1e-9 is far below any convention difference (padding,
        // window size, sample covariance, channel averaging all change SSIM by >1e-3).
        if c.psnr.is_infinite() {
            assert_eq!(p, f64::INFINITY, "{}", c.name);
        } else {
            assert!(
                (p - c.psnr).abs() < 1e-9,
                "{}: psnr {p} vs {}",
                c.name,
                c.psnr
            );
        }
        assert!(
            (s - c.ssim).abs() < 1e-9,
            "{}: ssim {s} vs {}",
            c.name,
            c.ssim
        );
        // Symmetric in its arguments.
        let s2 = ssim(&c.gt, &c.render).expect("ssim");
        assert!((s - s2).abs() < 1e-12, "{}", c.name);
    }
}

#[test]
fn f32_images_give_the_same_metrics_up_to_input_rounding() {
    for c in cases() {
        let (r, g) = (c.render.cast::<f32>(), c.gt.cast::<f32>());
        let m = image_metrics(&r, &g).expect("metrics");
        // Casting the inputs to f32 moves each value by <= 3e-8 relative; the metrics
        // are accumulated in f64, so they move by ~1e-6 at most.
        if c.psnr.is_finite() {
            assert!((m.psnr - c.psnr).abs() < 1e-4, "{}", c.name);
        }
        assert!((m.ssim - c.ssim).abs() < 1e-5, "{}", c.name);
    }
}

#[test]
fn psnr_of_a_uniform_offset_is_closed_form() {
    let gt = Tensor::<f64>::full(&[4, 5, 3], 0.5);
    let render = Tensor::full(&[4, 5, 3], 0.6);
    // MSE = 0.01 -> 20 dB.
    assert!((psnr(&render, &gt).expect("psnr") - 20.0).abs() < 1e-12);
}

#[test]
fn error_map_is_the_channel_mean_of_absolute_differences() {
    let gt = Tensor::<f32>::from_vec(vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0], &[1, 2, 3]);
    let render = Tensor::from_vec(vec![0.3, 0.0, 0.6, 1.0, 0.4, 1.0], &[1, 2, 3]);
    let e = error_map(&render, &gt).expect("map");
    assert_eq!(e.shape(), &[1, 2]);
    assert!((e.data()[0] - 0.3).abs() < 1e-7);
    assert!((e.data()[1] - 0.2).abs() < 1e-7);
}

#[test]
fn mean_is_over_per_image_values() {
    let m = [
        ImageMetrics {
            psnr: 20.0,
            ssim: 0.5,
        },
        ImageMetrics {
            psnr: 30.0,
            ssim: 0.9,
        },
    ];
    let mean = mean_metrics(&m).expect("non-empty");
    assert_eq!(mean.psnr, 25.0);
    assert!((mean.ssim - 0.7).abs() < 1e-15);
    assert!(mean_metrics(&[]).is_none());
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let a = Tensor::<f64>::zeros(&[12, 12, 3]);
    let b = Tensor::<f64>::zeros(&[12, 13, 3]);
    assert!(matches!(
        psnr(&a, &b),
        Err(MetricError::ShapeMismatch { .. })
    ));
    let small = Tensor::<f64>::zeros(&[10, 30, 3]);
    let e = ssim(&small, &small).expect_err("too small");
    assert_eq!(
        e,
        MetricError::TooSmallForSsim {
            height: 10,
            width: 30
        }
    );
    assert!(e.to_string().contains("11x11"));
    let flat = Tensor::<f64>::zeros(&[12, 12]);
    assert!(matches!(
        error_map(&flat, &flat),
        Err(MetricError::NotAnImage { .. })
    ));
}
