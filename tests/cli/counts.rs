//! Every count bounded: each numeric flag of every command, given 0, 1, -1, a
//! billion, 2^64 - 1, NaN (and infinity where it parses as a number), exits with 0, 1
//! or 2 and, when refused, one line naming what is wrong; no value panics, runs away
//! or allocates past a 2 GB address space; and the counts that sized an allocation
//! (frames, cameras, views) are refused at a billion with the flag and its limit.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::support::{Fixture, copy_dir, fixture, maaf, s, succeeded};

/// The address space every command of this file runs in: a command that asks for
/// gigabytes of a billion-frame plan dies with an allocation failure instead.
const ADDRESS_SPACE_MB: u64 = 2048;

/// How long one command may take before it counts as running away.
const TIMEOUT: Duration = Duration::from_secs(300);

/// What a finished command gave: its exit code (`None`: killed by a signal) and
/// standard error.
struct Exit {
    code: Option<i32>,
    stderr: String,
}

/// `maaf ARGS` in an address space of [`ADDRESS_SPACE_MB`] (`ulimit -v`), standard
/// output discarded, standard error kept in `scratch/stderr`; killed and failed
/// after [`TIMEOUT`].
fn limited(scratch: &Path, args: &[String]) -> Exit {
    let err_path = scratch.join("stderr");
    let err_file = std::fs::File::create(&err_path).expect("stderr file");
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {}; exec \"$0\" \"$@\"",
            ADDRESS_SPACE_MB * 1024
        ))
        .arg(env!("CARGO_BIN_EXE_maaf"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(err_file)
        .spawn()
        .expect("spawn");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if start.elapsed() > TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("maaf {} ran past {TIMEOUT:?}", args.join(" "));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Exit {
        code: status.code(),
        stderr: std::fs::read_to_string(&err_path).unwrap_or_default(),
    }
}

/// The evaluation of the sweep's suites: one view at the training scale (16x16).
const EVAL: &str = "--no-images --max-views 1 --scales 1";

/// The sweep's values of an integer or float flag.
const NUMBERS: [&str; 7] = [
    "0",
    "1",
    "-1",
    "1000000000",
    "18446744073709551615",
    "NaN",
    "inf",
];

/// One command line of the sweep: its fixed arguments (`{out}` is replaced by a
/// fresh path per case) and its numeric flags, each with the value it has while
/// another flag is swept (`None`: absent then) and how a swept value is spelled
/// (`{}` replaced by the value: `{}x8` for a size).
struct Line {
    fixed: Vec<String>,
    flags: Vec<(&'static str, Option<&'static str>, &'static str)>,
}

fn line(fixed: &[&str], flags: &[(&'static str, Option<&'static str>, &'static str)]) -> Line {
    Line {
        fixed: fixed.iter().map(|a| a.to_string()).collect(),
        flags: flags.to_vec(),
    }
}

/// Every command with numeric flags, on the fixture's data, run and files.
fn lines(fx: &Fixture, run: &Path, suite: &Path, ply: &Path, camera: &Path) -> Vec<Line> {
    let data = s(&fx.data);
    let run = s(run);
    let scenes = fx.root.join("scenes");
    let scenes = s(&scenes);
    let preset = fx.root.join("preset.json");
    let preset = s(&preset);
    let config = fx.root.join("tiny.json");
    let config = s(&config);
    let n = "{}";
    vec![
        line(
            &["demo", "--data", data, "--out", "{out}"],
            &[("--iters", Some("1"), n), ("--seed", Some("0"), n)],
        ),
        line(
            &["generate", "--out", "{out}"],
            &[
                ("--size", Some("16"), n),
                ("--frames", Some("2"), n),
                ("--seed", Some("0"), n),
                ("--samples", Some("1"), n),
                ("--test-frames", Some("1"), n),
                ("--val-frames", Some("0"), n),
                ("--video-frames", Some("2"), n),
            ],
        ),
        line(
            &[
                "generate",
                "--out",
                "{out}",
                "--rig",
                "ring",
                "--size",
                "16",
                "--frames",
                "2",
                "--samples",
                "1",
                "--test-frames",
                "1",
                "--val-frames",
                "0",
                "--video-frames",
                "2",
            ],
            &[("--cameras", Some("2"), n)],
        ),
        line(
            &[
                "generate",
                "--out",
                "{out}",
                "--rig",
                "multiview",
                "--size",
                "16",
                "--frames",
                "2",
                "--cameras",
                "2",
                "--samples",
                "1",
            ],
            &[("--height", Some("16"), n)],
        ),
        line(
            &["cameras", "--data", data, "--out", "{out}"],
            &[("--scale", Some("1"), n)],
        ),
        line(
            &[
                "train", "--data", data, "--out", "{out}", "--config", config,
            ],
            &[
                ("--train-scale", Some("0.5"), n),
                ("--iters", Some("2"), n),
                ("--batch", Some("1"), n),
                ("--seed", Some("0"), n),
            ],
        ),
        line(
            &[
                "sweep",
                "--data",
                data,
                "--out",
                "{out}",
                "--grid",
                "filter.grid_t=25,50",
            ],
            &[
                ("--train-scale", Some("0.5"), n),
                ("--iters", Some("2"), n),
                ("--batch", Some("1"), n),
                ("--seed", Some("0"), n),
            ],
        ),
        line(
            &["eval", "--run", run, "--no-images"],
            &[
                ("--scales", Some("1"), n),
                ("--max-views", Some("1"), n),
                ("--frame-stride", Some("1"), n),
            ],
        ),
        line(
            &[
                "render",
                "--run",
                run,
                "--view",
                "test:0",
                "--out",
                "{out}.png",
            ],
            &[
                ("--time", Some("0.5"), n),
                ("--scale", None, n),
                ("--size", None, "{}x8"),
            ],
        ),
        line(
            &[
                "render-video",
                "--run",
                run,
                "--view",
                "test:0",
                "--out",
                "{out}",
            ],
            &[
                ("--frames", Some("2"), n),
                ("--scale", None, n),
                ("--size", None, "{}x8"),
            ],
        ),
        line(
            &["export-ply", "--run", run, "--out", "{out}.ply"],
            &[("--time", None, n)],
        ),
        line(
            &["export-ply", "--run", run, "--out", "{out}"],
            &[("--frames", None, n)],
        ),
        line(
            &[
                "render-ply",
                "--ply",
                s(ply),
                "--camera",
                s(camera),
                "--out",
                "{out}.png",
            ],
            &[("--sh-degree", Some("0"), n)],
        ),
        line(
            &["bench", "--run", run],
            &[
                ("--gaussians", Some("100"), n),
                ("--iters", Some("1"), n),
                ("--warmup", Some("0"), n),
                ("--batch", Some("1"), n),
            ],
        ),
        line(
            &[
                "bench-suite",
                "--data",
                scenes,
                "--preset",
                preset,
                "--out",
                "{out}",
                "--filters",
                "none",
                "--jobs-only",
                "--eval-args",
                EVAL,
            ],
            &[("--seeds", Some("0"), n), ("--iters", Some("2"), n)],
        ),
        line(&["bench-suite", "--out", s(suite)], &[("--job", None, n)]),
    ]
}

/// What the sweep saw: cases per exit code, as (0, 1, 2).
fn sweep(fx: &Fixture, lines: &[Line]) -> (usize, usize, usize) {
    let mut exits = (0, 0, 0);
    let mut case = 0;
    for l in lines {
        for (swept, _, spelling) in &l.flags {
            for value in NUMBERS {
                case += 1;
                let out = fx.root.join(format!("case_{case}"));
                let mut args: Vec<String> = l
                    .fixed
                    .iter()
                    .map(|a| a.replace("{out}", s(&out)))
                    .collect();
                for (flag, base, _) in &l.flags {
                    if flag == swept {
                        args.extend([flag.to_string(), spelling.replace("{}", value)]);
                    } else if let Some(b) = base {
                        args.extend([flag.to_string(), b.to_string()]);
                    }
                }
                let exit = limited(&fx.root, &args);
                let shown = format!("maaf {}: {:?}\n{}", args.join(" "), exit.code, exit.stderr);
                assert!(!exit.stderr.contains("panicked"), "{shown}");
                match exit.code {
                    Some(0) => exits.0 += 1,
                    Some(1) => {
                        let errors = exit
                            .stderr
                            .lines()
                            .filter(|l| l.starts_with("maaf: error: "))
                            .count();
                        assert_eq!(errors, 1, "one error line: {shown}");
                        exits.1 += 1;
                    }
                    Some(2) => {
                        // clap's usage error: one `error:` line naming the flag or
                        // value, then its usage hint.
                        let first = exit.stderr.lines().next().unwrap_or_default();
                        assert!(first.starts_with("error: "), "{shown}");
                        assert_eq!(exit.stderr.matches("error:").count(), 1, "{shown}");
                        exits.2 += 1;
                    }
                    _ => panic!("exit neither 0, 1 nor 2: {shown}"),
                }
            }
        }
    }
    println!(
        "numeric-flag sweep: {case} cases: {} exit 0, {} exit 1, {} exit 2",
        exits.0, exits.1, exits.2
    );
    exits
}

#[test]
fn every_numeric_flag_of_every_command_exits_cleanly_at_every_extreme() {
    let fx = fixture("counts_sweep");
    std::fs::write(
        fx.root.join("tiny.json"),
        r#"{"iterations": 2, "init_points": 100, "val_every": 0, "checkpoint_every": 2}"#,
    )
    .expect("config");
    let run = fx.trained("run");
    let scenes = fx.root.join("scenes");
    copy_dir(&fx.data, &scenes.join("a"));
    std::fs::write(
        fx.root.join("preset.json"),
        r#"{"iterations": 2, "init_points": 100, "train_scale": 0.25, "val_every": 0}"#,
    )
    .expect("preset");
    let suite = fx.root.join("suite");
    let preset = fx.root.join("preset.json");
    succeeded(maaf(&[
        "bench-suite",
        "--data",
        s(&scenes),
        "--preset",
        s(&preset),
        "--out",
        s(&suite),
        "--filters",
        "none",
        "--jobs-only",
        "--eval-args",
        EVAL,
    ]));
    let cameras = fx.root.join("cameras");
    succeeded(maaf(&[
        "cameras",
        "--data",
        s(&fx.data),
        "--out",
        s(&cameras),
    ]));
    let ply = fx.root.join("frame.ply");
    succeeded(maaf(&[
        "export-ply",
        "--run",
        s(&run),
        "--time",
        "0.5",
        "--out",
        s(&ply),
    ]));
    let lines = lines(&fx, &run, &suite, &ply, &cameras.join("0000.json"));
    let (ok, refused, usage) = sweep(&fx, &lines);
    let flags: usize = lines.iter().map(|l| l.flags.len()).sum();
    assert_eq!(ok + refused + usage, flags * NUMBERS.len());
    // Every flag refuses some value and accepts another: the sweep reached the
    // commands, not only their argument parsers.
    assert!(ok >= flags && refused >= flags, "{ok} {refused} {usage}");
}

#[test]
fn a_billion_frames_or_cameras_is_refused_at_once_naming_the_flag_and_its_limit() {
    let fx = fixture("counts_billion");
    let run = fx.trained("run");
    let generate = |extra: &[&str]| {
        let out = fx.root.join("gen");
        let mut args: Vec<String> = ["generate", "--out", s(&out), "--size", "16"]
            .iter()
            .map(|a| a.to_string())
            .collect();
        args.extend(extra.iter().map(|a| a.to_string()));
        limited(&fx.root, &args)
    };
    let cases = [
        (
            limited(
                &fx.root,
                &[
                    "render-video",
                    "--run",
                    s(&run),
                    "--view",
                    "test:0",
                    "--size",
                    "1x1",
                    "--frames",
                    "1000000000",
                    "--out",
                    s(&fx.root.join("video")),
                ]
                .map(String::from),
            ),
            "--frames 1000000000: must be in 1..=10000",
        ),
        (
            limited(
                &fx.root,
                &[
                    "export-ply",
                    "--run",
                    s(&run),
                    "--frames",
                    "1000000000",
                    "--out",
                    s(&fx.root.join("plys")),
                ]
                .map(String::from),
            ),
            "--frames 1000000000: must be in 1..=10000",
        ),
        (
            generate(&["--frames", "1000000000"]),
            "--frames 1000000000: must be in 2..=10000",
        ),
        (
            generate(&["--video-frames", "1000000000"]),
            "--video-frames 1000000000: must be in 2..=10000",
        ),
        (
            generate(&["--test-frames", "18446744073709551615"]),
            "--test-frames 18446744073709551615: must be in 1..=10000",
        ),
        (
            generate(&["--rig", "ring", "--cameras", "18446744073709551615"]),
            "--cameras 18446744073709551615: must be in 2..=100",
        ),
    ];
    for (exit, needle) in cases {
        assert_eq!(exit.code, Some(1), "{needle}: {}", exit.stderr);
        assert_eq!(exit.stderr.lines().count(), 1, "{}", exit.stderr);
        assert!(
            exit.stderr.contains(needle),
            "`{needle}` not in {}",
            exit.stderr
        );
    }
    assert!(!fx.root.join("gen").exists() && !fx.root.join("video").exists());
}
