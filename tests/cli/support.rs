//! What the CLI tests share: a self-removing scratch folder, paths as arguments, and
//! the tiny built-in scene most of them train on.

use std::path::{Path, PathBuf};
use std::process::Command;

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
/// anything else (numbers, strings, booleans, null, arrays) is a leaf.
pub fn json_leaves(value: &serde_json::Value) -> Vec<(String, serde_json::Value)> {
    fn walk(v: &serde_json::Value, prefix: &str, out: &mut Vec<(String, serde_json::Value)>) {
        match v {
            serde_json::Value::Object(map) => {
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
pub fn config_json(config: &maaf::train::trainer::TrainConfig) -> serde_json::Value {
    let text = serde_json::to_string(config).expect("serialise");
    serde_json::from_str(&text).expect("parse back")
}
