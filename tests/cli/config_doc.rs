//! `docs/config.md` documents every key the training configuration accepts, with its
//! default, for every built-in model kind: the key list and the defaults come from
//! serialising the default configurations, so the document cannot drift from the code.

use std::collections::BTreeMap;
use std::path::Path;

use maaf::scene::TrainConfig;
use maaf::train::models::ModelConfig;
use serde_json::Value;

use crate::support::{config_json, json_leaves};

/// Which table a documented key belongs to: the Deformable-3DGS or the tracking model
/// section, or any other (the top level, SaRO's model section, filter, densify, prune).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    Saro,
    Deform,
    Track,
}

/// The rows of `docs/config.md`: `| `key` | `default` | range | meaning |`, keyed by
/// (section kind, key), with the default parsed as JSON.
fn documented() -> BTreeMap<(Kind, String), Value> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/config.md");
    let text = std::fs::read_to_string(&path).expect("docs/config.md");
    let mut kind = Kind::Saro;
    let mut rows = BTreeMap::new();
    for line in text.lines() {
        if let Some(heading) = line.strip_prefix("## ") {
            kind = if heading.contains("\"deform\"") {
                Kind::Deform
            } else if heading.contains("\"track\"") {
                Kind::Track
            } else {
                Kind::Saro
            };
            continue;
        }
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 4 || !cells[1].starts_with('`') {
            continue;
        }
        let key = cells[1].trim_matches('`').to_string();
        let default = cells[2].trim_matches('`');
        let value: Value = serde_json::from_str(default)
            .unwrap_or_else(|e| panic!("docs/config.md: `{key}`: default {default}: {e}"));
        assert!(
            rows.insert((kind, key.clone()), value).is_none(),
            "docs/config.md lists `{key}` twice"
        );
    }
    rows
}

/// Every key of the default configuration with SaRO, and of the model section with
/// Deformable-3DGS and with the tracking model, with its default.
fn from_code() -> BTreeMap<(Kind, String), Value> {
    let mut keys = BTreeMap::new();
    for (key, value) in json_leaves(&config_json(&TrainConfig::default())) {
        keys.insert((Kind::Saro, key), value);
    }
    // Plug-in options are left out of the JSON while empty, as they are by default.
    for key in ["densify.options", "filter.options"] {
        keys.insert(
            (Kind::Saro, key.to_string()),
            Value::Object(Default::default()),
        );
    }
    for (kind, name) in [(Kind::Deform, "deform"), (Kind::Track, "track")] {
        let other = TrainConfig {
            model: ModelConfig::default_of(name).expect("a built-in kind"),
            ..TrainConfig::default()
        };
        for (key, value) in json_leaves(&config_json(&other)) {
            if key.starts_with("model.") {
                keys.insert((kind, key), value);
            }
        }
    }
    keys
}

/// Numbers compare by value (`10` and `10.0` are the same default).
fn same(a: &Value, b: &Value) -> bool {
    match (a.as_f64(), b.as_f64()) {
        (Some(x), Some(y)) => x == y || (x - y).abs() <= 1e-12 * x.abs().max(y.abs()),
        _ => match (a, b) {
            (Value::Array(x), Value::Array(y)) => {
                x.len() == y.len() && x.iter().zip(y).all(|(p, q)| same(p, q))
            }
            _ => a == b,
        },
    }
}

#[test]
fn config_doc_lists_every_key_with_its_default() {
    let doc = documented();
    let code = from_code();
    let mut problems = Vec::new();
    for ((kind, key), default) in &code {
        match doc.get(&(*kind, key.clone())) {
            None => problems.push(format!("missing ({kind:?}): | `{key}` | `{default}` |")),
            Some(d) if !same(d, default) => problems.push(format!(
                "default of `{key}` ({kind:?}): the doc says {d}, the code {default}"
            )),
            Some(_) => {}
        }
    }
    for (kind, key) in doc.keys() {
        if !code.contains_key(&(*kind, key.clone())) {
            problems.push(format!("documented but not a key ({kind:?}): `{key}`"));
        }
    }
    assert!(
        problems.is_empty(),
        "docs/config.md is out of date:\n{}",
        problems.join("\n")
    );
}
