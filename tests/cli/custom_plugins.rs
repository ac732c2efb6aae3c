//! A filter, a densification strategy and a representation of one's own, each in a
//! program of a few lines around `maaf::cli::Maaf` (`examples/custom_filter.rs`,
//! `custom_strategy.rs`, `custom_representation.rs`), named in a plain training
//! config: each program trains, is killed mid-run, `maaf` itself refuses to resume
//! the run (one line naming the run, the name and what it knows), the program
//! resumes it to the uninterrupted run's tensors, and the run is evaluated. An image
//! metric of one's own (`examples/custom_metric.rs`) evaluates a run, and its values
//! are recomputed from the saved PNGs; a data layout of one's own
//! (`examples/custom_data_format.rs`) holds a generated scene that is trained and
//! evaluated through `--data`.

use std::path::{Path, PathBuf};

use serde_json::Value;

use super::custom_terms::{example, run};
use super::support::{Fixture, fixture, maaf, refused, s, succeeded};

/// The settings every case shares: ten iterations, a checkpoint every second one.
const BASE: &str = r#""iterations": 10, "init_points": 200, "train_scale": 0.5, "seed": 3,
    "checkpoint_every": 2, "log_every": 1, "val_every": 0"#;

/// A JSON file of the run's folder.
fn json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).expect("json")
}

/// `PROGRAM train --data DATA --out ROOT/NAME --config CONFIG`.
fn train(program: &Path, fx: &Fixture, name: &str, config: &Path, env: &[(&str, &str)]) -> PathBuf {
    let out = fx.root.join(name);
    let args = [
        "train",
        "--data",
        s(&fx.data),
        "--out",
        s(&out),
        "--config",
        s(config),
    ];
    let done = run(program, &args, env);
    if env.is_empty() {
        succeeded(done);
    } else {
        assert!(
            !done.status.success(),
            "the fault injection did not stop the run"
        );
    }
    out
}

/// Writes the config `{BASE, settings}` as `ROOT/NAME.json`, has `program` train it
/// into `ROOT/NAME` and checks that it is refused with one line holding `needles`
/// before the run's log is written.
fn refused_config(program: &Path, fx: &Fixture, name: &str, settings: &str, needles: &[&str]) {
    let config = fx.root.join(format!("{name}.json"));
    std::fs::write(&config, format!("{{{BASE}, {settings}}}")).expect("config");
    let out = fx.root.join(name);
    let args = [
        "train",
        "--data",
        s(&fx.data),
        "--out",
        s(&out),
        "--config",
        s(&config),
    ];
    refused(run(program, &args, &[]), needles);
    assert!(!out.join("log.csv").exists());
}

/// Trains the program's run uninterrupted and killed (an abort at a write step, as a
/// kill -9), checks that plain `maaf` refuses to resume the killed run with one line
/// holding `needles` and leaves it unchanged, resumes it with the program to the
/// uninterrupted run's tensors, and evaluates it with the program. Returns the
/// uninterrupted and the resumed runs.
fn killed_and_resumed(
    program: &str,
    fx: &Fixture,
    settings: &str,
    needles: &[&str],
) -> (PathBuf, PathBuf) {
    let program = example(program);
    let config = fx.root.join("config.json");
    std::fs::write(&config, format!("{{{BASE}, {settings}}}")).expect("config");
    let reference = train(&program, fx, "reference", &config, &[]);
    let killed = train(
        &program,
        fx,
        "killed",
        &config,
        &[("MAAF_FAULT_ABORT_AT_WRITE", "36")],
    );
    assert!(
        killed.join("checkpoints").is_dir(),
        "killed before any checkpoint"
    );
    assert!(!killed.join("model").exists(), "killed after the end");

    let log_before = std::fs::read(killed.join("log.csv")).expect("log");
    let line = refused(maaf(&["train", "--resume", s(&killed)]), needles);
    assert!(line.contains(s(&killed.join("config.json"))), "{line}");
    assert_eq!(
        std::fs::read(killed.join("log.csv")).expect("log"),
        log_before
    );

    succeeded(run(&program, &["train", "--resume", s(&killed)], &[]));
    let tensors = |r: &Path| std::fs::read(r.join("model/tensors.safetensors")).expect("model");
    assert!(
        tensors(&killed) == tensors(&reference),
        "the resumed run's tensors differ from the uninterrupted run's"
    );
    succeeded(run(
        &program,
        &["eval", "--run", s(&killed), "--scales", "1", "--no-images"],
        &[],
    ));
    let psnr = json(&killed.join("eval.json"))["scales"][0]["psnr"].as_f64();
    assert!(psnr.is_some_and(f64::is_finite), "{psnr:?}");
    (reference, killed)
}

