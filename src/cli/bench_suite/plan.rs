//! Planning a suite from its options: the scenes of the data folder, the split each is
//! evaluated on, one resolved config per preset x filter (x the random background's
//! own), and one run per scene x preset x filter x background (x seed), every
//! evaluation checked before anything is written.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, bail};
use maaf_eval::report::suite::SuiteRun;
use maaf_filter::FilterKind;
use maaf_scene::TrainConfig;
use maaf_train::Plugins;

use super::super::train::{SettingsArgs, config_from};
use super::args::{BenchSuiteArgs, SuiteBackground};
use super::{SuiteSpec, eval_plan};

/// The scene folders of `data` (those with transforms_train.json), sorted, or the
/// `only` ones (each must be there).
fn scenes(data: &Path, only: &[String]) -> anyhow::Result<Vec<String>> {
    let entries =
        std::fs::read_dir(data).with_context(|| format!("{}: cannot read", data.display()))?;
    let mut found = Vec::new();
    for e in entries {
        let path = e
            .with_context(|| format!("{}: cannot read", data.display()))?
            .path();
        if path.join("transforms_train.json").is_file()
            && let Some(name) = path.file_name().and_then(|n| n.to_str())
        {
            found.push(name.to_string());
        }
    }
    found.sort();
    if found.is_empty() {
        bail!(
            "{}: no scene folder (a subfolder with transforms_train.json)",
            data.display()
        );
    }
    if only.is_empty() {
        return Ok(found);
    }
    for s in only {
        if !found.contains(s) {
            bail!(
                "--scenes {s}: no scene folder {s} with transforms_train.json in {}",
                data.display()
            );
        }
    }
    Ok(found.into_iter().filter(|f| only.contains(f)).collect())
}

/// The split each scene is evaluated on: `--split` overrides, else test; the split's
/// transforms file must exist.
fn split_of(data: &Path, scene: &str, overrides: &[String]) -> anyhow::Result<String> {
    let mut split = "test".to_string();
    for o in overrides {
        let Some((name, value)) = o.split_once('=') else {
            bail!("--split {o}: expected SCENE=SPLIT, e.g. lego=val");
        };
        if !["test", "val", "train"].contains(&value.trim()) {
            bail!("--split {o}: the split must be test, val or train");
        }
        if name.trim() == scene {
            split = value.trim().to_string();
        }
    }
    let file = data.join(scene).join(format!("transforms_{split}.json"));
    if !file.is_file() {
        bail!(
            "{}: missing (scene {scene} is evaluated on {split})",
            file.display()
        );
    }
    Ok(split)
}

/// The suite the options describe: configs resolved and validated, one run per scene x
/// preset x filter x background (scene-major, so a scene's lines are together).
pub(super) fn plan(
    args: &BenchSuiteArgs,
    out: &Path,
    plugins: &Plugins,
) -> anyhow::Result<SuiteSpec> {
    refuse_repeats("--scenes", &args.scenes, |s| format!("scene {s}"))?;
    refuse_repeats("--filters", &args.filters, |&f| {
        format!("filter {}", FilterKind::from(f).name())
    })?;
    refuse_repeats("--backgrounds", &args.backgrounds, |b| {
        format!("background {}", b.name())
    })?;
    refuse_repeats("--seeds", &args.seeds, |s| format!("seed {s}"))?;
    let (eval_args, eval_options) = eval_plan::parse_eval_args(&args.eval_args)?;
    let data_arg = args
        .data
        .as_deref()
        .ok_or_else(|| anyhow::anyhow!("--data DIR is required (the folder of scenes)"))?;
    let data = std::path::absolute(data_arg)
        .with_context(|| format!("{}: cannot resolve", data_arg.display()))?;
    let scene_names = scenes(&data, &args.scenes)?;
    let mut presets: Vec<(String, &Path)> = Vec::new();
    for p in &args.presets {
        let name = p
            .file_stem()
            .and_then(|n| n.to_str())
            .ok_or_else(|| anyhow::anyhow!("--preset {}: not a file name", p.display()))?;
        if presets.iter().any(|(n, _)| n == name) {
            bail!(
                "--preset {}: a preset named {name} is given twice",
                p.display()
            );
        }
        presets.push((name.to_string(), p));
    }
    let mut configs = Vec::new();
    for (name, file) in &presets {
        for &f in &args.filters {
            let settings = SettingsArgs {
                model: None,
                filter: Some(FilterKind::from(f).name().to_string()),
                train_scale: None,
                iters: args.iters,
                budget: None,
                batch: None,
                seed: None,
                config: Some(file.to_path_buf()),
                background: None,
            };
            // The preset's config, and a second one with `random_background` for the
            // random background's runs (one file per config_suffix).
            let config = config_from(&settings)?;
            plugins.check(&config, &file.display().to_string())?;
            let filter = FilterKind::from(f).name().to_string();
            let mut kinds = args.backgrounds.clone();
            kinds.sort_by_key(|b| b.config_suffix());
            kinds.dedup_by_key(|b| b.config_suffix());
            for bg in kinds {
                let config = TrainConfig {
                    random_background: config.random_background || bg == SuiteBackground::Random,
                    ..config.clone()
                };
                configs.push((config_file(name, &filter, bg), config));
            }
        }
    }
    let mut also_eval_on = Vec::new();
    for &bg in &args.also_eval_on {
        if bg == SuiteBackground::Random {
            bail!(
                "--also-eval-on random: evaluations are on white or black (a random colour per view is a training background)"
            );
        }
        if !also_eval_on.contains(&bg.name().to_string()) {
            also_eval_on.push(bg.name().to_string());
        }
    }
    let seeds: Vec<Option<u64>> = if args.seeds.is_empty() {
        vec![None]
    } else {
        args.seeds.iter().copied().map(Some).collect()
    };
    let mut runs = Vec::new();
    for scene in &scene_names {
        let split = split_of(&data, scene, &args.splits)?;
        for (preset, _) in &presets {
            for &f in &args.filters {
                for &bg in &args.backgrounds {
                    for &seed in &seeds {
                        let mut name =
                            format!("{preset}-{}-{}", FilterKind::from(f).name(), bg.name());
                        if let Some(seed) = seed {
                            let _ = write!(name, "-seed{seed}");
                        }
                        runs.push(SuiteRun {
                            scene: scene.clone(),
                            split: split.clone(),
                            preset: preset.clone(),
                            filter: FilterKind::from(f).name().to_string(),
                            background: bg.name().to_string(),
                            seed,
                            dir: out.join("runs").join(scene).join(name),
                        });
                    }
                }
            }
        }
    }
    eval_plan::check_scenes(&data, &runs, &configs, &eval_options, &eval_args)?;
    Ok(SuiteSpec {
        data,
        configs,
        eval_args,
        also_eval_on,
        runs,
        record: false,
    })
}

/// Refuses a list option naming a value twice (`--filters none,none` would plan the
/// same runs twice), naming the option and the value as `name` spells it.
fn refuse_repeats<T: PartialEq>(
    option: &str,
    values: &[T],
    name: impl Fn(&T) -> String,
) -> anyhow::Result<()> {
    for (i, v) in values.iter().enumerate() {
        if values[..i].contains(v) {
            bail!("{option}: {} is given twice", name(v));
        }
    }
    Ok(())
}

/// Name of the config file of a preset, filter and background in `OUT/configs/`.
pub(super) fn config_file(preset: &str, filter: &str, bg: SuiteBackground) -> String {
    format!("{preset}-{filter}{}.json", bg.config_suffix())
}
