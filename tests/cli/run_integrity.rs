//! A run directory nobody can corrupt, as a user meets it on
//! the command line, each with its exit code and one-line message: a run remembers its
//! data set, one trainer per run folder, memory checked before a user-sized
//! allocation, degenerate cameras and non-finite output, typos under `model`, resume
//! settings that cannot be honoured, damaged checkpoints (these two in
//! `run_integrity/resume.rs`), and the smaller items.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::support::{BASE, copy_dir, fixture, maaf, refused, s, succeeded};

mod resume;

fn checkpoint_names(run: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(run.join("checkpoints"))
        .expect("ls")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn case_1_a_run_remembers_its_data_set_and_refuses_another() {
    let fx = fixture("integrity_data");
    let run = fx.trained("run");
    let recorded = std::fs::read_to_string(run.join("data.json")).expect("data.json");
    assert!(recorded.contains("\"frames\""), "{recorded}");
    // Fewer training views, and the same count with one camera moved.
    let fewer = fx.edited_copy("fewer", "train", |v| {
        v["frames"].as_array_mut().expect("frames").pop();
    });
    let moved = fx.moved_copy();
    let model = std::fs::read(run.join("model/state.json")).expect("model");
    let checkpoints = checkpoint_names(&run);
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
            &[
                "is not the data set the run",
                other.file_name().and_then(|n| n.to_str()).expect("name"),
                s(&std::fs::canonicalize(&fx.data).expect("canonical")),
            ],
        );
    }
    assert_eq!(
        std::fs::read(run.join("model/state.json")).expect("model"),
        model
    );
    assert_eq!(checkpoint_names(&run), checkpoints);
    // No --data: the run's own data set.
    let err = succeeded(maaf(&["train", "--resume", s(&run), "--iters", "8"]));
    assert!(err.contains("resuming from"), "{err}");
    // The same frames in another folder are the same data set (recorded at its new place).
    let copy = fx.root.join("copy");
    copy_dir(&fx.data, &copy);
    succeeded(maaf(&[
        "train",
        "--resume",
        s(&run),
        "--data",
        s(&copy),
        "--iters",
        "10",
    ]));
    let recorded = std::fs::read_to_string(run.join("data.json")).expect("data.json");
    assert!(
        recorded.contains(s(&std::fs::canonicalize(&copy).expect("c"))),
        "{recorded}"
    );
    // A run of an older version: data.json without a fingerprint is checked by view
    // count and size, and gains the fingerprint on resume.
    let mut old: serde_json::Value = serde_json::from_str(&recorded).expect("json");
    old.as_object_mut().expect("object").remove("frames");
    std::fs::write(run.join("data.json"), old.to_string()).expect("write");
    refused(
        maaf(&[
            "train",
            "--resume",
            s(&run),
            "--data",
            s(&fewer),
            "--iters",
            "12",
        ]),
        &["it has 3 training views of 64x64, the run's has 4"],
    );
    succeeded(maaf(&["train", "--resume", s(&run), "--iters", "12"]));
    let upgraded = std::fs::read_to_string(run.join("data.json")).expect("data.json");
    assert!(upgraded.contains("\"frames\""), "{upgraded}");
    // Without data.json at all, --data is needed.
    std::fs::remove_file(run.join("data.json")).expect("rm");
    refused(
        maaf(&["train", "--resume", s(&run), "--iters", "14"]),
        &["records no data set", "pass --data DIR"],
    );
}

