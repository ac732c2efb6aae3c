//! Loss terms named in a config: a built-in regulariser used by plain `maaf train`,
//! and the README's ten-line program (`examples/custom_regulariser.rs`: the library's
//! command line plus a term of its own) training with its term, killed mid-run,
//! resumed bit-identical to an uninterrupted run, and evaluated; `maaf` itself
//! refuses to resume that run, naming the term.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use super::support::{fixture, maaf, refused, s, succeeded};

/// The README's program compiled into this test crate, so that its gradient test runs
/// under `cargo test` while `cargo test` builds the example itself as the program the
/// tests below run (an example marked `test = true` would be built only as a test
/// harness, without its `main`).
#[path = "../../examples/custom_regulariser.rs"]
mod readme_program;

/// The example binary: `cargo test` builds every example into `target/PROFILE/examples`,
/// beside the folder of the `maaf` binary.
pub(crate) fn example(name: &str) -> PathBuf {
    let bin = Path::new(env!("CARGO_BIN_EXE_maaf"));
    let path = bin
        .parent()
        .expect("profile folder")
        .join("examples")
        .join(name);
    assert!(
        path.is_file(),
        "{}: not built; `cargo test` builds the examples (or: cargo build --release --example {name})",
        path.display()
    );
    path
}

/// `PROGRAM ARGS` with two worker threads and extra environment, output captured.
pub(crate) fn run(program: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(program);
    cmd.args(args).env("RAYON_NUM_THREADS", "2");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run the program")
}

/// The header and the rows of `RUN/log.csv`, split into cells.
fn log(run: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(run.join("log.csv")).expect("log.csv");
    let mut lines = text
        .lines()
        .map(|l| l.split(',').map(String::from).collect());
    let header = lines.next().expect("header");
    (header, lines.collect())
}

/// The column `name` of the rows, as numbers.
fn column(run: &Path, name: &str) -> Vec<f64> {
    let (header, rows) = log(run);
    let i = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column `{name}` in {header:?}"));
    rows.iter()
        .map(|r| r[i].parse().expect("a number"))
        .collect()
}

/// The README shows the program line for line (its code between the `//!` header and
/// the marker before its gradient test).
#[test]
fn the_readme_shows_the_ten_line_program_as_it_is() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let read = |p: &str| std::fs::read_to_string(root.join(p)).expect(p);
    let example = read("examples/custom_regulariser.rs");
    let code: Vec<&str> = example
        .lines()
        .skip_while(|l| l.starts_with("//!") || l.is_empty())
        .take_while(|l| *l != "// ---- end of the README's program ----")
        .collect();
    let readme = read("README.md");
    let shown: Vec<&str> = readme
        .lines()
        .skip_while(|l| *l != "```rust")
        .skip(1)
        .take_while(|l| *l != "```")
        .collect();
    assert_eq!(shown, code);
    assert!(code.len() <= 12, "{} lines", code.len());
}

#[test]
fn a_built_in_term_named_in_a_config_is_trained_and_logged_by_plain_maaf() {
    let fx = fixture("terms_builtin");
    let terms = r#""terms": {"opacity_entropy": 0.001, "scale_anisotropy": 0.01, "depth_tv": 0.0001}, "log_every": 1"#;
    succeeded(fx.train("run", terms));
    let run = fx.root.join("run");
    let (header, _) = log(&run);
    for col in [
        "depth_tv",
        "opacity_entropy",
        "scale_anisotropy",
        "1e-4*depth_tv",
        "0.01*scale_anisotropy",
    ] {
        assert!(header.iter().any(|h| h == col), "`{col}` in {header:?}");
    }
    // Every step evaluated the entropy of opacities strictly inside (0, 1): positive,
    // at most ln 2; the weighted column is the weight times it.
    let h = column(&run, "opacity_entropy");
    assert_eq!(h.len(), 6);
    assert!(h.iter().all(|&v| v > 0.0 && v <= 2f64.ln()), "{h:?}");
    let weighted = column(&run, "0.001*opacity_entropy");
    for (w, v) in weighted.iter().zip(&h) {
        assert!(
            (w - 0.001 * v).abs() <= 1e-6 * w.abs().max(1e-12),
            "{w} vs {v}"
        );
    }
    assert!(column(&run, "depth_tv").iter().all(|&v| v > 0.0));
    let config: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(run.join("config.json")).expect("config.json"),
    )
    .expect("json");
    assert_eq!(config["terms"]["scale_anisotropy"], 0.01);
    // The run resumes with plain `maaf` (its terms are built in).
    succeeded(fx.resume(&run, "8"));
    assert_eq!(column(&run, "opacity_entropy").len(), 8);
    // A name no one registered is refused before any work, naming it.
    refused(
        fx.train("unknown", r#""terms": {"smoothness": 0.01}"#),
        &["`smoothness`", "not registered", "`opacity_entropy`"],
    );
    assert!(!fx.root.join("unknown").join("log.csv").exists());
}

