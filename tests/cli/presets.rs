//! The presets in `configs/`: each parses as a training configuration, uses only keys
//! the configuration has, validates, and is listed in `configs/README.md`;
//! `configs/dnerf.json` is the training default spelled out.

use std::path::{Path, PathBuf};

use maaf::scene::TrainConfig;

use crate::support::{config_json, json_leaves};

/// The repository's `configs/` folder.
fn configs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("configs")
}

/// Every `configs/*.json`, sorted by name.
fn presets() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(configs_dir())
        .expect("configs/ exists")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    files
}

/// A preset, parsed; panics with the file's name on a parse or validation error, or
/// on a key the parsed configuration does not have (the model sections accept
/// unknown keys, so a misspelt one would otherwise be dropped silently).
fn load(path: &Path) -> TrainConfig {
    let name = path.display();
    let text = std::fs::read_to_string(path).expect("read preset");
    let raw: serde_json::Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{name}: not JSON: {e}"));
    let config: TrainConfig =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{name}: not a config: {e}"));
    config
        .validate()
        .unwrap_or_else(|e| panic!("{name}: does not validate: {e}"));
    let known: Vec<String> = json_leaves(&config_json(&config))
        .into_iter()
        .map(|(k, _)| k)
        .collect();
    for (key, _) in json_leaves(&raw) {
        assert!(
            known.contains(&key),
            "{name}: `{key}` is not a configuration key"
        );
    }
    config
}

#[test]
fn every_preset_validates_and_is_listed() {
    let files = presets();
    let names: Vec<String> = files
        .iter()
        .map(|p| p.file_name().expect("name").to_string_lossy().into_owned())
        .collect();
    for needed in [
        "demo.json",
        "dnerf.json",
        "multiview.json",
        "stability.json",
        "compact.json",
    ] {
        assert!(
            names.iter().any(|n| n == needed),
            "configs/{needed} missing"
        );
    }
    let readme = std::fs::read_to_string(configs_dir().join("README.md")).expect("README");
    for (path, name) in files.iter().zip(&names) {
        load(path);
        assert!(
            readme.contains(&format!("`{name}`")),
            "configs/README.md does not describe {name}"
        );
    }
}

#[test]
fn dnerf_preset_is_the_training_default() {
    let config = load(&configs_dir().join("dnerf.json"));
    assert_eq!(config, TrainConfig::default());
}

#[test]
fn a_misspelt_model_key_is_caught() {
    let dir = crate::support::TempDir::fresh("preset_typo");
    let path = dir.0.join("typo.json");
    std::fs::write(&path, r#"{"model": {"kind": "saro", "hiden": 32}}"#).expect("write");
    let caught = std::panic::catch_unwind(|| load(&path));
    assert!(caught.is_err(), "a key the config lacks must be refused");
}
