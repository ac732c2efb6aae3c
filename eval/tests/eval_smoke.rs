//! Evaluation end to end on tiny runs. On a generated scene in the D-NeRF layout
//! (200x200 RGBA images, trained at 100x100): eval.json has exactly the contract fields, renders and error maps are
//! written, bad input fails with one line and overwrites nothing. On a generated scene
//! in the Dynamic 3D Gaussians layout: a frame stride, and PSNR by region from the
//! temporal-median masks.

use std::path::Path;

use maaf_data::dynamic3dgs::MASKS_DIR;
use maaf_data::synthetic::{GenerateOptions, MultiviewOptions, generate, generate_dynamic3dgs};
use maaf_data::{Dataset, DatasetOptions};
use maaf_eval::metrics::rings::RingErrors;
use maaf_eval::{EvalOptions, evaluate_run, scale_label};
use maaf_filter::FilterKind;
use maaf_io::TempDir;
use maaf_scene::TrainConfig;
use maaf_scene::run_data::record_data;
use maaf_train::trainer::train_run;

fn tiny_config() -> TrainConfig {
    let mut c = TrainConfig {
        iterations: 30,
        train_scale: 0.5,
        init_points: 500,
        seed: 5,
        ..TrainConfig::default()
    };
    c.filter.kind = FilterKind::Motion;
    c.filter.refresh.start = 10;
    c.filter.refresh.every = 10;
    c.densify.from = 10;
    c.densify.every = 10;
    c.densify.opacity_reset_every = 0;
    *c.model.warm_up_mut().expect("a built-in model") = 10;
    c
}

/// A copy of `root` (json files only; image folders symlinked) with the first
/// `keep` training frames: a data set that does not match a run trained on `root`.
fn fewer_training_views(root: &Path, keep: usize, out: &Path) {
    std::fs::create_dir_all(out).expect("mkdir");
    for name in ["transforms_test.json", "transforms_val.json"] {
        std::fs::copy(root.join(name), out.join(name)).expect("copy json");
    }
    let text = std::fs::read_to_string(root.join("transforms_train.json")).expect("json");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("parse");
    let frames = v["frames"].as_array_mut().expect("frames");
    frames.truncate(keep);
    std::fs::write(
        out.join("transforms_train.json"),
        serde_json::to_vec(&v).expect("json"),
    )
    .expect("write");
    for dir in ["train", "test", "val"] {
        let link = out.join(dir);
        if !link.exists() {
            std::os::unix::fs::symlink(root.join(dir).canonicalize().expect("abs"), &link)
                .expect("symlink");
        }
    }
}

