//! `maaf bench-suite` checked before hours of training, honest about what it did, and
//! never leaving a child behind: the evaluation's arguments and scales are refused
//! while planning, evaluation-only options may change on a trained suite (its runs
//! evaluated again, never retrained), a suite or job that evaluated fewer runs than
//! planned fails, a killed suite's training dies with it, and repeated list values,
//! unregistered names and a recording cut short by a full disk are refused or leave
//! nothing behind.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use super::support::{Fixture, copy_dir, fixture, maaf, refused, s, stderr, succeeded};

/// A suite folder of one scene (the fixture's tiny scene as `scenes/a`) and a small
/// preset trained at 1/4 scale (16x16 images).
struct Suite {
    fx: Fixture,
    scenes: PathBuf,
    preset: PathBuf,
    out: PathBuf,
}

fn suite_fixture(name: &str) -> Suite {
    let fx = fixture(name);
    let scenes = fx.root.join("scenes");
    copy_dir(&fx.data, &scenes.join("a"));
    let preset = fx.root.join("small.json");
    std::fs::write(
        &preset,
        r#"{"iterations": 2, "init_points": 100, "train_scale": 0.25, "val_every": 0}"#,
    )
    .expect("preset");
    let out = fx.root.join("suite");
    Suite {
        fx,
        scenes,
        preset,
        out,
    }
}

impl Suite {
    /// `maaf bench-suite` of the one scene with the `none` filter, `eval_args` and
    /// `extra` options.
    fn command(&self, eval_args: &str, extra: &[&str]) -> Command {
        let mut command = Command::new(env!("CARGO_BIN_EXE_maaf"));
        command
            .args(["bench-suite", "--data", s(&self.scenes), "--preset"])
            .args([s(&self.preset), "--out", s(&self.out), "--filters", "none"])
            .args(["--eval-args", eval_args])
            .args(extra);
        command
    }

    /// [`Suite::command`], run to its end.
    fn run(&self, eval_args: &str, extra: &[&str]) -> Output {
        self.command(eval_args, extra).output().expect("run maaf")
    }

    /// The one run's folder.
    fn run_dir(&self) -> PathBuf {
        self.out.join("runs/a/small-none-black")
    }
}

/// Standard output of a finished command, as text.
fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

const EVAL: &str = "--no-images --max-views 1 --scales 1";

#[test]
fn the_evaluation_is_checked_while_planning_and_may_change_without_retraining() {
    let st = suite_fixture("suite_eval_plan");
    // Arguments maaf eval refuses, and scales none of which the scene can be evaluated
    // at, are refused before anything is trained or written.
    refused(
        st.run("--bogus", &[]),
        &["--eval-args `--bogus`", "--bogus"],
    );
    refused(
        st.run("--no-images --scales 8", &[]),
        &["cannot evaluate scene a", "8x needs 128x128 ground truth"],
    );
    // A config trained at the source scale cannot be evaluated at 2x or 4x: asked for
    // those scales alone it is refused, naming its training scale; with the default
    // scales it is planned (eval skips those two and evaluates the others).
    let full = st.fx.root.join("full.json");
    std::fs::write(&full, r#"{"iterations": 2, "train_scale": 1.0}"#).expect("preset");
    let full_suite = |eval_args: &str, out: &Path, extra: &[&str]| {
        let mut args = vec![
            "bench-suite",
            "--data",
            s(&st.scenes),
            "--preset",
            s(&full),
            "--out",
            s(out),
            "--filters",
            "none",
            "--eval-args",
            eval_args,
        ];
        args.extend_from_slice(extra);
        maaf(&args)
    };
    refused(
        full_suite("--no-images --scales 2,4", &st.out, &[]),
        &["cannot evaluate scene a", "trained at scale 1", "2x needs"],
    );
    assert!(!st.out.exists(), "nothing written for a refused plan");
    let planned = st.fx.root.join("full_suite");
    succeeded(full_suite("--no-images", &planned, &["--jobs-only"]));
    assert!(planned.join("jobs.txt").is_file());

    let first = succeeded_out(st.run(EVAL, &[]));
    assert!(first.contains("trained and evaluated"), "{first}");
    let summary = std::fs::read(st.run_dir().join("summary.json")).expect("summary");
    // Only the spacing differs: the same suite, nothing to do.
    let spaced = succeeded_out(st.run("--no-images  --max-views 1   --scales 1", &[]));
    assert!(spaced.contains("skipped (evaluated)"), "{spaced}");
    // Other evaluation arguments: accepted, the run evaluated again, not retrained.
    let again = succeeded_out(st.run("--no-images --max-views 2 --scales 1", &[]));
    assert!(again.contains("evaluations removed"), "{again}");
    assert!(
        again.contains("a small / none / black: evaluated"),
        "{again}"
    );
    assert_eq!(
        std::fs::read(st.run_dir().join("summary.json")).expect("summary"),
        summary,
        "the run was not retrained"
    );
    let spec = std::fs::read_to_string(st.out.join("suite.json")).expect("suite.json");
    assert!(spec.contains("--max-views 2"), "{spec}");
    // Training options still may not change.
    refused(st.run(EVAL, &["--iters", "3"]), &["other options"]);
}

/// Asserts success; returns the standard output.
fn succeeded_out(out: Output) -> String {
    let text = stdout(&out);
    succeeded(out);
    text
}

#[test]
fn a_suite_that_evaluates_fewer_runs_than_planned_fails() {
    let st = suite_fixture("suite_false_success");
    // Options of maaf eval the suite sets itself, and --help, are refused at once.
    refused(
        st.run("--no-images --background white", &[]),
        &["--background is set by the suite"],
    );
    refused(
        st.run("--help", &[]),
        &["print its help", "evaluates nothing"],
    );
    assert!(!st.out.exists());
    // A suite.json whose evaluation writes no eval.json (edited by hand, or from an
    // older version that let --background through): the job fails, not succeeds.
    succeeded(st.run(EVAL, &["--jobs-only"]));
    let spec_path = st.out.join("suite.json");
    let spec = std::fs::read_to_string(&spec_path).expect("suite.json");
    let edited = spec.replace(EVAL, &format!("{EVAL} --background white"));
    assert_ne!(spec, edited);
    std::fs::write(&spec_path, edited).expect("edit");
    let job = maaf(&["bench-suite", "--out", s(&st.out), "--job", "1"]);
    refused(job, &["exited 0 but wrote no", "eval.json"]);
    assert!(!st.run_dir().join("eval.json").exists());
}

#[test]
fn repeated_values_and_unregistered_names_are_refused_before_any_job() {
    let st = suite_fixture("suite_repeats");
    refused(
        st.run(EVAL, &["--filters", "none,none", "--jobs-only"]),
        &["--filters: filter none is given twice"],
    );
    refused(
        st.run(EVAL, &["--backgrounds", "black,black", "--jobs-only"]),
        &["--backgrounds: background black is given twice"],
    );
    std::fs::write(
        &st.preset,
        r#"{"iterations": 2, "train_scale": 0.25, "model": {"kind": "nope"}}"#,
    )
    .expect("preset");
    refused(
        st.run(EVAL, &["--jobs-only"]),
        &["small.json", "model.kind", "`nope` is not registered"],
    );
    assert!(!st.out.exists());
}

#[test]
fn a_record_cut_short_by_a_full_disk_leaves_no_folder_behind() {
    let st = suite_fixture("suite_record_full");
    succeeded(st.run(EVAL, &[]));
    let record = st.fx.root.join("record");
    // Files over 512 bytes cannot be written (as on a full disk); the signal such a
    // write raises is ignored, so the write fails with an error instead.
    let out = Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 1; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_maaf"))
        .args(["bench-suite", "--out", s(&st.out), "--record", s(&record)])
        .output()
        .expect("run");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!record.exists(), "a failed record leaves nothing: {err}");
    let later = succeeded_out(maaf(&[
        "bench-suite",
        "--out",
        s(&st.out),
        "--record",
        s(&record),
    ]));
    assert!(later.contains("recorded 1 of 1 runs"), "{later}");
}