#[test]
fn a_filter_of_ones_own_is_named_by_config_resumes_bit_identical_and_is_labelled_by_name() {
    let fx = fixture("plugin_filter");
    let settings = r#""filter": {"kind": "median", "refresh": {"start": 2, "every": 2},
            "options": {"quantile": 0.25}},
        "densify": {"from": 2, "until": 9, "every": 2, "grad_threshold": 1e-6}"#;
    let needles = ["filter `median`", "not registered", "mip3d", "Maaf::filter"];
    let (reference, killed) = killed_and_resumed("custom_filter", &fx, settings, &needles);
    let filter = &json(&reference.join("config.json"))["filter"];
    assert_eq!(filter["kind"], "median");
    assert_eq!(filter["options"]["quantile"], 0.25, "{filter}");
    // The filter checks its own options, naming the one at fault.
    refused_config(
        &example("custom_filter"),
        &fx,
        "bad_quantile",
        r#""filter": {"kind": "median", "options": {"quantile": 2}}"#,
        &[
            "`options`",
            "filter `median`",
            "`quantile`",
            "[0, 1], got 2",
        ],
    );
    assert_eq!(
        json(&killed.join("model/state.json"))["config"]["filter"]["kind"],
        "median"
    );
    assert_eq!(json(&killed.join("eval.json"))["filter"], "median");
    // Reading the run needs the filter's state, not its code: plain `maaf` evaluates
    // it, with the same label.
    succeeded(maaf(&[
        "eval",
        "--run",
        s(&reference),
        "--scales",
        "1",
        "--no-images",
    ]));
    assert_eq!(json(&reference.join("eval.json"))["filter"], "median");
    // `--filter` takes the name too, and plain `maaf` refuses it before any work.
    let other = fx.root.join("by_flag");
    refused(
        maaf(&[
            "train",
            "--data",
            s(&fx.data),
            "--out",
            s(&other),
            "--iters",
            "4",
            "--filter",
            "median",
        ]),
        &["filter `median`", "not registered"],
    );
    assert!(!other.join("log.csv").exists());
}