#[test]
fn case_2_one_trainer_per_run_and_no_reader_while_it_trains() {
    let fx = fixture("integrity_lock");
    let run = fx.trained("run");
    // A long resumed training holds the run until it is killed.
    let mut first = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args(["train", "--resume", s(&run), "--iters", "100000000"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let lock = run.join("run.lock");
    let start = Instant::now();
    while std::fs::read_to_string(&lock)
        .unwrap_or_default()
        .is_empty()
    {
        assert!(start.elapsed() < Duration::from_secs(60), "never locked");
        std::thread::sleep(Duration::from_millis(20));
    }
    let pid = first.id().to_string();
    refused(
        maaf(&["train", "--resume", s(&run), "--iters", "100"]),
        &["is being trained (maaf train, pid", &pid],
    );
    refused(
        fx.train("run", ""),
        &["is being trained (maaf train, pid", &pid],
    );
    refused(
        maaf(&["eval", "--run", s(&run), "--max-views", "1"]),
        &["is being trained"],
    );
    let png = fx.root.join("x.png");
    refused(
        maaf(&[
            "render",
            "--run",
            s(&run),
            "--view",
            "test:0",
            "--out",
            s(&png),
        ]),
        &["is being trained"],
    );
    let ply = fx.root.join("x.ply");
    refused(
        maaf(&[
            "export-ply",
            "--run",
            s(&run),
            "--time",
            "0.5",
            "--out",
            s(&ply),
        ]),
        &["is being trained"],
    );
    assert!(!png.exists() && !ply.exists());
    // A kill -9 leaves no stale lock: the next training trains (two iterations past
    // the newest checkpoint the killed one wrote).
    first.kill().expect("kill");
    first.wait().expect("wait");
    let newest = checkpoint_names(&run)
        .iter()
        .filter_map(|n| n.strip_prefix("iter_")?.parse::<usize>().ok())
        .max()
        .unwrap_or(0)
        .max(6);
    let iters = (newest + 2).to_string();
    succeeded(maaf(&["train", "--resume", s(&run), "--iters", &iters]));
    // Readers share the run: an export while nothing trains works.
    succeeded(maaf(&[
        "export-ply",
        "--run",
        s(&run),
        "--time",
        "0.5",
        "--out",
        s(&ply),
    ]));
}

#[test]
fn case_3_a_size_the_machine_cannot_hold_is_refused_before_allocating() {
    let fx = fixture("integrity_memory");
    let run = fx.trained("run");
    refused(
        maaf(&["bench", "--run", s(&run), "--gaussians", "999999999999"]),
        &[
            "a training step of 999999999999 Gaussians needs about",
            "GB of memory but",
            "is available (MemAvailable",
        ],
    );
}

#[test]
// 3.14159265 is just under pi: a field of view whose focal length is 1e-8 px.
#[allow(clippy::approx_constant)]
fn case_4_degenerate_cameras_and_non_finite_output_fail() {
    let fx = fixture("integrity_camera");
    let fov = fx.edited_copy("fov", "train", |v| {
        v["camera_angle_x"] = serde_json::json!(3.14159265);
    });
    let far = fx.edited_copy("far", "train", |v| {
        v["frames"][1]["transform_matrix"][0][3] = serde_json::json!(1e30);
    });
    let run = fx.root.join("r");
    for (data, needle) in [
        (
            &fov,
            "field `camera_angle_x`: 3.14159265 is not a field of view in (0, 3.124139) radians",
        ),
        (
            &far,
            "translation of length 1.000e30 is beyond 1e6 world units",
        ),
    ] {
        refused(
            maaf(&["train", "--data", s(data), "--out", s(&run)]),
            &[needle],
        );
        assert!(!run.exists(), "refused before any work");
    }
    // A test camera whose focal length is finite but overflows the renderer's f32
    // renders NaN: the test PSNR is NaN, the run failed and summary.json says so.
    let narrow = fx.edited_copy("narrow", "test", |v| {
        v["camera_angle_x"] = serde_json::json!(1e-30);
    });
    let config = fx.root.join("c.json");
    std::fs::write(&config, format!("{{{BASE}}}")).expect("config");
    let nan = fx.root.join("nan");
    let args = [
        "train",
        "--data",
        s(&narrow),
        "--out",
        s(&nan),
        "--config",
        s(&config),
    ];
    refused(maaf(&args), &["the test PSNR is NaN dB", "the run failed"]);
    let summary = std::fs::read_to_string(nan.join("summary.json")).expect("summary");
    assert!(
        summary.contains("\"failure\"") && summary.contains("the run failed"),
        "{summary}"
    );
    // Render refuses a NaN image instead of writing a black PNG; a camera file with a
    // field of view of 180 degrees or more is refused.
    let png = fx.root.join("x.png");
    let render = |cam: &str| {
        let path = fx.root.join("cam.json");
        std::fs::write(&path, cam).expect("cam");
        maaf(&[
            "render",
            "--run",
            s(&nan),
            "--camera",
            s(&path),
            "--out",
            s(&png),
        ])
    };
    let pose = r#""world_to_camera":[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]"#;
    refused(
        render(&format!(
            r#"{{"width":32,"height":32,"fx":1e30,"fy":1e30,"cx":16,"cy":16,{pose}}}"#
        )),
        &["the render has a non-finite value (NaN)", "nothing written"],
    );
    refused(
        render(&format!(
            r#"{{"width":32,"height":32,"fx":0.01,"fy":0.01,"cx":16,"cy":16,{pose}}}"#
        )),
        &[
            "field `fx`: 0.01 px gives a field of view of 179.9",
            "less than 179",
        ],
    );
    assert!(!png.exists());
    // Export refuses non-finite Gaussians (a model made degenerate in memory: a
    // saved one with a NaN parameter is already refused on load).
    let registry = maaf::scene::ModelRegistry::builtin();
    let mut t = maaf::scene::TrainedScene::load(&nan, &registry).expect("model");
    let p = t.model.params_mut().iter_mut().next().expect("a parameter");
    p.value.data_mut()[0] = f32::NAN;
    let ply = fx.root.join("x.ply");
    let err = maaf::eval::export::export_frame(&t, 0.5, &ply).expect_err("NaN");
    assert!(err.to_string().contains("nothing written"), "{err}");
    assert!(!ply.exists());
}

#[test]
fn case_5_typos_under_model_and_a_config_that_is_not_an_object_are_refused() {
    let fx = fixture("integrity_typos");
    refused(
        fx.train("a", r#""model": {"lr": {"feture": 0.1}}"#),
        &["invalid training config", "unknown field `feture`"],
    );
    refused(
        fx.train("b", r#""model": {"shdegree": 1}"#),
        &["invalid training config", "unknown field `shdegree`"],
    );
    refused(
        fx.train("c", r#""model": {"kind": "deform", "lr": {"deform": 1}}"#),
        &["unknown field `deform`"],
    );
    let list = fx.root.join("list.json");
    std::fs::write(&list, "[1,2,3]").expect("config");
    let run = fx.root.join("d");
    refused(
        maaf(&[
            "train",
            "--data",
            s(&fx.data),
            "--out",
            s(&run),
            "--config",
            s(&list),
        ]),
        &["expected a JSON object", "got an array"],
    );
    for run in ["a", "b", "c", "d"] {
        assert!(!fx.root.join(run).exists(), "refused before any work");
    }
}

#[test]
fn case_8_the_smaller_items() {
    let fx = fixture("integrity_small");
    let run = fx.trained("run");
    // summary.json and the last line of training count the Gaussians without a
    // gradient since the last opacity reset.
    let out = fx.train(
        "reset",
        r#""densify": {"from": 2, "until": 5, "every": 2, "opacity_reset_every": 4}"#,
    );
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    succeeded(out);
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fx.root.join("reset/summary.json")).expect("summary"),
    )
    .expect("json");
    assert_eq!(summary["last_reset"], 4, "{summary}");
    let count = |k: &str| summary[k].as_u64().expect(k);
    let (n, dead, cap) = (
        count("num_gaussians"),
        count("dead_gaussians"),
        count("dead_at_cap"),
    );
    assert!(cap <= dead && dead <= n, "{summary}");
    let line =
        format!("({dead} without a gradient since the reset at 4, {cap} of them at its cap)");
    assert!(stdout.contains(&line), "`{line}` not in: {stdout}");
    // A killed evaluation's temporaries are swept by the next one.
    let leftover = run.join(".eval.maaf-tmp-999999");
    std::fs::create_dir_all(leftover.join("1x")).expect("leftover");
    succeeded(maaf(&[
        "eval",
        "--run",
        s(&run),
        "--max-views",
        "1",
        "--scales",
        "1",
    ]));
    assert!(!leftover.exists());
    // An export outside the data's time range says so.
    let ply = fx.root.join("t5.ply");
    let err = succeeded(maaf(&[
        "export-ply",
        "--run",
        s(&run),
        "--time",
        "5",
        "--out",
        s(&ply),
    ]));
    assert!(
        err.contains("--time 5 is outside the data's time range [0, 1]"),
        "{err}"
    );
    // Test images at another size than the training images are refused.
    let half = fx.root.join("half");
    let out = maaf(&[
        "generate",
        "--out",
        s(&half),
        "--size",
        "32",
        "--frames",
        "4",
        "--samples",
        "1",
    ]);
    succeeded(out);
    let mixed = fx.root.join("mixed");
    copy_dir(&fx.data, &mixed);
    std::fs::remove_dir_all(mixed.join("test")).expect("rm test");
    copy_dir(&half.join("test"), &mixed.join("test"));
    std::fs::copy(
        half.join("transforms_test.json"),
        mixed.join("transforms_test.json"),
    )
    .expect("copy");
    refused(
        maaf(&["inspect", "--data", s(&mixed)]),
        &[
            "transforms_test.json",
            "its images are 32x32 but the training images are 64x64",
        ],
    );
    // --scales shows its default as it is typed.
    let help = maaf(&["eval", "--help"]);
    assert!(
        String::from_utf8_lossy(&help.stdout).contains("[default: 0.25,0.5,1,2,4]"),
        "{}",
        String::from_utf8_lossy(&help.stdout)
    );
    // info reports the thread pool the commands run on.
    let info = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .arg("info")
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .expect("info");
    assert!(String::from_utf8_lossy(&info.stdout).contains("threads: 1"));
    // demo --iters 0 is refused before the scene is generated.
    let demo = fx.root.join("demo");
    refused(
        maaf(&["demo", "--iters", "0", "--out", s(&demo)]),
        &["iterations = 0: must be an integer in 1..=100000000"],
    );
    assert!(!demo.exists());
}