#[test]
fn eval_writes_the_contract_and_refuses_bad_input() {
    let tmp = TempDir::new("eval-smoke").expect("temp dir");
    let root = tmp.path().join("scene");
    generate(&root, &GenerateOptions::small(200, 40), &mut |_, _| {}).expect("generates");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    let run = tmp.path().join("run");
    let summary = train_run(&data, tiny_config(), &run, false).expect("train");
    record_data(&run, &data).expect("data.json");
    // The summary's CPU time is counted and bounded by the timed phases' wall time
    // times the cores (a double count would break the bound).
    let (cpu, wall) = (summary.timings.cpu, summary.timings.total());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
    assert!(
        cpu > 0.0 && cpu <= wall * cores * 1.1 + 0.05,
        "cpu {cpu} s, wall {wall} s"
    );
    // Every step records statistics after the update, timed apart from Adam.
    assert!(
        summary.timings.statistics > 0.0 && summary.timings.optimiser > 0.0,
        "{:?}",
        summary.timings
    );
    // On Linux the machine's clock covers the same phases and includes the training's
    // own CPU, and no more than every core for the wall time. It counts 10 ms ticks,
    // so over 30 short iterations it is only roughly the process's: at least half.
    if cfg!(target_os = "linux") {
        let machine = summary.timings.machine_cpu;
        assert!(
            machine >= 0.5 * cpu && machine <= wall * cores * 1.1 + 0.5,
            "machine {machine} s, cpu {cpu} s, wall {wall} s"
        );
    }

    let options = EvalOptions {
        scales: vec![0.5, 1.0, 2.0],
        max_views: Some(2),
        ..EvalOptions::default()
    };
    let report = evaluate_run(&run, &data, &options).expect("eval");
    assert_eq!(report.scales.len(), 3);
    assert_eq!(
        [
            report.scales[0].width,
            report.scales[1].width,
            report.scales[2].width
        ],
        [50, 100, 200]
    );

    // eval.json: exactly the contract keys, LPIPS filled, temporal fields null.
    let text = std::fs::read_to_string(run.join("eval.json")).expect("eval.json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("json");
    let mut keys: Vec<&str> = v
        .as_object()
        .expect("object")
        .keys()
        .map(String::as_str)
        .collect();
    keys.sort_unstable();
    let mut want = vec![
        "model",
        "filter",
        "train_scale",
        "iterations",
        "train_seconds",
        "num_gaussians",
        "model_bytes",
        "filter_bytes",
        "background",
        "quantized_8bit",
        "scales",
    ];
    want.sort_unstable();
    assert_eq!(keys, want);
    assert_eq!(v["filter"], "motion");
    assert_eq!(v["quantized_8bit"], false);
    assert_eq!(v["iterations"], 30);
    assert!(v["filter_bytes"].as_u64().expect("bytes") > 0);
    assert!(v["model_bytes"].as_u64().expect("bytes") > 0);
    for s in v["scales"].as_array().expect("scales") {
        let mut k: Vec<&str> = s
            .as_object()
            .expect("object")
            .keys()
            .map(String::as_str)
            .collect();
        k.sort_unstable();
        assert_eq!(
            k,
            [
                "flow",
                "height",
                "lpips",
                "lpips_note",
                "popping",
                "psnr",
                "regions",
                "rings",
                "scale",
                "ssim",
                "temporal",
                "w_lpips",
                "w_ssim",
                "warp_error",
                "width"
            ]
        );
        assert!(s["popping"].is_null(), "no --temporal, no popping: {s}");
        // The committed LPIPS weights load; no --temporal, so no temporal metrics.
        let lpips = s["lpips"].as_f64().expect("lpips");
        assert!(
            lpips > 0.0 && lpips < 1.5 && s["lpips_note"].is_null(),
            "{s}"
        );
        assert!(s["warp_error"].is_null() && s["flow"].is_null());
        assert_eq!(s["temporal"], serde_json::json!([]));
        // A D-NeRF layout has no moving masks: no PSNR by region.
        assert!(s["regions"].is_null(), "{s}");
        // It has alpha: squared error by ring over every pixel of the two views, whose
        // pooled MSE is the mean of the per-view MSEs that metrics.csv's PSNRs give.
        let rings: RingErrors = serde_json::from_value(s["rings"].clone()).expect("rings");
        let (w, h) = (
            s["width"].as_u64().expect("w"),
            s["height"].as_u64().expect("h"),
        );
        assert_eq!(rings.pixels.iter().sum::<u64>(), 2 * w * h, "{s}");
        assert!(rings.pixels[0] > 0 && rings.pixels[4] > 0, "{s}");
        let label = scale_label(s["scale"].as_f64().expect("scale"));
        let csv = std::fs::read_to_string(run.join("eval").join(&label).join("metrics.csv"))
            .expect("metrics.csv");
        let mses: Vec<f64> = csv
            .lines()
            .skip(1)
            .map(|l| {
                let psnr: f64 = l.split(',').nth(2).expect("psnr").parse().expect("number");
                10f64.powf(-psnr / 10.0)
            })
            .collect();
        let pooled = rings.sse.iter().sum::<f64>() / (3 * 2 * w * h) as f64;
        let per_view = mses.iter().sum::<f64>() / mses.len() as f64;
        assert!(
            (pooled / per_view - 1.0).abs() < 1e-5,
            "{label}: rings {pooled}, metrics.csv {per_view}"
        );
        let psnr = s["psnr"].as_f64().expect("psnr");
        let ssim = s["ssim"].as_f64().expect("ssim");
        assert!(psnr > 5.0 && psnr < 60.0, "psnr {psnr}");
        assert!(ssim > 0.0 && ssim <= 1.0, "ssim {ssim}");
    }
    for label in ["0.5x", "1x", "2x"] {
        let dir = run.join("eval").join(label);
        for f in ["render_000.png", "error_000.png", "metrics.csv"] {
            let len = std::fs::metadata(dir.join(f)).expect(f).len();
            assert!(len > 0, "{label}/{f}");
        }
    }
    assert!(run.join("eval/filter_analysis.json").exists());

    // Bad input: one line, nothing overwritten.
    let before = std::fs::read(run.join("eval.json")).expect("eval.json");
    let one_line = |e: &dyn std::fmt::Display| {
        let m = e.to_string();
        assert!(!m.contains('\n'), "multi-line error: {m}");
        m
    };
    // Zoom-in beyond the 200x200 source: 0.5 * 16 = 8.
    let e = evaluate_run(
        &run,
        &data,
        &EvalOptions {
            scales: vec![16.0],
            ..EvalOptions::default()
        },
    )
    .expect_err("16x");
    let m = one_line(&e);
    assert!(
        m.contains("none of the scales") && m.contains("1600x1600") && m.contains("200x200"),
        "{m}"
    );
    // Not an integer factor of the source: 0.5 * 0.6 = 1 / 3.33.
    let e = evaluate_run(
        &run,
        &data,
        &EvalOptions {
            scales: vec![0.6],
            ..EvalOptions::default()
        },
    )
    .expect_err("0.6x");
    one_line(&e);
    let e = evaluate_run(
        &run,
        &data,
        &EvalOptions {
            scales: vec![-1.0],
            ..EvalOptions::default()
        },
    )
    .expect_err("negative");
    one_line(&e);
    // A run without a model.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    let e = evaluate_run(&empty, &data, &options).expect_err("no model");
    assert!(one_line(&e).contains("no trained model"));
    // A data set that does not match the run (fewer training views).
    let other_root = tmp.path().join("fewer");
    fewer_training_views(&root, 20, &other_root);
    let other = Dataset::open(&other_root, DatasetOptions::default()).expect("subset");
    let e = evaluate_run(&run, &other, &options).expect_err("mismatch");
    assert!(one_line(&e).contains("is not the data set"), "{e}");
    assert_eq!(
        std::fs::read(run.join("eval.json")).expect("eval.json"),
        before
    );
    assert!(run.join("eval/1x/render_000.png").exists());
}

#[test]
fn a_tiny_run_trains_from_the_hull_and_evaluates_a_frame_stride_by_region() {
    let tmp = TempDir::new("eval-d3dgs").expect("temp dir");
    let root = tmp.path().join("scene");
    let opts = MultiviewOptions {
        scene: "approach".into(),
        width: 96,
        height: 64,
        cameras: 6,
        frames: 6,
        samples: 2,
        seed: 3,
        force: false,
    };
    generate_dynamic3dgs(&root, &opts, &mut |_, _| {}).expect("generates");
    // Without the test camera's masks the regions come from the temporal median.
    std::fs::remove_dir_all(root.join(MASKS_DIR).join("0")).expect("removes");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    let mut config = TrainConfig {
        iterations: 20,
        train_scale: 0.5,
        init_points: 400,
        val_every: 0,
        ..TrainConfig::default()
    };
    config.filter.kind = FilterKind::Motion;
    config.filter.refresh.start = 5;
    config.filter.refresh.every = 5;
    config.densify.opacity_reset_every = 0;
    let run = tmp.path().join("run");
    train_run(&data, config, &run, false).expect("trains");
    let options = EvalOptions {
        scales: vec![0.5, 1.0, 2.0],
        frame_stride: 2,
        save_images: false,
        ..EvalOptions::default()
    };
    let report = evaluate_run(&run, &data, &options).expect("evaluates");
    assert_eq!(report.frame_stride, 2);
    assert_eq!(report.scales.len(), 3);
    assert_eq!((report.scales[2].width, report.scales[2].height), (96, 64));
    for s in &report.scales {
        assert!(s.psnr.is_finite(), "{s:?}");
        assert!(
            s.regions.is_some(),
            "regions by the median masks at {}",
            s.scale
        );
    }
    // Frames 0, 2 and 4 of the one test camera: views 0, 2, 4.
    let csv = std::fs::read_to_string(run.join("eval/1x/metrics.csv")).expect("csv");
    let views: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap_or(""))
        .collect();
    assert_eq!(views, ["0", "2", "4"]);
    let bad = EvalOptions {
        frame_stride: 0,
        ..EvalOptions::default()
    };
    let err = evaluate_run(&run, &data, &bad)
        .expect_err("stride 0")
        .to_string();
    assert!(err.contains("--frame-stride"), "{err}");
}
