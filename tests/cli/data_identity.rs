//! Another data set does not get in: a run without `data.json` is checked against what
//! its checkpoints record, the fingerprint covers the training images' bytes, a
//! branch (`--from`) onto another data set is refused unless asked for on purpose
//! (`--other-data`), and a Panoptic test file with fewer frames than the training
//! file takes its times from the training frames.

use std::path::{Path, PathBuf};

use super::support::{copy_dir, fixture, maaf, panoptic, refused, s, succeeded};

/// Every file of a run's checkpoints and model, with its bytes.
fn checkpoint_bytes(run: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    for dir in [run.join("model"), run.join("checkpoints")] {
        let mut stack = vec![dir];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    let bytes = std::fs::read(&p).expect("read");
                    files.push((p, bytes));
                }
            }
        }
    }
    files.sort();
    files
}

#[test]
fn a_run_without_data_json_refuses_other_data_instead_of_starting_over() {
    let fx = fixture("identity_no_record");
    let run = fx.trained("run");
    std::fs::remove_file(run.join("data.json")).expect("rm");
    let before = checkpoint_bytes(&run);
    let fewer = fx.edited_copy("fewer", "train", |v| {
        v["frames"].as_array_mut().expect("frames").pop();
    });
    let moved = fx.moved_copy();
    for other in [&fewer, &moved] {
        refused(
            maaf(&[
                "train",
                "--resume",
                s(&run),
                "--data",
                s(other),
                "--iters",
                "8",
            ]),
            &["is not the data set the checkpoint", s(other)],
        );
    }
    assert_eq!(checkpoint_bytes(&run), before, "nothing of the run changed");
    assert!(!run.join("data.json").exists());
    // Its own data set, in another folder, resumes and is recorded.
    let copy = fx.root.join("copy");
    copy_dir(&fx.data, &copy);
    let err = succeeded(maaf(&[
        "train",
        "--resume",
        s(&run),
        "--data",
        s(&copy),
        "--iters",
        "8",
    ]));
    assert!(err.contains("resuming from"), "{err}");
    assert!(run.join("data.json").is_file());
}

#[test]
fn the_same_json_over_other_images_is_another_data_set() {
    let fx = fixture("identity_pixels");
    let run = fx.trained("run");
    let repainted = fx.root.join("repainted");
    copy_dir(&fx.data, &repainted);
    std::fs::copy(
        repainted.join("train/r_001.png"),
        repainted.join("train/r_000.png"),
    )
    .expect("repaint");
    refused(
        maaf(&[
            "train",
            "--resume",
            s(&run),
            "--data",
            s(&repainted),
            "--iters",
            "8",
        ]),
        &["training images differ", s(&repainted)],
    );
    refused(
        maaf(&[
            "eval",
            "--run",
            s(&run),
            "--data",
            s(&repainted),
            "--max-views",
            "1",
        ]),
        &["training images differ"],
    );
    // A data.json written before the pixels were fingerprinted gains them on resume.
    let path = run.join("data.json");
    let mut old: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
    old.as_object_mut().expect("object").remove("pixels");
    std::fs::write(&path, old.to_string()).expect("write");
    succeeded(fx.resume(&run, "8"));
    let upgraded = std::fs::read_to_string(&path).expect("read");
    assert!(upgraded.contains("\"pixels\""), "{upgraded}");
}

#[test]
fn a_branch_onto_another_data_set_needs_other_data() {
    let fx = fixture("identity_branch");
    let run = fx.trained("run");
    let moved = fx.moved_copy();
    let branch = |out: &str, extra: &[&str]| {
        let out = fx.root.join(out);
        let mut args = vec![
            "train".to_string(),
            "--data".into(),
            s(&moved).into(),
            "--out".into(),
            s(&out).into(),
            "--from".into(),
            s(&run.join("model")).into(),
            "--config".into(),
            s(&fx.root.join("run.json")).into(),
            "--iters".into(),
            "8".into(),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        maaf(&args)
    };
    refused(
        branch("b1", &[]),
        &["is not the data set the run", s(&moved), "--other-data"],
    );
    let err = succeeded(branch("b2", &["--other-data"]));
    assert!(err.contains("branching from"), "{err}");
    // Without data.json the checkpoint's own record of its cameras speaks.
    std::fs::remove_file(run.join("data.json")).expect("rm");
    refused(branch("b3", &[]), &["is not the data set the checkpoint"]);
}

#[test]
fn panoptic_test_frames_take_the_training_frames_times() {
    let t = fixture("identity_panoptic");
    let data = t.root.join("pan");
    panoptic(&data, "32", "32", "3", "5");
    // Keep the first two of the five frames in test_meta.json.
    let path = data.join("test_meta.json");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
    for key in ["k", "w2c", "fn", "cam_id"] {
        meta[key].as_array_mut().expect("table").truncate(2);
    }
    std::fs::write(&path, meta.to_string()).expect("write");
    let cams = t.root.join("cams");
    succeeded(maaf(&["cameras", "--data", s(&data), "--out", s(&cams)]));
    let listing: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cams.join("cameras.json")).expect("listing"))
            .expect("json");
    let times: Vec<f64> = listing["cameras"]
        .as_array()
        .expect("cameras")
        .iter()
        .map(|c| c["time"].as_f64().expect("time"))
        .collect();
    assert_eq!(times, [0.0, 0.25], "frames 0 and 1 of five training frames");
    // More test frames than training frames: they would have no training time.
    let train: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("train_meta.json")).expect("read"))
            .expect("json");
    let mut longer = train.clone();
    for key in ["k", "w2c", "fn", "cam_id"] {
        let first = train[key][0].clone();
        longer[key].as_array_mut().expect("table").push(first);
    }
    std::fs::write(&path, longer.to_string()).expect("write");
    refused(
        maaf(&["inspect", "--data", s(&data)]),
        &["test_meta.json", "has 6 frames but train_meta.json has 5"],
    );
}
