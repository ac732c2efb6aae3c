//! `keep_best`: the run's model is the state with the best validation PSNR of
//! `log.csv`, the last state stays in `checkpoints/iter_N`, a resume across a budget
//! chooses exactly what an uninterrupted run does, and a data set without validation
//! views is refused (its test views would both choose and measure the model).

use std::path::Path;

use maaf_io::TempDir;
use maaf_scene::TrainConfig;
use maaf_train::data::synthetic::{
    GenerateOptions, MultiviewOptions, generate, generate_dynamic3dgs,
};
use maaf_train::data::{Dataset, DatasetOptions};
use maaf_train::trainer::{BEST_DIR, checkpoint_dir, checkpoint_iteration, train_run};

/// A 48x48 D-NeRF-layout scene of 6 training frames and 3 validation views.
fn scene(dir: &Path) -> Dataset {
    let opts = GenerateOptions {
        val_frames: 3,
        seed: 4,
        ..GenerateOptions::small(48, 6)
    };
    generate(dir, &opts, &mut |_, _| {}).expect("generates");
    Dataset::open(dir, DatasetOptions::default()).expect("opens")
}

fn config(iterations: usize) -> TrainConfig {
    let mut c = TrainConfig {
        iterations,
        train_scale: 1.0,
        init_points: 200,
        seed: 1,
        log_every: 5,
        val_every: 5,
        val_views: 3,
        checkpoint_every: 15,
        keep_best: true,
        ..TrainConfig::default()
    };
    c.densify.from = 5;
    c.densify.every = 5;
    c.densify.until = 30;
    c.densify.opacity_reset_every = 0;
    c
}

/// (iteration, val_psnr) of every validated row of `RUN/log.csv`.
fn validations(run: &Path) -> Vec<(usize, f64)> {
    let mut reader = csv::Reader::from_path(run.join("log.csv")).expect("log");
    let headers = reader.headers().expect("header").clone();
    let column = headers
        .iter()
        .position(|h| h == "val_psnr")
        .expect("column");
    reader
        .records()
        .map(|r| r.expect("row"))
        .filter(|r| !r[column].is_empty())
        .map(|r| (r[0].parse().expect("it"), r[column].parse().expect("psnr")))
        .collect()
}

fn bytes(dir: &Path) -> Vec<u8> {
    std::fs::read(dir.join("tensors.safetensors")).expect("tensors")
}

#[test]
fn the_model_is_the_state_with_the_best_validation_and_the_last_is_kept() {
    let t = TempDir::new("keep-best").expect("temp dir");
    let data = scene(&t.path().join("scene"));
    let run = t.path().join("run");
    let summary = train_run(&data, config(60), &run, false).expect("trains");

    let vals = validations(&run);
    assert_eq!(vals.len(), 12, "a validation every 5 iterations: {vals:?}");
    let best = vals
        .iter()
        .copied()
        .fold(None, |b: Option<(usize, f64)>, v| match b {
            Some(b) if b.1 >= v.1 => Some(b),
            _ => Some(v),
        })
        .expect("validations");
    let chosen = summary.chosen.expect("a chosen state");
    assert_eq!((chosen.iteration, chosen.val_psnr), best);
    assert_eq!(
        checkpoint_iteration(&run.join("model")).expect("model"),
        best.0
    );
    assert_eq!(bytes(&run.join("model")), bytes(&run.join(BEST_DIR)));
    let last = checkpoint_dir(&run, 60);
    assert_eq!(checkpoint_iteration(&last).expect("the last state"), 60);
    assert_eq!(summary.iterations, 60);
    // The test presupposes a choice other than the last state: with a best at the
    // end it would not tell the two apart.
    assert_ne!(best.0, 60, "validations {vals:?}");
    assert!(
        bytes(&run.join("model")) != bytes(&last),
        "model/ is the last state"
    );

    // Killed after its last validation, before its final save: a resume from the
    // checkpoint at 45 replays to the same choice and the same last state.
    let cut = t.path().join("cut");
    maaf_io::copy_tree(&run, &cut).expect("copies the run");
    for gone in ["model", "summary.json", "checkpoints/iter_000060"] {
        let path = cut.join(gone);
        if path.is_dir() {
            std::fs::remove_dir_all(&path).expect("rm dir");
        } else {
            std::fs::remove_file(&path).expect("rm file");
        }
    }
    let settings: TrainConfig =
        serde_json::from_slice(&std::fs::read(cut.join("config.json")).expect("config"))
            .expect("parses");
    let resumed = train_run(&data, settings, &cut, true).expect("resumed");
    assert_eq!(resumed.chosen, summary.chosen);
    assert!(
        bytes(&cut.join("model")) == bytes(&run.join("model")),
        "model/ differs"
    );
    assert!(
        bytes(&checkpoint_dir(&cut, 60)) == bytes(&last),
        "the last state differs"
    );
}

#[test]
fn keep_best_is_refused_without_validation_views_or_validations() {
    let t = TempDir::new("keep-best-refused").expect("temp dir");
    let root = t.path().join("video");
    let opts = MultiviewOptions {
        scene: "approach".into(),
        width: 48,
        height: 32,
        cameras: 4,
        frames: 3,
        samples: 1,
        seed: 3,
        force: false,
    };
    generate_dynamic3dgs(&root, &opts, &mut |_, _| {}).expect("generates");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    let err = train_run(&data, config(10), &t.path().join("run"), false)
        .expect_err("no validation views")
        .to_string();
    assert!(
        err.contains("keep_best") && err.contains("validation views"),
        "{err}"
    );

    let mut never = config(10);
    never.val_every = 0;
    let err = never.validate().expect_err("never validated").to_string();
    assert!(
        err.contains("keep_best") && err.contains("val_every"),
        "{err}"
    );
}
