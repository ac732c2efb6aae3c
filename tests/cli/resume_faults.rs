//! Fault injection on `maaf train` (a tiny synthetic scene, 10 iterations): child
//! processes aborted at chosen write steps (config, log, checkpoint and model writes,
//! inside the folder swaps too) and killed at random moments are resumed with
//! `--resume`; the final tensors equal those of an uninterrupted run byte for byte and
//! `log.csv` holds each iteration once under one header. A full disk injected in the
//! middle of a checkpoint fails with one line and leaves the previous checkpoint
//! loadable and no temporary behind.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use super::support::{TempDir, s, tiny_scene};

fn maaf(args: &[&str], env: &[(&str, String)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_maaf"));
    cmd.args(args).env("RAYON_NUM_THREADS", "2");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run maaf")
}

fn ok(out: Output, what: &str) -> Output {
    assert!(
        out.status.success(),
        "{what} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Densification, opacity resets, filter refreshes, the SaRO stage switch and its
/// adaptive learning-rate refreshes (every 2, so checkpoints carry the scale computed
/// at their own iteration from the parameters before that step) all happen inside
/// the 10 iterations, between checkpoints every 2.
const CONFIG: &str = r#"{
  "iterations": 10, "init_points": 300, "train_scale": 0.5, "seed": 5,
  "checkpoint_every": 2, "log_every": 1, "val_every": 0,
  "model": {"kind": "saro", "static_iterations": 3, "adaptive_every": 2},
  "filter": {"kind": "motion", "refresh": {"start": 2, "every": 3, "after_densify": true}},
  "densify": {"from": 2, "until": 9, "every": 2, "opacity_reset_every": 5, "grad_threshold": 1e-6}
}"#;

struct Scene {
    _tmp: TempDir,
    root: PathBuf,
    data: PathBuf,
    config: PathBuf,
}

fn scene(name: &str) -> Scene {
    let tmp = TempDir::fresh(&format!("faults_{name}"));
    let root = tmp.0.clone();
    let data = root.join("data");
    tiny_scene(&data);
    let config = root.join("config.json");
    std::fs::write(&config, CONFIG).expect("config");
    Scene {
        _tmp: tmp,
        root,
        data,
        config,
    }
}

fn train_args<'a>(sc: &'a Scene, run: &'a Path) -> Vec<&'a str> {
    vec![
        "train",
        "--data",
        s(&sc.data),
        "--out",
        s(run),
        "--config",
        s(&sc.config),
    ]
}

fn resume(sc: &Scene, run: &Path) -> Output {
    maaf(&["train", "--data", s(&sc.data), "--resume", s(run)], &[])
}

/// Every entry below `dir` whose name marks a temporary.
fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for e in std::fs::read_dir(dir).expect("ls").flatten() {
        let p = e.path();
        if e.file_name().to_string_lossy().contains(".maaf-tmp-") {
            found.push(p.clone());
        }
        if p.is_dir() {
            found.extend(temporaries(&p));
        }
    }
    found
}

/// The iteration column of `log.csv`, after checking there is exactly one header.
fn logged_iterations(run: &Path) -> Vec<usize> {
    let text = std::fs::read_to_string(run.join("log.csv")).expect("log.csv");
    let mut lines = text.lines();
    assert!(lines.next().expect("header").starts_with("iteration,"));
    lines
        .map(|l| {
            l.split(',')
                .next()
                .and_then(|v| v.parse().ok())
                .expect("row")
        })
        .collect()
}

fn tensors(run: &Path) -> Vec<u8> {
    std::fs::read(run.join("model/tensors.safetensors")).expect("final tensors")
}

fn assert_same_as_reference(reference: &Path, run: &Path, what: &str) {
    assert!(
        tensors(reference) == tensors(run),
        "{what}: final tensors differ"
    );
    assert_eq!(
        logged_iterations(run),
        (1..=10).collect::<Vec<_>>(),
        "{what}"
    );
    assert_eq!(temporaries(run), Vec::<PathBuf>::new(), "{what}");
}

#[test]
fn runs_killed_anywhere_resume_to_the_uninterrupted_tensors() {
    let sc = scene("kill");
    let reference = sc.root.join("reference");
    ok(maaf(&train_args(&sc, &reference), &[]), "reference run");
    // The same run resumed after it finished changes nothing.
    ok(resume(&sc, &reference), "resume of a finished run");
    assert_eq!(logged_iterations(&reference), (1..=10).collect::<Vec<_>>());

    // Steps 1-5 are config.json, 6-10 the log header; each checkpoint is about 12
    // steps; the final swap of model/ follows the last one.
    let mut aborted = 0;
    for k in [1, 4, 8, 11, 17, 23, 30, 36, 41, 47, 52, 58, 64, 70] {
        let run = sc.root.join(format!("abort_{k}"));
        let env = [("MAAF_FAULT_ABORT_AT_WRITE", k.to_string())];
        let first = maaf(&train_args(&sc, &run), &env);
        if !first.status.success() {
            aborted += 1;
            let stderr = String::from_utf8_lossy(&first.stderr);
            assert!(stderr.contains("fault injection: abort"), "{stderr}");
            if run.join("config.json").exists() {
                ok(
                    resume(&sc, &run),
                    &format!("resume after abort at step {k}"),
                );
            } else {
                // Killed before the run existed: resume says so, a new start works.
                let refused = resume(&sc, &run);
                assert_eq!(refused.status.code(), Some(1));
                assert!(String::from_utf8_lossy(&refused.stderr).contains("no run to resume"));
                ok(maaf(&train_args(&sc, &run), &[]), "restart");
            }
        }
        assert_same_as_reference(&reference, &run, &format!("abort at write step {k}"));
    }
    assert!(aborted >= 12, "only {aborted} injected aborts landed");

    // Kills at moments the test does not choose: SIGKILL after a pseudo-random delay,
    // then resumes until the run completes (a resume may be killed too).
    let mut seed = u64::from(std::process::id());
    for round in 0..3 {
        let run = sc.root.join(format!("sigkill_{round}"));
        // A run killed before it wrote config.json does not exist yet: start it again
        // rather than resume it (resume refuses, as the abort cases above check).
        let args_now = || -> Vec<String> {
            if run.join("config.json").exists() {
                ["train", "--data", s(&sc.data), "--resume", s(&run)]
                    .map(String::from)
                    .to_vec()
            } else {
                train_args(&sc, &run)
                    .iter()
                    .map(|a| a.to_string())
                    .collect()
            }
        };
        for attempt in 0..6 {
            let args = args_now();
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let delay = Duration::from_millis(20 + (seed >> 33) % 200);
            let mut child = Command::new(env!("CARGO_BIN_EXE_maaf"))
                .args(&args)
                .env("RAYON_NUM_THREADS", "2")
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()
                .expect("spawn");
            std::thread::sleep(delay);
            let _ = child.kill();
            let status = child.wait().expect("wait");
            if status.success() && attempt > 0 {
                break;
            }
        }
        if run.join("config.json").exists() {
            ok(resume(&sc, &run), "final resume");
        } else {
            ok(
                maaf(&train_args(&sc, &run), &[]),
                "start after kills before it began",
            );
        }
        assert_same_as_reference(&reference, &run, &format!("SIGKILL round {round}"));
    }
}

#[test]
fn a_full_disk_mid_checkpoint_keeps_the_previous_one_and_no_temporary() {
    let sc = scene("enospc");
    let reference = sc.root.join("reference");
    ok(maaf(&train_args(&sc, &reference), &[]), "reference run");
    let run = sc.root.join("full");
    // Data writes: 1 data.json, 2 config.json, 3 log header, 4-5 iter_2, 6 = iter_4's
    // tensors.
    let env = [("MAAF_FAULT_ENOSPC_AT_WRITE", "6".to_string())];
    let out = maaf(&train_args(&sc, &run), &env);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let errors: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("maaf: error"))
        .collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert!(
        errors[0].contains("iter_000004") && errors[0].contains("No space left on device"),
        "{stderr}"
    );
    assert_eq!(
        errors[0].matches("No space left").count(),
        1,
        "the OS error is printed once: {stderr}"
    );
    assert_eq!(temporaries(&run), Vec::<PathBuf>::new());
    let checkpoints: Vec<String> = std::fs::read_dir(run.join("checkpoints"))
        .expect("ls")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(checkpoints, ["iter_000002"]);
    let data = maaf::train::data::Dataset::open(&sc.data, Default::default()).expect("data");
    let loaded = maaf::train::trainer::load_checkpoint(&data, &run.join("checkpoints/iter_000002"))
        .expect("the previous checkpoint loads");
    assert_eq!(loaded.iteration, 2);
    ok(resume(&sc, &run), "resume after the full disk");
    assert_same_as_reference(&reference, &run, "full disk");
}