#[test]
fn the_ten_line_program_trains_its_term_resumes_bit_identical_and_evaluates() {
    let program = example("custom_regulariser");
    let fx = fixture("terms_program");
    let config = fx.root.join("smooth.json");
    std::fs::write(
        &config,
        r#"{"iterations": 10, "init_points": 200, "train_scale": 0.5, "seed": 3,
            "checkpoint_every": 2, "log_every": 1, "val_every": 0,
            "densify": {"from": 2, "until": 9, "every": 2, "grad_threshold": 1e-6},
            "terms": {"smoothness": 0.05, "opacity_entropy": 0.001}}"#,
    )
    .expect("config");
    let train = |out: &Path, env: &[(&str, &str)]| {
        let args = [
            "train",
            "--data",
            s(&fx.data),
            "--out",
            s(out),
            "--config",
            s(&config),
        ];
        run(&program, &args, env)
    };
    let reference = fx.root.join("reference");
    succeeded(train(&reference, &[]));
    let smooth = column(&reference, "smoothness");
    assert_eq!(smooth.len(), 10);
    assert!(
        smooth.iter().all(|&v| v > 0.0 && v.is_finite()),
        "{smooth:?}"
    );
    assert!(log(&reference).0.iter().any(|h| h == "0.05*smoothness"));

    // Killed in the middle of the run (an abort at a write step, as a kill -9).
    let killed = fx.root.join("killed");
    let first = train(&killed, &[("MAAF_FAULT_ABORT_AT_WRITE", "36")]);
    assert!(
        !first.status.success(),
        "the fault injection did not stop the run"
    );
    assert!(
        killed.join("checkpoints").is_dir(),
        "killed before any checkpoint"
    );
    assert!(!killed.join("model").exists(), "killed after the end");

    // `maaf` itself does not know the term: one line naming it, nothing changed.
    let log_before = std::fs::read(killed.join("log.csv")).expect("log");
    refused(
        maaf(&["train", "--resume", s(&killed)]),
        &["config.json", "`smoothness`", "not registered"],
    );
    assert_eq!(
        std::fs::read(killed.join("log.csv")).expect("log"),
        log_before
    );

    // The program that registers it resumes to the uninterrupted run's tensors.
    succeeded(run(&program, &["train", "--resume", s(&killed)], &[]));
    let tensors = |r: &Path| std::fs::read(r.join("model/tensors.safetensors")).expect("model");
    assert!(
        tensors(&killed) == tensors(&reference),
        "the resumed run's tensors differ from the uninterrupted run's"
    );
    assert_eq!(column(&killed, "smoothness"), smooth);

    // And evaluates it (as does `maaf eval`: rendering needs no loss term).
    succeeded(run(
        &program,
        &["eval", "--run", s(&killed), "--scales", "1"],
        &[],
    ));
    let eval: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(killed.join("eval.json")).expect("eval.json"),
    )
    .expect("json");
    assert!(eval.to_string().contains("psnr"), "{eval}");
    succeeded(maaf(&["eval", "--run", s(&killed), "--scales", "1"]));
}
