//! `maaf export-ply`, `maaf render-ply`, `maaf render` and `maaf eval --temporal` as a
//! user runs them on a tiny trained run of the built-in scene: an exported frame, alone
//! or in a sequence, carries the run's background and 2D filter in its header, so
//! `render-ply` with no options renders the same PNG as the run at that time (and on
//! another background a visibly different one), a sequence goes into a zip (and a
//! non-zip file in its way is refused in one line), eval without LPIPS weights
//! writes null plus the reason and still fills the temporal fields, and eval on
//! another background writes its own file with the model rendered on that background.

use std::path::Path;
use std::process::{Command, Output};

use maaf::train::data::image::decode_rgba;
use maaf::train::data::{BLACK, Dataset, DatasetOptions, Split};

use super::support::{TempDir, s, tiny_scene};

fn maaf(args: &[&str], env: Option<(&str, &str)>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_maaf"));
    cmd.args(args);
    if let Some((k, v)) = env {
        cmd.env(k, v);
    }
    let out = cmd.output().expect("run maaf");
    assert!(
        out.status.success(),
        "maaf {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The decoded values of an 8-bit PNG.
fn png(path: &Path) -> Vec<f32> {
    decode_rgba(path).expect("png").data
}

/// Largest absolute difference of two images' values, and how many values differ.
fn difference(a: &[f32], b: &[f32]) -> (f32, usize) {
    assert_eq!(a.len(), b.len(), "image sizes differ");
    a.iter().zip(b).fold((0.0f32, 0), |(max, n), (x, y)| {
        let d = (x - y).abs();
        (max.max(d), n + usize::from(d > 0.0))
    })
}

#[test]
fn exported_frame_renders_as_the_run_and_eval_survives_missing_weights() {
    let tmp = TempDir::fresh("cli_export");
    let (data, run) = (tmp.0.join("data"), tmp.0.join("run"));
    tiny_scene(&data);
    maaf(
        &[
            "train",
            "--data",
            s(&data),
            "--out",
            s(&run),
            "--filter",
            "motion",
            "--train-scale",
            "0.5",
            "--iters",
            "20",
            "--background",
            "white",
        ],
        None,
    );

    // The same camera for both renderers: test view 0 at the training scale.
    let ds = Dataset::open(&data, DatasetOptions::default()).expect("data");
    let cam = ds.camera(Split::Test, 0, 0.5).expect("camera");
    let cam_path = tmp.0.join("cam.json");
    std::fs::write(&cam_path, cam.to_json_string()).expect("camera json");
    let ply = tmp.0.join("f.ply");
    maaf(
        &[
            "export-ply",
            "--run",
            s(&run),
            "--time",
            "0.4",
            "--out",
            s(&ply),
        ],
        None,
    );
    let header = std::fs::read(&ply).expect("ply");
    let header = String::from_utf8_lossy(&header[..header.len().min(400)]).into_owned();
    assert!(
        header.starts_with(
            "ply\nformat binary_little_endian 1.0\ncomment maaf time 0.4\ncomment maaf background white\ncomment maaf filter2d mip\nelement vertex "
        ),
        "{header}"
    );
    assert!(header.contains("property float x\nproperty float y\nproperty float z\n"));
    let (from_ply, from_run) = (tmp.0.join("ply.png"), tmp.0.join("run.png"));
    // `render-ply` of `ply` from the test camera into `out`, with `extra` options.
    let render_ply = |ply: &Path, out: &Path, extra: &[&str]| {
        let args = ["render-ply", "--ply", s(ply), "--camera", s(&cam_path)];
        maaf(&[&args[..], &["--out", s(out)], extra].concat(), None);
    };
    render_ply(&ply, &from_ply, &[]);
    let at = |t: &str, out: &Path| {
        maaf(
            &[
                "render",
                "--run",
                s(&run),
                "--camera",
                s(&cam_path),
                "--time",
                t,
                "--out",
                s(out),
            ],
            None,
        );
    };
    at("0.4", &from_run);
    // The PLY stores log-scales and opacity logits, so exp(ln s) and sigmoid(logit o)
    // may differ from the run's values by an ulp, which can move an 8-bit pixel by one
    // level: at most 1/255 anywhere, on at most 1 % of the values.
    let (ply_img, run_img) = (png(&from_ply), png(&from_run));
    let (max, moved) = difference(&ply_img, &run_img);
    assert!(
        max <= 1.0 / 255.0 + 1e-6 && moved <= ply_img.len() / 100,
        "render-ply of the export differs from maaf render at t = 0.4: max {max}, {moved} of {} values",
        ply_img.len()
    );
    // Negative controls: the same PLY with the classic 2D dilation, or on black (the
    // default background without the header), is another image.
    for (option, value) in [("--filter2d", "classic"), ("--background", "black")] {
        let other = tmp.0.join(format!("{value}.png"));
        render_ply(&ply, &other, &[option, value]);
        let (max, _) = difference(&png(&other), &run_img);
        assert!(
            max > 4.0 / 255.0,
            "{option} {value} changed nothing: max {max}"
        );
    }

    // A frame of an exported sequence renders as the run at the time its header gives.
    let seq = tmp.0.join("seq");
    maaf(
        &[
            "export-ply",
            "--run",
            s(&run),
            "--frames",
            "3",
            "--out",
            s(&seq),
        ],
        None,
    );
    let frame = seq.join("frame_0001.ply");
    let head = std::fs::read(&frame).expect("frame");
    let head = String::from_utf8_lossy(&head[..head.len().min(400)]).into_owned();
    let time = head
        .lines()
        .find_map(|l| l.strip_prefix("comment maaf time "))
        .expect("the frame's time")
        .to_string();
    assert!(head.contains("comment maaf background white\n"), "{head}");
    let (seq_ply, seq_run) = (tmp.0.join("seq_ply.png"), tmp.0.join("seq_run.png"));
    render_ply(&frame, &seq_ply, &[]);
    at(&time, &seq_run);
    let (seq_ply, seq_run) = (png(&seq_ply), png(&seq_run));
    let (max, moved) = difference(&seq_ply, &seq_run);
    assert!(
        max <= 1.0 / 255.0 + 1e-6 && moved <= seq_ply.len() / 100,
        "render-ply of frame 1 differs from maaf render at t = {time}: max {max}, {moved} values"
    );

    // 20 frames as one zip archive; a non-zip file at the .zip path is refused in one
    // line naming it, and left as it was.
    let zip = tmp.0.join("seq.zip");
    let out = maaf(
        &[
            "export-ply",
            "--run",
            s(&run),
            "--frames",
            "20",
            "--out",
            s(&zip),
        ],
        None,
    );
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        said.contains("wrote 20 frames") && said.contains("MB zip"),
        "{said}"
    );
    let archive = std::fs::read(&zip).expect("zip");
    assert!(archive.starts_with(b"PK\x03\x04"), "not a zip archive");
    eprintln!("{} ({} bytes)", said.trim(), archive.len());
    let notes = tmp.0.join("notes.zip");
    std::fs::write(&notes, b"my notes").expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args(["export-ply", "--run", s(&run), "--frames", "2"])
        .args(["--out", s(&notes)])
        .output()
        .expect("run maaf");
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains(s(&notes)) && err.contains("not a zip archive"),
        "{err}"
    );
    assert_eq!(std::fs::read(&notes).expect("notes"), b"my notes");

    // One view at 1x with `extra` arguments and one environment variable set; the
    // eval.json it wrote.
    let eval_1x = |extra: &[&str], env: (&str, &str)| -> serde_json::Value {
        let mut args = vec!["eval", "--run", s(&run), "--scales", "1"];
        args.extend(["--max-views", "1", "--no-images"]);
        args.extend(extra);
        maaf(&args, Some(env));
        serde_json::from_slice(&std::fs::read(run.join("eval.json")).expect("eval.json"))
            .expect("json")
    };
    // eval --temporal with no LPIPS weights: null and the reason, temporal still filled.
    let missing = "/nonexistent/alex.safetensors";
    let v = eval_1x(&["--temporal"], ("MAAF_LPIPS_WEIGHTS", missing));
    let sc = &v["scales"][0];
    assert!(sc["lpips"].is_null() && sc["w_lpips"].is_null(), "{sc}");
    assert!(
        sc["lpips_note"].as_str().expect("reason").contains(missing),
        "{sc}"
    );
    assert_eq!(sc["flow"], "exact");
    assert!(sc["warp_error"].as_f64().expect("warp error") > 0.0);
    assert_eq!(sc["temporal"][1]["flow"], "model");
    // Popping: one count and one mass per step of the same video.
    let steps = sc["temporal"][0]["times"].as_array().expect("times").len() - 1;
    assert_eq!(sc["popping"]["pops"].as_array().expect("pops").len(), steps);
    assert_eq!(sc["popping"]["mass"].as_array().expect("mass").len(), steps);
    assert!(
        v.get("lpips_net").is_none(),
        "AlexNet keeps the old contract: {v}"
    );
    assert!(
        v.get("trained_background").is_none(),
        "on the run's own background the field is left out: {v}"
    );

    // Another background than the run's (white) writes eval-on-black.json beside the
    // run's eval.json, which stays as it was; the model is rendered on black as the
    // ground truth is composited on it (a white render against a black ground truth
    // would sit far below the same-background scores).
    let own = std::fs::read(run.join("eval.json")).expect("eval.json");
    let mut args = vec!["eval", "--run", s(&run), "--scales", "1"];
    args.extend(["--max-views", "1", "--no-images", "--background", "black"]);
    let said = maaf(&args, Some(("MAAF_LPIPS_WEIGHTS", missing)));
    assert!(
        String::from_utf8_lossy(&said.stdout).contains("eval-on-black.json"),
        "the output names the file"
    );
    assert_eq!(
        std::fs::read(run.join("eval.json")).expect("eval.json"),
        own
    );
    let on_black: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("eval-on-black.json")).expect("written"))
            .expect("json");
    assert_eq!(on_black["background"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(
        on_black["trained_background"],
        serde_json::json!([1.0, 1.0, 1.0]),
        "the file records what the run trained on"
    );
    let psnr = |v: &serde_json::Value| v["scales"][0]["psnr"].as_f64().expect("psnr");
    let on_white: serde_json::Value = serde_json::from_slice(&own).expect("json");
    // Independently: `maaf render` on black against the ground truth the data set
    // composites on black gives the same PSNR (to the PNG's 8-bit rounding); the
    // run's own white render against it does not.
    let gt = Dataset::open(&data, DatasetOptions { background: BLACK })
        .expect("data")
        .view(Split::Test, 0, 0.5)
        .expect("view");
    let psnr_of_render = |background: &str| {
        let out = tmp.0.join(format!("view0_{background}.png"));
        maaf(
            &[
                "render",
                "--run",
                s(&run),
                "--view",
                "test:0",
                "--background",
                background,
                "--out",
                s(&out),
            ],
            None,
        );
        let rgba = png(&out);
        let mse = rgba
            .chunks_exact(4)
            .zip(gt.image.data.chunks_exact(3))
            .flat_map(|(r, g)| (0..3).map(move |c| (r[c] as f64 - g[c] as f64).powi(2)))
            .sum::<f64>()
            / gt.image.data.len() as f64;
        -10.0 * mse.log10()
    };
    let (direct, white) = (psnr_of_render("black"), psnr_of_render("white"));
    eprintln!(
        "PSNR on black: eval {:.3}, direct {direct:.3}; white render {white:.3}; eval.json {:.3}",
        psnr(&on_black),
        psnr(&on_white)
    );
    assert!(
        (psnr(&on_black) - direct).abs() < 0.02,
        "{} vs {direct}",
        psnr(&on_black)
    );
    assert!(
        (psnr(&on_black) - white).abs() > 0.5,
        "the background made no difference"
    );

    // --lpips-net vgg is recorded in eval.json; without its weights, null and the reason.
    let missing = "/nonexistent/vgg.safetensors";
    let v = eval_1x(&["--lpips-net", "vgg"], ("MAAF_LPIPS_VGG_WEIGHTS", missing));
    assert_eq!(v["lpips_net"], "vgg", "{v}");
    let note = v["scales"][0]["lpips_note"].as_str().expect("reason");
    assert!(
        note.contains(missing) && note.contains("MAAF_LPIPS_VGG_WEIGHTS"),
        "{note}"
    );
}