#[test]
fn a_strategy_of_ones_own_is_named_by_config_and_its_state_resumes_with_it() {
    let fx = fixture("plugin_strategy");
    let settings = r#""filter": {"kind": "mip3d"},
        "densify": {"strategy": "budgeted_growth", "every": 2,
            "options": {"budget": 15, "lifetime": 40}}"#;
    let needles = [
        "strategy (densify.strategy) `budgeted_growth`",
        "not registered",
        "default, sensitivity",
    ];
    let (reference, killed) = killed_and_resumed("custom_strategy", &fx, settings, &needles);
    // Refinements at 2, 4, 6 and 8 clone 15, 15, 10 and 0 (its options: a budget of
    // 15, a lifetime of 40): the count is the strategy's own state, saved with every
    // checkpoint.
    for run in [&reference, &killed] {
        let state = json(&run.join("model/state.json"));
        assert_eq!(state["strategy"]["cloned"], 40, "{}", state["strategy"]);
    }
    let at4 = json(&reference.join("checkpoints/iter_000004/state.json"));
    assert_eq!(at4["strategy"]["cloned"], 30, "{}", at4["strategy"]);
    // Its options are its own to check, naming the one at fault.
    refused_config(
        &example("custom_strategy"),
        &fx,
        "bad_budget",
        r#""densify": {"strategy": "budgeted_growth", "every": 2, "options": {"budget": -1}}"#,
        &["densify.options.budget", "expected a count, got -1"],
    );
    // Its maker refuses a config it cannot run, naming the field.
    refused_config(
        &example("custom_strategy"),
        &fx,
        "no_interval",
        r#""densify": {"strategy": "budgeted_growth", "every": 0}"#,
        &["densify.every = 0"],
    );
    // The built-ins by name, in plain `maaf`.
    succeeded(fx.train("named_default", r#""densify": {"strategy": "default"}"#));
}

#[test]
fn a_representation_of_ones_own_trains_from_a_config_with_its_options_and_resumes() {
    let fx = fixture("plugin_model");
    let settings = r#""filter": {"kind": "motion"},
        "model": {"kind": "tiny_deform", "width": 16, "warm_up": 4},
        "densify": {"from": 2, "until": 9, "every": 2, "grad_threshold": 1e-6}"#;
    let needles = [
        "representation (model.kind) `tiny_deform`",
        "not registered",
        "saro, deform, track",
    ];
    let (reference, killed) = killed_and_resumed("custom_representation", &fx, settings, &needles);
    let model = &json(&reference.join("config.json"))["model"];
    assert_eq!(
        (&model["kind"], &model["width"]),
        (&Value::from("tiny_deform"), &Value::from(16))
    );
    // The program loads its runs in every command; plain `maaf` names what it lacks.
    let program = example("custom_representation");
    let ply = fx.root.join("frame.ply");
    succeeded(run(
        &program,
        &[
            "export-ply",
            "--run",
            s(&killed),
            "--time",
            "0.5",
            "--out",
            s(&ply),
        ],
        &[],
    ));
    assert!(std::fs::metadata(&ply).expect("ply").len() > 0);
    refused(
        maaf(&["eval", "--run", s(&killed), "--scales", "1"]),
        &["`tiny_deform`", "not registered"],
    );
    // `bench` continues stepping the run, so it needs the program too.
    let bench = [
        "bench",
        "--run",
        s(&killed),
        "--gaussians",
        "50",
        "--iters",
        "1",
        "--warmup",
        "0",
    ];
    succeeded(run(&program, &bench, &[]));
    refused(maaf(&bench), &["`tiny_deform`", "not registered"]);
    // Its factory checks its options, naming the field.
    for (options, needle) in [
        (r#""width": "wide""#, "model.width"),
        (r#""depth": 3"#, "model.depth"),
    ] {
        let settings = format!(r#""model": {{"kind": "tiny_deform", {options}}}"#);
        refused_config(&program, &fx, "bad", &settings, &[needle]);
    }
}

/// The mean absolute error of two saved 8-bit PNGs over pixels and RGB channels,
/// computed here without the example's code.
fn png_mae(render: &Path, gt: &Path) -> f64 {
    let read = |p: &Path| {
        maaf::train::data::image::decode_rgba(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    };
    let (r, g) = (read(render), read(gt));
    assert_eq!((r.width, r.height), (g.width, g.height));
    let sum: f64 = r
        .data
        .chunks_exact(4)
        .zip(g.data.chunks_exact(4))
        .flat_map(|(a, b)| (0..3).map(move |c| f64::from((a[c] - b[c]).abs())))
        .sum();
    sum / (3 * r.pixels()) as f64
}

#[test]
fn a_metric_of_ones_own_is_in_eval_json_metrics_csv_and_the_report() {
    let fx = fixture("plugin_metric");
    let trained = fx.trained("run");
    let program = example("custom_metric");
    let eval = ["eval", "--run", s(&trained), "--scales", "0.5,1"];
    succeeded(run(&program, &eval, &[]));
    let report = json(&trained.join("eval.json"));
    assert_eq!(
        report["extra_metrics"],
        serde_json::json!({"mae": {"higher_is_better": false}})
    );
    // The saved PNGs are the float images rounded to 8 bits (after clamping to
    // [0, 1], as the metric clamps), each value within 0.5 / 255 of the one measured:
    // a per-view value, and so the mean, recomputed from them is within 1 / 255.
    let tolerance = 1.0 / 255.0 + 1e-6;
    let scales = report["scales"].as_array().expect("scales");
    assert_eq!(scales.len(), 2);
    for (entry, label) in scales.iter().zip(["0.5x", "1x"]) {
        let mean = entry["extra"]["mae"].as_f64().expect("extra.mae");
        let dir = trained.join("eval").join(label);
        let text = std::fs::read_to_string(dir.join("metrics.csv")).expect("metrics.csv");
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().expect("header").split(',').collect();
        assert_eq!(header, ["view", "time", "psnr", "ssim", "lpips", "mae"]);
        let mut csv_values = Vec::new();
        let mut png_values = Vec::new();
        for line in lines {
            let cells: Vec<&str> = line.split(',').collect();
            let view: usize = cells[0].parse().expect("view index");
            let value: f64 = cells[5].parse().expect("mae value");
            let png = png_mae(
                &dir.join(format!("render_{view:03}.png")),
                &dir.join(format!("gt_{view:03}.png")),
            );
            assert!(
                (value - png).abs() <= tolerance,
                "{label} view {view}: mae {value} in metrics.csv, {png} from the PNGs"
            );
            csv_values.push(value);
            png_values.push(png);
        }
        assert!(!csv_values.is_empty(), "{label}: no view evaluated");
        let average = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        // metrics.csv prints 6 decimals.
        assert!((average(&csv_values) - mean).abs() < 1e-6, "{label}");
        assert!(
            (average(&png_values) - mean).abs() <= tolerance,
            "{label}: mean mae {mean} in eval.json, {} from the PNGs",
            average(&png_values)
        );
        assert!(
            mean > 0.0,
            "{label}: a run of 6 iterations renders its views exactly"
        );
    }
    // Plain `maaf report` reads the values from eval.json alone.
    let out = maaf(&[
        "report",
        "--runs",
        s(&trained),
        "--out",
        s(&fx.root.join("report")),
    ]);
    succeeded(out.clone());
    let printed = String::from_utf8_lossy(&out.stdout);
    let at_1x = format!("{:.4}", scales[1]["extra"]["mae"].as_f64().expect("mae"));
    assert!(
        printed.contains("| Method | mae ↓ 1/2x | mae ↓ 1x |"),
        "{printed}"
    );
    assert!(printed.contains(&at_1x), "{printed}");
    let markdown = std::fs::read_to_string(fx.root.join("report/report.md")).expect("report");
    assert!(markdown.contains("mae ↓ 1x"), "{markdown}");
    // A name no program registers is refused before anything is evaluated.
    refused(
        run(
            &program,
            &["eval", "--run", s(&trained), "--metrics", "maee"],
            &[],
        ),
        &["--metrics", "metric `maee`", "did you mean `mae`?"],
    );
    refused(
        maaf(&["eval", "--run", s(&trained), "--metrics", "mae"]),
        &["metric `mae` is not registered", "Maaf::metric"],
    );
}

/// Writes the `split` views of the generated scene `data` into `dir` in the layout of
/// `examples/custom_data_format.rs`: its PNGs copied to `images/`, its cameras as
/// `maaf cameras` writes them. Returns the `views.json` entries.
fn views_entries(data: &Path, dir: &Path, split: &str) -> Vec<Value> {
    let cams = dir
        .parent()
        .expect("scratch folder")
        .join(format!("cams_{split}"));
    succeeded(maaf(&[
        "cameras",
        "--data",
        s(data),
        "--split",
        split,
        "--out",
        s(&cams),
    ]));
    let transforms = json(&data.join(format!("transforms_{split}.json")));
    let frames = transforms["frames"].as_array().expect("frames");
    std::fs::create_dir_all(dir.join("images")).expect("images folder");
    frames
        .iter()
        .enumerate()
        .map(|(i, frame)| {
            let file = frame["file_path"].as_str().expect("file_path");
            let source = data.join(format!("{}.png", file.trim_start_matches("./")));
            let image = format!("images/{split}_{i:03}.png");
            std::fs::copy(&source, dir.join(&image)).expect("copies the image");
            let mut camera = json(&cams.join(format!("{i:04}.json")));
            let time = camera["time"].take();
            camera.as_object_mut().expect("camera").remove("time");
            assert_eq!(time, frame["time"], "view {i} of {split}");
            serde_json::json!({"image": image, "time": time, "camera": camera})
        })
        .collect()
}

#[test]
fn a_data_format_of_ones_own_is_read_through_data_by_train_and_eval() {
    let fx = fixture("plugin_format");
    let scene = fx.root.join("views_scene");
    let listing = serde_json::json!({
        "train": views_entries(&fx.data, &scene, "train"),
        "test": views_entries(&fx.data, &scene, "test"),
    });
    std::fs::write(scene.join("views.json"), listing.to_string()).expect("views.json");
    let program = example("custom_data_format");
    let config = fx.root.join("config.json");
    std::fs::write(&config, format!("{{{BASE}}}")).expect("config");
    let out = fx.root.join("run");
    let train = [
        "train",
        "--data",
        s(&scene),
        "--out",
        s(&out),
        "--config",
        s(&config),
    ];
    // Plain `maaf` knows no such layout.
    refused(maaf(&train), &["views_scene", "transforms_train.json"]);
    assert!(!out.join("log.csv").exists());
    succeeded(run(&program, &train, &[]));
    assert_eq!(json(&out.join("summary.json"))["iterations"], 10);
    // The run records its data folder: eval finds it without --data.
    succeeded(run(
        &program,
        &["eval", "--run", s(&out), "--scales", "1", "--no-images"],
        &[],
    ));
    let scale = &json(&out.join("eval.json"))["scales"][0];
    assert_eq!(
        (&scale["width"], &scale["height"]),
        (&Value::from(32), &Value::from(32))
    );
    assert!(
        scale["psnr"].as_f64().is_some_and(f64::is_finite),
        "{scale}"
    );
    succeeded(run(&program, &["inspect", "--data", s(&scene)], &[]));
    // The built-in layouts come first: a D-NeRF folder with a broken views.json
    // still reads as D-NeRF, and a broken listing alone is refused naming the file.
    std::fs::write(fx.data.join("views.json"), "{}").expect("views.json");
    succeeded(run(&program, &["inspect", "--data", s(&fx.data)], &[]));
    std::fs::write(scene.join("views.json"), r#"{"train": []}"#).expect("views.json");
    refused(
        run(&program, &["inspect", "--data", s(&scene)], &[]),
        &["views.json", "test"],
    );
}
