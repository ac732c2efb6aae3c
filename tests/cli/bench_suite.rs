//! `maaf bench-suite` as a user runs it, on a folder of two tiny generated scenes: the
//! job list first (one line per scene x filter, the split rule applied), one line run
//! as written and again (skipped), one interrupted run resumed by its line, then the
//! suite run here, which skips those runs and does the others; a
//! second invocation does nothing, one whose evaluation was removed is only
//! evaluated, other options on the same folder are refused, and the report has a row
//! per scene and method, each method's average and the published rows. Records of a
//! suite's measurements are `bench_suite/records.rs`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use super::support::{TempDir, copy_dir, maaf, refused, s};

mod records;

fn ok(out: Output) -> String {
    assert!(
        out.status.success(),
        "failed: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The suite's options on `data`, `preset` and `out` (two filters' worth of runs
/// would do, but the default three are what the suite is for).
fn suite(data: &Path, preset: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "bench-suite",
        "--data",
        s(data),
        "--preset",
        s(preset),
        "--out",
        s(out),
        "--iters",
        "6",
        "--split",
        "b=val,lego=val",
        "--eval-args",
        "--no-images --max-views 2",
    ];
    args.extend_from_slice(extra);
    maaf(&args)
}

/// A generated scene at 192x192 (4 frames, one sample per pixel): trained at 1/4
/// scale, its 1/4x renders (12x12) still hold the 11x11 SSIM window.
fn scene(dir: &Path) {
    ok(maaf(&[
        "generate",
        "--out",
        s(dir),
        "--size",
        "192",
        "--frames",
        "4",
        "--samples",
        "1",
    ]));
}

fn count(text: &str, needle: &str) -> usize {
    text.matches(needle).count()
}

/// In `tmp`: a scenes folder with one scene `a`, a small preset `small.json`, and the
/// suite folder to write (`tmp/suite`, not created).
fn one_scene(tmp: &TempDir) -> (PathBuf, PathBuf, PathBuf) {
    let data = tmp.0.join("scenes");
    std::fs::create_dir_all(&data).expect("mkdir");
    scene(&data.join("a"));
    let preset = tmp.0.join("small.json");
    std::fs::write(
        &preset,
        r#"{"init_points": 200, "train_scale": 0.25, "val_every": 0}"#,
    )
    .expect("preset");
    (data, preset, tmp.0.join("suite"))
}

#[test]
fn suite_writes_jobs_runs_them_once_and_reports_every_scene_beside_the_published_rows() {
    let tmp = TempDir::fresh("cli_bench_suite");
    let data = tmp.0.join("scenes");
    std::fs::create_dir_all(&data).expect("mkdir");
    scene(&data.join("a"));
    scene(&data.join("b"));
    std::fs::create_dir_all(data.join("not_a_scene")).expect("mkdir");
    let preset = tmp.0.join("small.json");
    std::fs::write(
        &preset,
        r#"{"init_points": 200, "train_scale": 0.25, "val_every": 0, "checkpoint_every": 3}"#,
    )
    .expect("preset");
    let out = tmp.0.join("suite");

    ok(suite(&data, &preset, &out, &["--jobs-only"]));
    let jobs = std::fs::read_to_string(out.join("jobs.txt")).expect("jobs.txt");
    let lines: Vec<&str> = jobs.lines().collect();
    assert_eq!(
        lines.len(),
        6,
        "2 scenes x 3 filters x 1 background: {jobs}"
    );
    for (i, line) in lines.iter().enumerate() {
        assert!(line.contains(" bench-suite --out "), "{line}");
        assert!(line.contains(&format!(" --job {}   # ", i + 1)), "{line}");
        assert!(
            line.contains("small / ") && line.contains(" / black"),
            "{line}"
        );
    }
    assert!(
        lines[0].ends_with("# a small / none / black"),
        "{}",
        lines[0]
    );
    // The split rule: b is named (val), a is not (test); lego is absent and ignored.
    let spec = std::fs::read_to_string(out.join("suite.json")).expect("suite.json");
    assert_eq!(count(&spec, r#""split": "val""#), 3, "{spec}");
    assert_eq!(count(&spec, r#""split": "test""#), 3, "{spec}");
    assert!(!out.join("report.md").exists());

    // One line run as written, as on another machine; run again, it does nothing.
    let sh = |line: &str| Command::new("sh").arg("-c").arg(line).output().expect("sh");
    let printed = ok(sh(lines[0]));
    assert!(
        printed.contains("[1/6] a small / none / black: trained and evaluated"),
        "{printed}"
    );
    let first = out.join("runs/a/small-none-black");
    assert!(first.join("eval.json").is_file());
    assert!(ok(sh(lines[0])).contains("[1/6] a small / none / black: skipped (evaluated)"));

    // A run interrupted after its iteration-3 checkpoint: its line resumes it.
    let second = out.join("runs/a/small-mip3d-black");
    ok(sh(lines[1]));
    for done in ["eval.json", "summary.json"] {
        std::fs::remove_file(second.join(done)).expect("rm");
    }
    std::fs::remove_dir_all(second.join("model")).expect("rm model");
    assert!(second.join("checkpoints/iter_000003").is_dir());
    let printed = ok(sh(lines[1]));
    assert!(
        printed.contains("[2/6] a small / mip3d / black: resumed and evaluated"),
        "{printed}"
    );
    let summary = std::fs::read_to_string(second.join("summary.json")).expect("summary");
    assert!(summary.contains(r#""iterations": 6"#), "{summary}");
    assert!(second.join("eval.json").is_file());
    refused(
        maaf(&["bench-suite", "--out", s(&out), "--job", "7"]),
        &["--job 7", "suite.json", "1..=6"],
    );
    // The plan is read from suite.json: planning options beside --job or
    // --report-only would be ignored, so they are refused by name.
    for (read, arg) in [
        (["--job", "1"].as_slice(), ["--iters", "9"]),
        (["--report-only"].as_slice(), ["--filters", "none"]),
    ] {
        let mut argv = vec!["bench-suite", "--out", s(&out)];
        argv.extend(read);
        argv.extend(arg);
        let out = maaf(&argv);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "a usage error: {err}");
        for needle in [arg[0], read[0], "cannot be used with"] {
            assert!(err.contains(needle), "`{needle}` not in: {err}");
        }
    }

    let printed = ok(suite(&data, &preset, &out, &[]));
    assert_eq!(count(&printed, "skipped (evaluated)"), 2, "{printed}");
    assert_eq!(count(&printed, "trained and evaluated"), 4, "{printed}");

    let stamp = |p: &Path| std::fs::metadata(p.join("eval.json")).and_then(|m| m.modified());
    let before = stamp(&first).expect("mtime");
    let again = ok(suite(&data, &preset, &out, &[]));
    assert_eq!(count(&again, "skipped (evaluated)"), 6, "{again}");
    assert_eq!(stamp(&first).expect("mtime"), before);

    // A trained run whose evaluation is missing is only evaluated.
    let b_motion = out.join("runs/b/small-motion-black");
    std::fs::remove_file(b_motion.join("eval.json")).expect("rm");
    let third = ok(suite(&data, &preset, &out, &[]));
    assert_eq!(
        count(&third, "[6/6] b small / motion / black: evaluated"),
        1,
        "{third}"
    );
    assert!(b_motion.join("eval.json").is_file());

    refused(
        suite(&data, &preset, &out, &["--filters", "none"]),
        &["suite.json", "other options"],
    );

    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    for filter in ["none", "mip3d", "motion"] {
        let method = format!("small / {filter} / black");
        // Per-scene PSNR, SSIM and LPIPS tables: a row per scene, then the average.
        assert_eq!(count(&md, &format!("| {method} | a | test |")), 3, "{md}");
        assert_eq!(count(&md, &format!("| {method} | b | val |")), 3, "{md}");
        assert!(md.contains(&format!("| {method} (maaf) | 2 |")), "{md}");
    }
    assert_eq!(count(&md, "**average (2 scenes)**"), 3 * 3 + 3, "{md}");
    for published in ["36.61", "37.10", "34.50", "27.83", "32.28", "6.48", "2330"] {
        assert!(md.contains(published), "{published} missing: {md}");
    }
    assert!(md.contains("published"), "{md}");
    assert!(
        md.contains("VGG features"),
        "the released LPIPS network: {md}"
    );

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("json"))
            .expect("report.json parses");
    let methods = json["methods"].as_array().expect("methods");
    assert_eq!(methods.len(), 3);
    for m in methods {
        assert_eq!(m["scenes"].as_array().expect("scenes").len(), 2);
        assert_eq!(m["average"]["scenes"], 2);
        let scales = m["average"]["scales"].as_array().expect("scales");
        assert_eq!(scales.len(), 5, "1/4x .. 4x averaged: {m}");
    }
    assert_eq!(json["paper_tab2"].as_array().map(Vec::len), Some(2));
    assert_eq!(json["released"].as_array().map(Vec::len), Some(2));
    assert_eq!(json["missing"].as_array().map(Vec::len), Some(0));

    // The report alone, from suite.json.
    std::fs::remove_file(out.join("report.md")).expect("rm");
    ok(maaf(&["bench-suite", "--out", s(&out), "--report-only"]));
    assert!(out.join("report.md").is_file());
}

#[test]
fn seeds_give_one_run_each_and_the_report_averages_a_scene_over_them() {
    let tmp = TempDir::fresh("cli_bench_suite_seeds");
    let (data, preset, out) = one_scene(&tmp);
    refused(
        suite(
            &data,
            &preset,
            &out,
            &["--filters", "motion", "--seeds", "1,1"],
        ),
        &["--seeds", "seed 1 is given twice"],
    );
    assert!(!out.exists(), "a refused plan writes nothing");

    let printed = ok(suite(
        &data,
        &preset,
        &out,
        &["--filters", "motion", "--seeds", "3,4"],
    ));
    assert!(
        printed.contains("[2/2] a small / motion / black / seed 4: trained and evaluated"),
        "{printed}"
    );
    let jobs = std::fs::read_to_string(out.join("jobs.txt")).expect("jobs.txt");
    assert!(
        jobs.contains("# a small / motion / black / seed 3\n"),
        "{jobs}"
    );
    // Each run trained with its own seed, which its resolved config records.
    let mut psnr = Vec::new();
    for seed in [3, 4] {
        let run = out.join(format!("runs/a/small-motion-black-seed{seed}"));
        let config = std::fs::read_to_string(run.join("config.json")).expect("config");
        assert!(config.contains(&format!(r#""seed": {seed}"#)), "{config}");
        let eval: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(run.join("eval.json")).expect("eval"))
                .expect("eval.json parses");
        psnr.push(eval["scales"][0]["psnr"].as_f64().expect("psnr"));
    }
    assert_ne!(psnr[0], psnr[1], "two seeds, two different models");

    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(md.contains("| small / motion / black (maaf) | 1 |"), "{md}");
    assert!(md.contains("**average (1 scenes, 2 runs)**"), "{md}");
    assert!(md.contains("| a seed 3 | test |"), "{md}");
    assert!(md.contains("## Seeds"), "{md}");
    assert!(md.contains("| small / motion / black | a | 2 |"), "{md}");
    // The same suite again is this suite; other seeds are other options.
    assert_eq!(
        count(
            &ok(suite(
                &data,
                &preset,
                &out,
                &["--filters", "motion", "--seeds", "3,4"]
            )),
            "skipped (evaluated)"
        ),
        2
    );
    refused(
        suite(
            &data,
            &preset,
            &out,
            &["--filters", "motion", "--seeds", "3"],
        ),
        &["suite.json", "seeds"],
    );
}

#[test]
fn the_random_background_trains_with_its_own_config_on_black_data_and_evaluates_on_black() {
    let tmp = TempDir::fresh("cli_bench_suite_random");
    let (data, preset, out) = one_scene(&tmp);
    let printed = ok(suite(
        &data,
        &preset,
        &out,
        &["--filters", "motion", "--backgrounds", "black,random"],
    ));
    assert!(
        printed.contains("[2/2] a small / motion / random: trained and evaluated"),
        "{printed}"
    );
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).expect("read")).expect("json")
    };
    // The black runs keep the preset's config; the random ones have their own.
    let configs = out.join("configs");
    assert_eq!(
        read(&configs.join("small-motion.json"))["random_background"],
        false
    );
    assert_eq!(
        read(&configs.join("small-motion-random.json"))["random_background"],
        true
    );
    for (bg, random) in [("black", false), ("random", true)] {
        let run = out.join(format!("runs/a/small-motion-{bg}"));
        assert_eq!(
            read(&run.join("config.json"))["random_background"],
            random,
            "{bg}"
        );
        let eval = read(&run.join("eval.json"));
        assert_eq!(
            eval["background"],
            serde_json::json!([0.0, 0.0, 0.0]),
            "{bg}"
        );
    }
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(
        md.contains("| small / motion / random (maaf) | 1 |"),
        "{md}"
    );
    assert!(md.contains("| small / motion / black (maaf) | 1 |"), "{md}");
}

#[test]
fn also_eval_on_adds_evaluations_on_other_backgrounds_to_a_finished_suite_once() {
    let tmp = TempDir::fresh("cli_bench_suite_also_eval_on");
    let (data, preset, out) = one_scene(&tmp);
    let motion = ["--filters", "motion"];
    ok(suite(&data, &preset, &out, &motion));
    let run = out.join("runs/a/small-motion-black");
    let own = std::fs::read(run.join("eval.json")).expect("eval.json");
    // The same suite with evaluations added: the run is not trained again, is
    // evaluated on white and not on black (its own background).
    let also = ["--filters", "motion", "--also-eval-on", "white,black"];
    let printed = ok(suite(&data, &preset, &out, &also));
    assert!(
        printed.contains("[1/1] a small / motion / black: was evaluated, also on white\n"),
        "{printed}"
    );
    assert!(run.join("eval-on-white.json").is_file());
    assert!(!run.join("eval-on-black.json").exists());
    assert_eq!(
        std::fs::read(run.join("eval.json")).expect("eval.json"),
        own
    );
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(md.contains("## PSNR on other backgrounds"), "{md}");
    // Done once: the next invocation skips the run.
    let printed = ok(suite(&data, &preset, &out, &also));
    assert!(
        printed.contains("[1/1] a small / motion / black: skipped (evaluated)"),
        "{printed}"
    );
    refused(
        suite(&data, &preset, &out, &["--also-eval-on", "random"]),
        &["--also-eval-on random"],
    );
}
