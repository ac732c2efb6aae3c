//! Bad input and interrupted work as a user meets them on the command line, each
//! with the one-line message and the exit code it must give: resume after a kill,
//! a folder swap cut short, divergence, caps and panics, unchecked settings and
//! resume flags, and the smaller items (data paths, video folders, extensions, OS
//! errors printed once, non-UTF-8 folder names).

use std::process::Command;

use super::support::{BASE, Fixture, copy_dir, fixture, maaf, refused, s, stderr, succeeded};

#[test]
fn case_1_a_run_killed_before_its_model_resumes_from_its_newest_checkpoint() {
    let fx = fixture("bad_resume");
    let run = fx.trained("run");
    // As if killed after iteration 5: no model, a temporary left behind.
    std::fs::remove_dir_all(run.join("model")).expect("rm model");
    std::fs::write(run.join("checkpoints/.iter_000006.maaf-tmp-1"), b"partial").expect("temp");
    let err = succeeded(maaf(&["train", "--data", s(&fx.data), "--resume", s(&run)]));
    assert!(
        err.contains("resuming from") && err.contains("iter_000004"),
        "{err}"
    );
    assert!(!run.join("checkpoints/.iter_000006.maaf-tmp-1").exists());
    let log = std::fs::read_to_string(run.join("log.csv")).expect("log");
    assert_eq!(log.matches("iteration,").count(), 1, "{log}");
    // Rerunning with --out instead no longer starts over on top of it.
    refused(
        fx.train("run", ""),
        &["already holds a run; continue it with --resume"],
    );
}

#[test]
fn case_2_a_model_swap_cut_short_still_renders_and_resumes() {
    let fx = fixture("bad_swap");
    let run = fx.trained("run");
    // The fallback swap died between its renames: only the parked old model exists.
    std::fs::rename(run.join("model"), run.join(".model.old.maaf-tmp-4242")).expect("park");
    let png = fx.root.join("a.png");
    succeeded(maaf(&[
        "render",
        "--run",
        s(&run),
        "--view",
        "test:0",
        "--out",
        s(&png),
    ]));
    assert!(png.is_file());
    succeeded(fx.resume(&run, "8"));
    assert!(run.join("model/state.json").is_file());
    assert!(!run.join(".model.old.maaf-tmp-4242").exists());
}

#[test]
fn case_3_a_diverged_run_fails_and_its_model_is_refused() {
    let fx = fixture("bad_diverge");
    let extra = r#""iterations": 40, "model": {"kind": "saro", "lr": {"scaling": 1000}}"#;
    refused(fx.train("lr", extra), &["training diverged"]);
    let extra =
        r#""iterations": 40, "validate": true, "model": {"kind": "saro", "lr": {"scaling": 1000}}"#;
    refused(
        fx.train("lr_validate", extra),
        &["produced a non-finite value"],
    );
    // A model with a NaN parameter (as an older version could save) is refused by eval.
    let run = fx.trained("run");
    let data = maaf::train::data::Dataset::open(&fx.data, Default::default()).expect("data");
    let mut t = maaf::train::trainer::load_checkpoint(&data, &run.join("model")).expect("model");
    let p = t
        .state
        .model
        .params_mut()
        .iter_mut()
        .next()
        .expect("a parameter");
    p.value.data_mut()[0] = f32::NAN;
    maaf::train::trainer::save_checkpoint(&t, &run.join("model")).expect("save");
    refused(
        maaf(&["eval", "--run", s(&run), "--max-views", "1"]),
        &["the run diverged, this model cannot be used"],
    );
    assert!(!run.join("eval.json").exists());
    // An eval.json with a null metric (written by an older version): one line.
    let null_psnr = r#"{"model":"saro","filter":"none","train_scale":0.5,"iterations":6,
        "train_seconds":1.0,"num_gaussians":1,"model_bytes":4,"filter_bytes":0,
        "background":[1,1,1],"quantized_8bit":false,"scales":[{"scale":1.0,"width":32,
        "height":32,"psnr":null,"ssim":0.5,"lpips":null}]}"#;
    std::fs::write(run.join("eval.json"), null_psnr).expect("eval.json");
    let report = fx.root.join("report");
    refused(
        maaf(&["report", "--runs", s(&run), "--out", s(&report)]),
        &["a null metric"],
    );
}

