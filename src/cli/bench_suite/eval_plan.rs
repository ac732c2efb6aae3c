//! The suite's evaluation, checked while planning rather than after hours of
//! training: `--eval-args` parsed exactly as `maaf eval` parses them, without the
//! options the suite gives every evaluation itself, and every scale possible on
//! every scene's split at every config's training scale; and redone, never
//! retrained, when only what evaluates changes on an existing suite.

use std::path::Path;

use anyhow::{Context, bail};
use clap::Parser;
use clap::error::ErrorKind;
use maaf_eval::eval_json::OTHER_BACKGROUND_PREFIX;
use maaf_eval::{EvalOptions, check_eval_options};
use maaf_scene::TrainConfig;
use maaf_train::data::{BLACK, Dataset, DatasetOptions};
use maaf_train::sweep::{shell_quote, split_args};

use super::super::eval::{EvalArgs, SplitArg};
use super::SuiteSpec;
use maaf_eval::report::suite::SuiteRun;

/// `maaf eval`'s arguments as a suite passes them.
#[derive(Parser)]
#[command(name = "maaf eval", no_binary_name = true)]
struct EvalLine {
    #[command(flatten)]
    args: EvalArgs,
}

/// The `maaf eval` options the suite sets for every evaluation itself: the run's
/// folder, its scene's split (`--split`), its background (`--backgrounds`,
/// `--also-eval-on`) and data (the scene, recorded in the run).
const SUITE_OWNED: [&str; 4] = ["--run", "--split", "--background", "--data"];

/// `--eval-args` split as a shell would (quotes group words; stored in `suite.json`
/// as [`words`]) with the evaluation they ask for. Refused in one line: unbalanced
/// quotes, an option the suite sets itself, one `maaf eval` does not take or a bad
/// value, and `--help` or `--version`, which would print and evaluate nothing.
pub(super) fn parse_eval_args(text: &str) -> anyhow::Result<(String, EvalOptions)> {
    let tokens = split_args(text, "--eval-args")?;
    let tokens: Vec<&str> = tokens.iter().map(String::as_str).collect();
    for word in &tokens {
        let name = word.split('=').next().unwrap_or(word);
        if SUITE_OWNED.contains(&name) {
            bail!(
                "--eval-args `{text}`: {name} is set by the suite for every evaluation (the run, its scene's split with --split, its background with --backgrounds and --also-eval-on)"
            );
        }
    }
    let line = EvalLine::try_parse_from(["--run", "RUN"].into_iter().chain(tokens.iter().copied()))
        .map_err(|e| match e.kind() {
            ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => anyhow::anyhow!(
                "--eval-args `{text}`: asks maaf eval to print its help or version, which evaluates nothing"
            ),
            _ => {
                let rendered = e.to_string();
                let first = rendered.lines().next().unwrap_or_default();
                anyhow::anyhow!(
                    "--eval-args `{text}`: {}",
                    first.trim_start_matches("error: ")
                )
            }
        })?;
    Ok((words(text), line.args.options()))
}

/// Refuses the suite when `options` could not evaluate some run: each scene of
/// `runs` is opened (black background, as the suite's runs are) and `options` checked
/// on its split at every training scale of `configs` ([`check_eval_options`]).
pub(super) fn check_scenes(
    data: &Path,
    runs: &[SuiteRun],
    configs: &[(String, TrainConfig)],
    options: &EvalOptions,
    eval_args: &str,
) -> anyhow::Result<()> {
    let mut scales: Vec<f64> = configs.iter().map(|(_, c)| c.train_scale).collect();
    scales.sort_by(f64::total_cmp);
    scales.dedup();
    let mut seen: Vec<(&str, &str)> = Vec::new();
    for run in runs {
        if seen.contains(&(run.scene.as_str(), run.split.as_str())) {
            continue;
        }
        seen.push((&run.scene, &run.split));
        let dir = data.join(&run.scene);
        let scene = Dataset::open(&dir, DatasetOptions { background: BLACK })
            .with_context(|| format!("scene {}", run.scene))?;
        let split = <SplitArg as clap::ValueEnum>::from_str(&run.split, false)
            .map_err(|_| anyhow::anyhow!("scene {}: unknown split {}", run.scene, run.split))?;
        let options = EvalOptions {
            split: split.into(),
            ..options.clone()
        };
        for &scale in &scales {
            check_eval_options(&scene, scale, &options).with_context(|| {
                format!(
                    "--eval-args `{eval_args}` cannot evaluate scene {} ({} split) trained at scale {scale}",
                    run.scene, run.split
                )
            })?;
        }
    }
    Ok(())
}

/// The runs of `new` whose evaluations the change from `old` makes stale: every run
/// when the `maaf eval` arguments changed, else those whose split changed. Refuses
/// (one line) a `new` that differs from `old` in anything that trains a run.
pub(super) fn reevaluated<'a>(
    old: &SuiteSpec,
    new: &'a SuiteSpec,
    spec_path: &Path,
) -> anyhow::Result<Vec<&'a SuiteRun>> {
    let training = |s: &SuiteSpec| SuiteSpec {
        eval_args: String::new(),
        also_eval_on: Vec::new(),
        runs: s
            .runs
            .iter()
            .map(|r| SuiteRun {
                split: String::new(),
                ..r.clone()
            })
            .collect(),
        ..s.clone()
    };
    if training(old) != training(new) {
        bail!(
            "{}: holds a suite written with other options (scenes, presets, filters, backgrounds, seeds or --iters; --eval-args, --split and --also-eval-on may change, its runs then evaluated again, never retrained); give the same options or another --out",
            spec_path.display()
        );
    }
    let args_changed = words(&old.eval_args) != new.eval_args;
    Ok(new
        .runs
        .iter()
        .zip(&old.runs)
        .filter(|(n, o)| args_changed || n.split != o.split)
        .map(|(n, _)| n)
        .collect())
}

/// `--eval-args` as `suite.json` stores it: its words (split as a shell would), each
/// quoted where it needs it, joined by one space; unbalanced quotes (refused by
/// [`parse_eval_args`]) are kept as given.
pub(super) fn words(eval_args: &str) -> String {
    match split_args(eval_args, "--eval-args") {
        Ok(words) => words
            .iter()
            .map(|w| shell_quote(w))
            .collect::<Vec<_>>()
            .join(" "),
        Err(_) => eval_args.to_string(),
    }
}

/// Removes the evaluations of the run in `dir` (`eval.json`, `eval-on-*.json`), so
/// the suite evaluates it again; returns how many there were.
pub(super) fn remove_evaluations(dir: &Path) -> anyhow::Result<usize> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(0);
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let evaluation = name == "eval.json"
            || (name.starts_with(OTHER_BACKGROUND_PREFIX) && name.ends_with(".json"));
        if evaluation {
            let path = entry.path();
            std::fs::remove_file(&path)
                .with_context(|| format!("{}: cannot remove", path.display()))?;
            removed += 1;
        }
    }
    Ok(removed)
}