/// The process id in a run's lock file while a running `maaf train` holds it (a
/// killed trainer's label stays in the file: its process is gone).
fn trainer_pid(run: &Path, deadline: Instant) -> u32 {
    loop {
        let label = std::fs::read_to_string(run.join("run.lock")).unwrap_or_default();
        if let Some(pid) = label
            .strip_prefix("trained (maaf train, pid ")
            .and_then(|r| r.strip_suffix(')'))
            .and_then(|p| p.parse().ok())
            .filter(|&p| !gone(p))
        {
            return pid;
        }
        assert!(
            Instant::now() < deadline,
            "the suite never started training"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Whether process `pid` is gone: no such process, or a zombie nobody reaped yet
/// whose threads have all ended (a killed process's first thread turns zombie while
/// the others still exit, holding its files).
fn gone(pid: u32) -> bool {
    let proc = std::path::PathBuf::from(format!("/proc/{pid}"));
    let stat = std::fs::read_to_string(proc.join("stat")).unwrap_or_default();
    // The state follows the command name in parentheses.
    let zombie = stat
        .rsplit_once(')')
        .is_none_or(|(_, rest)| rest.trim_start().starts_with('Z'));
    let threads = std::fs::read_dir(proc.join("task")).map_or(0, |t| t.count());
    zombie && threads <= 1
}

#[cfg(target_os = "linux")]
#[test]
fn a_killed_suite_leaves_no_training_running() {
    let st = suite_fixture("suite_orphans");
    for signal in ["KILL", "TERM"] {
        let mut suite = st
            .command(EVAL, &["--iters", "100000000"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn");
        let deadline = Instant::now() + Duration::from_secs(120);
        let child = trainer_pid(&st.run_dir(), deadline);
        let status = Command::new("kill")
            .args([format!("-{signal}"), suite.id().to_string()])
            .status()
            .expect("kill");
        assert!(status.success());
        suite.wait().expect("wait");
        let deadline = Instant::now() + Duration::from_secs(30);
        while !gone(child) {
            assert!(
                Instant::now() < deadline,
                "SIG{signal} of the suite left its maaf train {child} running"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    // Nothing holds the run: the next invocation resumes it (a shorter budget is
    // refused as a change of options, so the check is the lock alone).
    let lock = std::fs::OpenOptions::new()
        .write(true)
        .open(st.run_dir().join("run.lock"))
        .expect("lock file");
    lock.try_lock().expect("no process holds the run");
}
