//! How hard a method's scenes are against all eight D-NeRF scenes, by the paper's one
//! per-scene table ([`crate::report::published::per_scene_psnr`], supplementary
//! `tab:supp_zoomout`). A suite over some of the scenes averages above or below Tab. 2's
//! eight-scene figures for reasons that have nothing to do with maaf (the table has lego
//! 10 dB under the others); the difference between the subset's mean and the eight's in
//! that table says by how much, under the paper's own neighbouring protocol (trained at
//! 800x800, rendered at 1x and below).

use std::fmt::Write as _;

use serde::Serialize;

use super::MethodResult;
use crate::report::published::{PerScenePsnr, PublishedScene, scene_key};
use crate::report::scale_header;

/// One method's scenes in the paper's per-scene table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneSet {
    /// The method (`preset / filter / background`).
    pub method: String,
    /// Its evaluated scenes, each once, in the suite's order.
    pub scenes: Vec<String>,
    /// Those of `scenes` the table does not have; the means are absent then.
    pub unmatched: Vec<String>,
    /// Mean over `scenes` of the table's SpeeDe3DGS + MAAF PSNR at its scales.
    pub ours: Option<[f64; 3]>,
    /// Mean over `scenes` of the table's SpeeDe3DGS PSNR at its scales.
    pub base: Option<[f64; 3]>,
}

/// The scene set of `method` over `scenes` (repeats, such as a scene's seeds, count
/// once): the table's mean PSNR over them, when the table has every one.
pub fn scene_set(method: &str, scenes: &[&str], table: &PerScenePsnr) -> SceneSet {
    let mut names: Vec<String> = Vec::new();
    for s in scenes {
        if !names.iter().any(|n| n == s) {
            names.push((*s).to_string());
        }
    }
    let mut matched: Vec<&PublishedScene> = Vec::new();
    let mut unmatched = Vec::new();
    for n in &names {
        let key = scene_key(n);
        match table.scenes.iter().find(|r| scene_key(r.scene) == key) {
            Some(row) => matched.push(row),
            None => unmatched.push(n.clone()),
        }
    }
    let mean = |f: fn(&PublishedScene) -> [f64; 3]| {
        (unmatched.is_empty() && !matched.is_empty()).then(|| {
            std::array::from_fn(|k| {
                matched.iter().map(|r| f(r)[k]).sum::<f64>() / matched.len() as f64
            })
        })
    };
    SceneSet {
        method: method.to_string(),
        ours: mean(|r| r.ours),
        base: mean(|r| r.base),
        scenes: names,
        unmatched,
    }
}

/// The scene set of every method of `methods` with an evaluated scene.
pub fn scene_sets(methods: &[MethodResult], table: &PerScenePsnr) -> Vec<SceneSet> {
    methods
        .iter()
        .filter(|m| !m.scenes.is_empty())
        .map(|m| {
            let scenes: Vec<&str> = m.scenes.iter().map(|r| r.scene.as_str()).collect();
            scene_set(&m.method, &scenes, table)
        })
        .collect()
}

/// A markdown table: per method, the table's mean over its scenes at each scale with
/// the difference from the eight scenes' printed average in brackets (positive: easier
/// than the eight), then the eight's average; `None` when no method has a scene of
/// the table (a suite over other data).
pub fn scene_set_table(sets: &[SceneSet], table: &PerScenePsnr) -> Option<String> {
    if sets.iter().all(|s| s.unmatched.len() == s.scenes.len()) {
        return None;
    }
    let mut t = String::from("| Method | Scenes |");
    for name in ["MAAF", "SpeeDe3DGS"] {
        for &s in &table.scales {
            let _ = write!(t, " {name} {} |", scale_header(s));
        }
    }
    t.push_str("\n|---|---|");
    t.push_str(&"---:|".repeat(2 * table.scales.len()));
    t.push('\n');
    let all = [table.average.ours, table.average.base];
    for set in sets {
        let _ = write!(t, "| {} | {}", set.method, set.scenes.join(", "));
        if !set.unmatched.is_empty() {
            let _ = write!(t, " (not in the table: {})", set.unmatched.join(", "));
        }
        t.push_str(" |");
        for (means, eight) in [set.ours, set.base].iter().zip(all) {
            for k in 0..table.scales.len() {
                match means {
                    Some(m) => {
                        let _ = write!(t, " {:.2} ({:+.2}) |", m[k], m[k] - eight[k]);
                    }
                    None => t.push_str(" - |"),
                }
            }
        }
        t.push('\n');
    }
    let _ = write!(t, "| all eight (the table's average) | 8 |");
    for eight in all {
        for v in eight {
            let _ = write!(t, " {v:.2} |");
        }
    }
    t.push('\n');
    Some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::published::per_scene_psnr;

    #[test]
    fn a_subset_is_the_mean_of_its_rows_against_the_printed_average() {
        let table = per_scene_psnr();
        // Folder names, a repeated scene (two seeds) and another spelling all match.
        let set = scene_set(
            "paper / motion / black",
            &["bouncingballs", "mutant", "mutant", "Stand_Up"],
            &table,
        );
        assert_eq!(set.scenes, ["bouncingballs", "mutant", "Stand_Up"]);
        assert!(set.unmatched.is_empty());
        let ours = set.ours.expect("all three are in the table");
        let want_1x = (38.71 + 36.75 + 38.37) / 3.0;
        assert!((ours[0] - want_1x).abs() < 1e-12, "{ours:?}");
        let base = set.base.expect("all three are in the table");
        assert!((base[2] - (23.89 + 27.31 + 31.19) / 3.0).abs() < 1e-12);
        let md = scene_set_table(std::slice::from_ref(&set), &table).expect("one method");
        for cell in [
            "| paper / motion / black | bouncingballs, mutant, Stand_Up | 37.94 (+2.92) |",
            "| all eight (the table's average) | 8 | 35.02 | 35.88 | 35.87 | 35.01 |",
            "| MAAF 1x | MAAF 1/2x | MAAF 1/4x | SpeeDe3DGS 1x |",
        ] {
            assert!(md.contains(cell), "`{cell}` not in:\n{md}");
        }
        // With lego the four scenes are harder than the eight at 1x.
        let four = scene_set("m", &["bouncingballs", "lego", "mutant", "standup"], &table);
        let d = four.ours.expect("in the table")[0] - table.average.ours[0];
        assert!((d - (138.49 / 4.0 - 35.02)).abs() < 1e-9, "{d}");
    }

    #[test]
    fn a_scene_outside_the_table_leaves_the_means_out_and_is_named() {
        let table = per_scene_psnr();
        let set = scene_set("m", &["mutant", "my_scene"], &table);
        assert_eq!(set.unmatched, ["my_scene"]);
        assert_eq!((set.ours, set.base), (None, None));
        let md = scene_set_table(&[set], &table).expect("one method");
        assert!(
            md.contains("| m | mutant, my_scene (not in the table: my_scene) | - | - |"),
            "{md}"
        );
        assert_eq!(scene_set_table(&[], &table), None);
        let other = scene_set("m", &["my_scene"], &table);
        assert_eq!(
            scene_set_table(&[other], &table),
            None,
            "no scene of the table"
        );
    }
}
