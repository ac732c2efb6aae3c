//! What the CLI tests share: a self-removing scratch folder, paths as arguments, and
//! the tiny built-in scene most of them train on.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A scratch folder `maaf_{name}_{pid}` in the system temp folder, emptied on
/// creation and removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// Creates the folder (removing any leftover of an earlier run first).
    pub fn fresh(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("maaf_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf8 path")
}

/// Writes the built-in scene at 64x64, 4 frames, one sample per pixel into `data`.
pub fn tiny_scene(data: &Path) {
    let out = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args([
            "generate",
            "--out",
            s(data),
            "--size",
            "64",
            "--frames",
            "4",
        ])
        .args(["--samples", "1"])
        .output()
        .expect("run maaf");
    assert!(
        out.status.success(),
        "maaf generate failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every leaf of a JSON object as `(dotted.path, value)`: objects are walked,
/// anything else (numbers, strings, booleans, null, arrays) and an empty object (a
/// map such as `terms`, empty by default) is a leaf.
pub fn json_leaves(value: &serde_json::Value) -> Vec<(String, serde_json::Value)> {
    fn walk(v: &serde_json::Value, prefix: &str, out: &mut Vec<(String, serde_json::Value)>) {
        match v {
            serde_json::Value::Object(map) if !map.is_empty() => {
                for (k, child) in map {
                    let path = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    walk(child, &path, out);
                }
            }
            leaf => out.push((prefix.to_string(), leaf.clone())),
        }
    }
    let mut out = Vec::new();
    walk(value, "", &mut out);
    out
}

/// A training configuration as JSON text and back, so an `f32` field reads as its
/// shortest decimal (`0.2`, not `0.20000000298023224`).
pub fn config_json(config: &maaf::scene::TrainConfig) -> serde_json::Value {
    let text = serde_json::to_string(config).expect("serialise");
    serde_json::from_str(&text).expect("parse back")
}

/// `maaf ARGS`, its output captured.
pub fn maaf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args(args)
        .output()
        .expect("run maaf")
}

/// The standard error of a finished command, as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts exit code 1 and exactly one `maaf: error:` line containing every needle;
/// returns that line.
pub fn refused(out: Output, needles: &[&str]) -> String {
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "expected exit 1: {err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("maaf: error:"))
        .collect();
    assert_eq!(lines.len(), 1, "{err}");
    for needle in needles {
        assert!(lines[0].contains(needle), "`{needle}` not in: {err}");
    }
    lines[0].to_string()
}

/// Asserts success; returns the standard error.
pub fn succeeded(out: Output) -> String {
    let err = stderr(&out);
    assert!(out.status.success(), "failed: {err}");
    err
}

/// A scratch folder holding the tiny scene (`data/`), removed on drop.
pub struct Fixture {
    _tmp: TempDir,
    /// The scratch folder.
    pub root: PathBuf,
    /// The tiny scene inside it.
    pub data: PathBuf,
}

/// A [`Fixture`] named `name` (unique across the test binary).
pub fn fixture(name: &str) -> Fixture {
    let tmp = TempDir::fresh(name);
    let root = tmp.0.clone();
    let data = root.join("data");
    tiny_scene(&data);
    Fixture {
        _tmp: tmp,
        root,
        data,
    }
}

/// The short training run most cases start from.
pub const BASE: &str = r#""iterations": 6, "init_points": 200, "train_scale": 0.5, "val_every": 0, "checkpoint_every": 2"#;

impl Fixture {
    /// `maaf train --data DATA --out ROOT/RUN --config C`, C being [`BASE`] with
    /// `extra`'s top-level keys replacing its own.
    pub fn train(&self, run: &str, extra: &str) -> Output {
        let config = self.root.join(format!("{run}.json"));
        let mut merged: serde_json::Value =
            serde_json::from_str(&format!("{{{BASE}}}")).expect("base");
        let extra: serde_json::Value =
            serde_json::from_str(&format!("{{{extra}}}")).expect("extra");
        for (k, v) in extra.as_object().expect("object") {
            merged[k] = v.clone();
        }
        std::fs::write(&config, merged.to_string()).expect("config");
        let run = self.root.join(run);
        maaf(&[
            "train",
            "--data",
            s(&self.data),
            "--out",
            s(&run),
            "--config",
            s(&config),
        ])
    }

    /// A copy of the data set under `name` with `edit` applied to its `split` json.
    pub fn edited_copy(
        &self,
        name: &str,
        split: &str,
        edit: impl Fn(&mut serde_json::Value),
    ) -> PathBuf {
        let copy = self.root.join(name);
        copy_dir(&self.data, &copy);
        let json = copy.join(format!("transforms_{split}.json"));
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).expect("read")).expect("parse");
        edit(&mut v);
        std::fs::write(&json, v.to_string()).expect("write");
        copy
    }

    /// A copy of the data set with the first training camera moved: another data set
    /// with the same view count.
    pub fn moved_copy(&self) -> PathBuf {
        self.edited_copy("moved", "train", |v| {
            v["frames"][0]["transform_matrix"][0][3] = serde_json::json!(0.125);
        })
    }

    /// The path of run `run`, trained with [`BASE`] alone; the training must succeed.
    pub fn trained(&self, run: &str) -> PathBuf {
        succeeded(self.train(run, ""));
        self.root.join(run)
    }

    /// `maaf train --data DATA --resume RUN --iters ITERS`: a run of this fixture
    /// continued to a new budget.
    pub fn resume(&self, run: &Path, iters: &str) -> Output {
        maaf(&[
            "train",
            "--data",
            s(&self.data),
            "--resume",
            s(run),
            "--iters",
            iters,
        ])
    }
}

/// Copies a folder tree.
pub fn copy_dir(from: &Path, to: &Path) {
    maaf_io::copy_tree(from, to).expect("copies the folder");
}

/// A Panoptic-layout scene (`generate --rig multiview --layout dynamic3dgs`, one
/// sample per pixel) of `cameras` cameras x `frames` frames at `width` x `height` in
/// `dir`; returns what `generate` printed.
pub fn panoptic(dir: &Path, width: &str, height: &str, cameras: &str, frames: &str) -> String {
    let out = maaf(&[
        "generate",
        "--rig",
        "multiview",
        "--layout",
        "dynamic3dgs",
        "--out",
        s(dir),
        "--size",
        width,
        "--height",
        height,
        "--cameras",
        cameras,
        "--frames",
        frames,
        "--samples",
        "1",
    ]);
    let printed = String::from_utf8_lossy(&out.stdout).into_owned();
    succeeded(out);
    printed
}
