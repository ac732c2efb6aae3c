//! Nothing left behind and nothing written twice: a generation holds its folder as a
//! trainer holds its run, what a killed export, video or generation left beside its
//! target is swept by the next one, `maaf cameras` replaces an earlier folder whole,
//! and a refused `train`, `--from` or `eval` leaves no folder or lock file of its own.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::support::{fixture, maaf, refused, s, succeeded};

/// The names in `dir` containing the temporaries' marker.
fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("ls")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".maaf-tmp-"))
        .collect()
}

/// `maaf ARGS` killed by the fault injection at its `step`-th write step (as a
/// `kill -9` there would): it must not succeed.
fn killed_at(step: usize, args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args(args)
        .env("MAAF_FAULT_ABORT_AT_WRITE", step.to_string())
        .output()
        .expect("run");
    assert!(
        !out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn two_generations_into_one_folder_do_not_both_succeed() {
    let fx = fixture("litter_generate_lock");
    let out = fx.root.join("scene");
    let mut first = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args([
            "generate",
            "--out",
            s(&out),
            "--size",
            "128",
            "--frames",
            "40",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let start = Instant::now();
    while !std::fs::read_to_string(out.join("run.lock"))
        .unwrap_or_default()
        .contains("generated")
    {
        assert!(start.elapsed() < Duration::from_secs(60), "never locked");
        std::thread::sleep(Duration::from_millis(10));
    }
    let pid = first.id().to_string();
    let second = || {
        maaf(&[
            "generate",
            "--out",
            s(&out),
            "--size",
            "16",
            "--frames",
            "2",
        ])
    };
    let line = refused(second(), &["is being generated (maaf generate, pid", &pid]);
    assert_eq!(line.matches("is being generated").count(), 1, "{line}");
    assert!(first.wait().expect("wait").success());
    refused(second(), &["already exists"]);
    let train = std::fs::read_to_string(out.join("transforms_train.json")).expect("json");
    assert_eq!(
        train.matches("\"file_path\"").count(),
        40,
        "the first scene's"
    );
    assert!(!out.join("run.lock").exists());
}

#[test]
fn a_killed_export_video_or_generation_leaves_nothing_the_next_one_keeps() {
    let fx = fixture("litter_temps");
    let run = fx.trained("run");
    let (video, plys, zip, scene) = (
        fx.root.join("video"),
        fx.root.join("plys"),
        fx.root.join("plys.zip"),
        fx.root.join("scene"),
    );
    let video_args = [
        "render-video",
        "--run",
        s(&run),
        "--view",
        "test:0",
        "--frames",
        "4",
        "--out",
        s(&video),
    ];
    let plys_args = [
        "export-ply",
        "--run",
        s(&run),
        "--frames",
        "4",
        "--out",
        s(&plys),
    ];
    let zip_args = [
        "export-ply",
        "--run",
        s(&run),
        "--frames",
        "4",
        "--out",
        s(&zip),
    ];
    let scene_args = [
        "generate",
        "--out",
        s(&scene),
        "--size",
        "16",
        "--frames",
        "2",
    ];
    for args in [&video_args[..], &plys_args, &zip_args, &scene_args] {
        killed_at(3, args);
    }
    assert_eq!(
        temporaries(&fx.root).len(),
        4,
        "{:?}",
        temporaries(&fx.root)
    );
    for args in [&video_args[..], &plys_args, &zip_args, &scene_args] {
        succeeded(maaf(args));
    }
    assert_eq!(temporaries(&fx.root), Vec::<String>::new());
}

#[test]
fn cameras_into_an_earlier_camera_folder_replaces_it_whole() {
    let fx = fixture("litter_cameras");
    let out = fx.root.join("cams");
    succeeded(maaf(&["cameras", "--data", s(&fx.data), "--out", s(&out)]));
    let count = || std::fs::read_dir(&out).expect("ls").count();
    assert_eq!(count(), 21, "20 test cameras and the listing");
    succeeded(maaf(&[
        "cameras",
        "--data",
        s(&fx.data),
        "--split",
        "val",
        "--out",
        s(&out),
    ]));
    assert_eq!(
        count(),
        11,
        "10 val cameras and the listing, no stale test camera"
    );
    std::fs::write(out.join("notes.txt"), b"mine").expect("write");
    refused(
        maaf(&["cameras", "--data", s(&fx.data), "--out", s(&out)]),
        &["notes.txt", "not a camera file"],
    );
}

#[test]
fn a_refused_train_branch_or_eval_leaves_no_folder_or_lock_of_its_own() {
    let fx = fixture("litter_refused");
    let run = fx.trained("run");
    // Refused inside the trainer, after the run folder was locked.
    let new = fx.root.join("new");
    refused(
        fx.train("new", r#""model": {"kind": "nope"}"#),
        &["`nope` is not registered"],
    );
    assert!(!new.exists(), "a refused train leaves no folder");
    let moved = fx.moved_copy();
    let branch = fx.root.join("branch");
    refused(
        maaf(&[
            "train",
            "--data",
            s(&moved),
            "--out",
            s(&branch),
            "--from",
            s(&run.join("model")),
            "--iters",
            "8",
        ]),
        &["is not the data set the run"],
    );
    assert!(!branch.exists(), "a refused branch leaves no folder");
    // An evaluation of a checkpoint folder (not a run) puts no lock into it.
    let checkpoint = std::fs::read_dir(run.join("checkpoints"))
        .expect("ls")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.join("state.json").is_file())
        .expect("a checkpoint");
    refused(
        maaf(&["eval", "--run", s(&checkpoint), "--max-views", "1"]),
        &["no trained model", "checkpoint folder"],
    );
    assert!(!checkpoint.join("run.lock").exists());
    // A run killed before its model: the message says how to continue it.
    std::fs::remove_dir_all(run.join("model")).expect("rm model");
    let line = refused(
        maaf(&["eval", "--run", s(&run), "--max-views", "1"]),
        &["maaf train --resume"],
    );
    assert!(!line.contains("--out"), "{line}");
}