#[test]
fn case_4_huge_cameras_and_bad_field_sizes_are_one_line_errors() {
    let fx = fixture("bad_caps");
    succeeded(fx.train("run", ""));
    let cam = fx.root.join("cam.json");
    std::fs::write(
        &cam,
        r#"{"width":200000,"height":200000,"fx":100,"fy":100,"cx":100000,"cy":100000,
           "world_to_camera":[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}"#,
    )
    .expect("cam");
    let run = fx.root.join("run");
    let png = fx.root.join("huge.png");
    refused(
        maaf(&[
            "render",
            "--run",
            s(&run),
            "--camera",
            s(&cam),
            "--out",
            s(&png),
        ]),
        &["200000x200000 is over the cap of 16384 px a side"],
    );
    let spatial = r#""model": {"kind": "saro", "field": {"spatial_res": 63}}"#;
    refused(
        fx.train("a", spatial),
        &["model.field.spatial_res = 63: must be a power of two"],
    );
    let channels = r#""model": {"kind": "saro", "field": {"channels": 0}}"#;
    refused(
        fx.train("b", channels),
        &["model.field.channels = 0: must be in 1..=256"],
    );
}

#[test]
fn case_5_settings_are_checked_and_resume_keeps_the_run_settings() {
    let fx = fixture("bad_settings");
    let cases = [
        (
            r#""model": {"kind": "saro", "lr": {"scaling": -0.1}}"#,
            "model.lr.scaling = -0.1",
        ),
        (
            r#""lambda_dssim": 2"#,
            "lambda_dssim = 2: must be a number in [0, 1]",
        ),
        (
            r#""init_points": 0"#,
            "init_points = 0: must be an integer in 1..=10000000",
        ),
        (
            r#""densify": {"max_gaussians": 0}"#,
            "densify.max_gaussians = 0",
        ),
        (
            r#""model": {"kind": "saro", "sh_degree": 7}"#,
            "model.sh_degree = 7: must be in 0..=3",
        ),
        (
            r#""iterations": 0"#,
            "iterations = 0: must be an integer in 1..=100000000",
        ),
        (
            r#""checkpoint_every": 0"#,
            "checkpoint_every = 0: must be an integer >= 1",
        ),
        (
            r#""log_every": 10, "val_every": 15"#,
            "val_every = 15: must be 0 or a multiple",
        ),
        (r#""max_skipped_fraction": 2"#, "max_skipped_fraction = 2"),
    ];
    for (i, (extra, needle)) in cases.iter().enumerate() {
        refused(fx.train(&format!("bad{i}"), extra), &[needle]);
        assert!(
            !fx.root.join(format!("bad{i}")).exists(),
            "no work before the check"
        );
    }
    let run = fx.trained("run");
    let resume = |extra: &[&str]| {
        let mut args = vec!["train", "--data", s(&fx.data), "--resume", s(&run)];
        args.extend_from_slice(extra);
        maaf(&args)
    };
    for (flag, value) in [
        ("--seed", "4"),
        ("--filter", "mip3d"),
        ("--train-scale", "0.25"),
    ] {
        refused(
            resume(&[flag, value]),
            &["a resumed run keeps its settings"],
        );
    }
    succeeded(resume(&[]));
    let config = std::fs::read_to_string(run.join("config.json")).expect("config");
    assert!(
        config.contains("\"iterations\": 6,"),
        "budget kept: {config}"
    );
    let err = succeeded(resume(&["--iters", "8"]));
    assert!(err.contains("budget changes from 6 to 8"), "{err}");
    // A frame time outside [0, 1] names the file and field.
    let bad = fx.root.join("bad_time");
    copy_dir(&fx.data, &bad);
    let json = bad.join("transforms_train.json");
    let text = std::fs::read_to_string(&json).expect("json");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("parse");
    v["frames"][0]["time"] = serde_json::json!(1.5);
    std::fs::write(&json, v.to_string()).expect("write");
    refused(
        maaf(&["inspect", "--data", s(&bad)]),
        &["field `frames[0].time`: 1.5 is outside [0, 1]"],
    );
    // Rendering outside the data's time range warns.
    let png = fx.root.join("t2.png");
    let err = succeeded(maaf(&[
        "render",
        "--run",
        s(&run),
        "--view",
        "test:0",
        "--time",
        "2",
        "--out",
        s(&png),
    ]));
    assert!(
        err.contains("--time 2 is outside the data's time range"),
        "{err}"
    );
}

#[test]
fn case_6_paths_video_folders_extensions_and_os_errors() {
    let fx = fixture("bad_small");
    // Trained with a relative data path from the fixture folder.
    let config = fx.root.join("c.json");
    std::fs::write(&config, format!("{{{BASE}}}")).expect("config");
    let out = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .current_dir(&fx.root)
        .args([
            "train", "--data", "data", "--out", "run", "--config", "c.json",
        ])
        .output()
        .expect("train");
    succeeded(out);
    let run = fx.root.join("run");
    let recorded = std::fs::read_to_string(run.join("data.json")).expect("data.json");
    let canonical = std::fs::canonicalize(&fx.data).expect("canonical");
    assert!(recorded.contains(s(&canonical)), "{recorded}");
    // Evaluated from another working folder with the recorded data.
    let png = fx.root.join("x.png");
    let out = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .current_dir(std::env::temp_dir())
        .args([
            "render",
            "--run",
            s(&run),
            "--view",
            "test:0",
            "--out",
            s(&png),
        ])
        .output()
        .expect("render");
    succeeded(out);
    // A video into a folder of a longer earlier video keeps only the new frames.
    let video = fx.root.join("video");
    for frames in ["4", "2"] {
        succeeded(maaf(&[
            "render-video",
            "--run",
            s(&run),
            "--view",
            "test:0",
            "--frames",
            frames,
            "--out",
            s(&video),
        ]));
    }
    assert_eq!(
        std::fs::read_dir(&video).expect("ls").count(),
        3,
        "2 frames + gif"
    );
    std::fs::write(video.join("notes.txt"), b"mine").expect("user file");
    refused(
        maaf(&[
            "render-video",
            "--run",
            s(&run),
            "--view",
            "test:0",
            "--frames",
            "2",
            "--out",
            s(&video),
        ]),
        &["holds `notes.txt`, which is not a frame"],
    );
    let jpg = fx.root.join("x.jpg");
    refused(
        maaf(&[
            "render",
            "--run",
            s(&run),
            "--view",
            "test:0",
            "--out",
            s(&jpg),
        ]),
        &["writes PNG; give a file name ending in .png"],
    );
    // An OS error is printed once.
    let missing = fx.root.join("no_such_dir/x.png");
    let out = maaf(&[
        "render",
        "--run",
        s(&run),
        "--view",
        "test:0",
        "--out",
        s(&missing),
    ]);
    let err = stderr(&out);
    refused(out, &["No such file or directory"]);
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
    non_utf8_data_is_refused_before_training(&fx);
}

#[cfg(unix)]
fn non_utf8_data_is_refused_before_training(fx: &Fixture) {
    use std::os::unix::ffi::OsStrExt;
    let name = std::ffi::OsStr::from_bytes(b"data_\xff");
    let data = fx.root.join(name);
    std::fs::rename(&fx.data, &data).expect("rename");
    let run = fx.root.join("utf8_run");
    let out = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .arg("train")
        .arg("--data")
        .arg(&data)
        .args(["--out", s(&run)])
        .output()
        .expect("train");
    refused(out, &["is not valid UTF-8"]);
    assert!(!run.exists(), "refused before any work");
    std::fs::rename(&data, &fx.data).expect("rename back");
}

#[cfg(not(unix))]
fn non_utf8_data_is_refused_before_training(_fx: &Fixture) {}
