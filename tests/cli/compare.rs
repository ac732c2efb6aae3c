//! `maaf compare` as a user runs it: values on the LPIPS fixture pairs, JSON output,
//! and one-line errors naming the file.

use std::path::PathBuf;
use std::process::{Command, Output};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("lpips/tests/fixtures")
        .join(name)
}

fn maaf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_maaf"))
        .arg("compare")
        .args(args)
        .output()
        .expect("run maaf")
}

/// `maaf compare --json` of two fixtures with `extra` arguments and, when given, one
/// environment variable set: its JSON object.
fn compare_json(a: &str, b: &str, extra: &[&str], env: Option<(&str, &str)>) -> serde_json::Value {
    let (a, b) = (fixture(a), fixture(b));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_maaf"));
    cmd.args(["compare", "--render", a.to_str().expect("utf8")])
        .args(["--gt", b.to_str().expect("utf8"), "--json"])
        .args(extra);
    if let Some((k, v)) = env {
        cmd.env(k, v);
    }
    let out = cmd.output().expect("run maaf");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

/// The reference LPIPS of a fixture pair in `file` (`lpips_fixtures.txt`: AlexNet,
/// `lpips_vgg_fixtures.txt`: VGG16).
fn reference_lpips(file: &str, a: &str) -> f64 {
    let text = std::fs::read_to_string(fixture(file)).expect("fixtures");
    let line = text
        .lines()
        .find(|l| l.starts_with(a))
        .expect("pair listed");
    line.split_whitespace()
        .nth(2)
        .expect("value")
        .parse()
        .expect("number")
}

/// An 8-bit RGB fixture as the metrics see it.
fn tensor(name: &str) -> maaf::autodiff::Tensor<f32> {
    let img = maaf::train::data::image::decode_rgba(&fixture(name)).expect("decode");
    let rgb: Vec<f32> = img
        .data
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    maaf::autodiff::Tensor::from_vec(rgb, &[img.height as usize, img.width as usize, 3])
}

#[test]
fn json_output_has_the_eval_psnr_ssim_and_the_reference_lpips() {
    let v = compare_json("blur_a.png", "blur_b.png", &[], None);
    let (ta, tb) = (tensor("blur_a.png"), tensor("blur_b.png"));
    let psnr = maaf::scene::metrics::psnr(&ta, &tb).expect("psnr");
    let ssim = maaf::scene::metrics::ssim(&ta, &tb).expect("ssim");
    assert!(
        (v["psnr"].as_f64().expect("psnr") - psnr).abs() < 1e-9,
        "{v}"
    );
    assert!(
        (v["ssim"].as_f64().expect("ssim") - ssim).abs() < 1e-9,
        "{v}"
    );
    let lpips = v["lpips"].as_f64().expect("lpips");
    assert!(
        (lpips - reference_lpips("lpips_fixtures.txt", "blur_a.png")).abs() < 1e-5,
        "{v}"
    );
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(100), Some(100))
    );
    assert!(v["lpips_unavailable"].is_null());
}

#[test]
fn identical_images_and_missing_weights_are_reported_not_failed() {
    let a = fixture("near_a.png");
    let a = a.to_str().expect("utf8");
    let out = maaf(&["--render", a, "--gt", a, "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["identical"], serde_json::json!(true));
    assert!(
        v["psnr"].is_null() && v["lpips"].as_f64() == Some(0.0),
        "{v}"
    );
    let v = compare_json(
        "near_a.png",
        "near_a.png",
        &[],
        Some(("MAAF_LPIPS_WEIGHTS", "/nonexistent/alex.safetensors")),
    );
    assert!(v["lpips"].is_null(), "{v}");
    let why = v["lpips_unavailable"].as_str().expect("reason");
    assert!(why.contains("/nonexistent/alex.safetensors"), "{why}");
    // Text output says the same.
    let near_b = fixture("near_b.png");
    let text = maaf(&["--render", a, "--gt", near_b.to_str().expect("utf8")]);
    let s = String::from_utf8_lossy(&text.stdout);
    assert!(
        s.contains("PSNR") && s.contains("SSIM") && s.contains("LPIPS 0.00"),
        "{s}"
    );
}

#[test]
fn the_vgg_backbone_is_chosen_by_flag_and_its_missing_weights_are_named() {
    let missing = "/nonexistent/vgg.safetensors";
    let v = compare_json(
        "near_a.png",
        "near_b.png",
        &["--lpips-net", "vgg"],
        Some(("MAAF_LPIPS_VGG_WEIGHTS", missing)),
    );
    assert!(v["lpips"].is_null(), "{v}");
    let why = v["lpips_unavailable"].as_str().expect("reason");
    for part in [missing, "MAAF_LPIPS_VGG_WEIGHTS", "fetch_vgg_weights.sh"] {
        assert!(why.contains(part), "{why}");
    }
    // A backbone maaf does not offer is a usage error naming it.
    let (a, b) = (fixture("near_a.png"), fixture("near_b.png"));
    let (a, b) = (a.to_str().expect("utf8"), b.to_str().expect("utf8"));
    let out = maaf(&["--render", a, "--gt", b, "--lpips-net", "squeeze"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("squeeze") && err.contains("alex or vgg"),
        "{err}"
    );
}

#[test]
#[ignore = "needs the fetched VGG weights: bash lpips/tools/fetch_vgg_weights.sh"]
fn vgg_lpips_of_the_cli_is_the_reference_vgg_value() {
    let v = compare_json("blur_a.png", "blur_b.png", &["--lpips-net", "vgg"], None);
    let lpips = v["lpips"].as_f64().expect("lpips");
    let want = reference_lpips("lpips_vgg_fixtures.txt", "blur_a.png");
    assert!(
        (lpips - want).abs() < 1e-5,
        "maaf {lpips}, reference {want}"
    );
    // AlexNet's value on the same pair is another number (0.192 against 0.324).
    assert!((lpips - reference_lpips("lpips_fixtures.txt", "blur_a.png")).abs() > 0.05);
}

#[test]
fn errors_name_the_file() {
    let missing = fixture("no_such_image.png");
    let b = fixture("near_b.png");
    let out = maaf(&[
        "--render",
        missing.to_str().expect("utf8"),
        "--gt",
        b.to_str().expect("utf8"),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no_such_image.png") && err.lines().count() == 1,
        "{err}"
    );
    let other = fixture("far_a.png");
    let out = maaf(&[
        "--render",
        b.to_str().expect("utf8"),
        "--gt",
        other.to_str().expect("utf8"),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("near_b.png") && err.contains("far_a.png") && err.contains("64x64"),
        "{err}"
    );
}
