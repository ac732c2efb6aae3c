//! A filter, a densification strategy and a representation of one's own, each in a
//! program of a few lines around `maaf::cli::Maaf` (`examples/custom_filter.rs`,
//! `custom_strategy.rs`, `custom_representation.rs`), named in a plain training
//! config: each program trains, is killed mid-run, `maaf` itself refuses to resume
//! the run (one line naming the run, the name and what it knows), the program
//! resumes it to the uninterrupted run's tensors, and the run is evaluated.

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
    let settings = r#""filter": {"kind": "median", "refresh": {"start": 2, "every": 2}},
        "densify": {"from": 2, "until": 9, "every": 2, "grad_threshold": 1e-6}"#;
    let needles = ["filter `median`", "not registered", "mip3d", "Maaf::filter"];
    let (reference, killed) = killed_and_resumed("custom_filter", &fx, settings, &needles);
    assert_eq!(
        json(&reference.join("config.json"))["filter"]["kind"],
        "median"
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
        "densify": {"strategy": "budgeted_growth", "every": 2}"#;
    let needles = [
        "densify.strategy `budgeted_growth`",
        "not registered",
        "default, sensitivity",
    ];
    let (reference, killed) = killed_and_resumed("custom_strategy", &fx, settings, &needles);
    // Refinements at 2, 4, 6 and 8 clone 20, 20, 10 and 0 (a lifetime of 50): the
    // count is the strategy's own state, saved with every checkpoint.
    for run in [&reference, &killed] {
        let state = json(&run.join("model/state.json"));
        assert_eq!(state["strategy"]["cloned"], 50, "{}", state["strategy"]);
    }
    let at4 = json(&reference.join("checkpoints/iter_000004/state.json"));
    assert_eq!(at4["strategy"]["cloned"], 40, "{}", at4["strategy"]);
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
        "deform, saro",
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
