//! The suite's evaluation, checked while planning rather than after hours of
//! training: `--eval-args` parsed exactly as `maaf eval` parses them, without the
//! options the suite gives every evaluation itself, and every scale possible on
//! every scene's split at every config's training scale.

use std::path::Path;

use anyhow::{Context, bail};
use clap::Parser;
use clap::error::ErrorKind;
use maaf_eval::{EvalOptions, check_eval_options};
use maaf_scene::TrainConfig;
use maaf_train::data::{BLACK, Dataset, DatasetOptions};

use super::super::eval::{EvalArgs, SplitArg};
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

/// `--eval-args` split at spaces (one space between words, as stored in
/// `suite.json`) with the evaluation they ask for. Refused in one line: an option
/// the suite sets itself, one `maaf eval` does not take or a bad value, and `--help`
/// or `--version`, which would print and evaluate nothing.
pub(super) fn parse_eval_args(text: &str) -> anyhow::Result<(String, EvalOptions)> {
    let words: Vec<&str> = text.split_whitespace().collect();
    for word in &words {
        let name = word.split('=').next().unwrap_or(word);
        if SUITE_OWNED.contains(&name) {
            bail!(
                "--eval-args `{text}`: {name} is set by the suite for every evaluation (the run, its scene's split with --split, its background with --backgrounds and --also-eval-on)"
            );
        }
    }
    let line = EvalLine::try_parse_from(["--run", "RUN"].into_iter().chain(words.iter().copied()))
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
    Ok((words.join(" "), line.args.options()))
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
