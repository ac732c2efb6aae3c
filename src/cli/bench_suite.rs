//! `maaf bench-suite`: the D-NeRF protocol over a folder of scenes. Every scene x preset
//! x filter x background (x seed, with `--seeds`) is one run (train with the preset,
//! then `maaf eval` at 1/4x..4x on the scene's evaluation split), written as a job list
//! like `maaf sweep` (`jobs.txt`, one `maaf bench-suite --out OUT --job N` line per run,
//! so scenes can run on several machines and a line run again resumes its run) and,
//! without `--jobs-only`, run here one at a time, skipping evaluated runs and resuming
//! interrupted ones. Then one report ([`maaf_eval::report::suite`]): the paper's Tab. 2
//! layout with the published rows beside maaf's. `--record` keeps the measurements of
//! a suite without its run folders ([`record`]).
//!
//! This file holds the command's order and `suite.json` ([`SuiteSpec`]); the arguments
//! are [`args`], planning a suite [`plan`] (its evaluations checked up front in
//! [`eval_plan`]), and running its runs [`runs`].

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_eval::report::suite::{SuiteRun, write_suite_report};
use maaf_scene::{TrainConfig, write_atomic};
use maaf_train::Plugins;
use maaf_train::sweep::shell_quote;
use serde::{Deserialize, Serialize};

mod args;
mod eval_plan;
mod plan;
mod record;
mod runs;

pub use args::BenchSuiteArgs;
use runs::{label, maaf_exe, run_job, run_name, run_one};

/// `OUT/suite.json`: what a suite was written with, so that a second invocation
/// continues the same suite and `--report-only` finds its runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct SuiteSpec {
    /// Scenes folder.
    data: PathBuf,
    /// Resolved configuration of every preset x filter, by config file name.
    configs: Vec<(String, TrainConfig)>,
    /// Extra `maaf eval` arguments.
    eval_args: String,
    /// Backgrounds every run is also evaluated on (`white`, `black`); absent from a
    /// suite written without them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    also_eval_on: Vec<String>,
    /// Every run, in job order (in a record, by scene, their folders relative to it).
    runs: Vec<SuiteRun>,
    /// A record of measurements (`--record`): reported, never trained or evaluated;
    /// absent from a suite.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    record: bool,
}

impl SuiteSpec {
    /// The runs with their folders resolved against the suite folder `out` (a
    /// record's are relative to it; a suite's are absolute already).
    fn runs_in(&self, out: &Path) -> Vec<SuiteRun> {
        self.runs
            .iter()
            .map(|r| SuiteRun {
                dir: out.join(&r.dir),
                ..r.clone()
            })
            .collect()
    }

    /// An error when this is a record: its runs are not trained or evaluated.
    fn refuse_record(&self, out: &Path) -> anyhow::Result<()> {
        if self.record {
            bail!(
                "{}: a record of measurements (`--record`), whose runs cannot be trained or evaluated; run them in the suite folder they were recorded from, or report it with --report-only",
                out.join(SPEC_FILE).display()
            );
        }
        Ok(())
    }
}

const SPEC_FILE: &str = "suite.json";

/// Writes `suite.json` (or checks that the one there is this suite), the configs and
/// `jobs.txt`. A suite there that differs only in how its runs are evaluated
/// (`--eval-args`, `--split`, `--also-eval-on`) is this suite evaluated otherwise: its
/// trained runs are kept, the evaluations the change makes stale are removed (so the
/// suite does them again), and the new plan replaces the old.
fn write_suite(spec: &SuiteSpec, out: &Path, exe: &Path) -> anyhow::Result<()> {
    let spec_path = out.join(SPEC_FILE);
    if spec_path.is_file() {
        let old = read_spec(out)?;
        old.refuse_record(out)?;
        let mut removed = 0;
        for run in eval_plan::reevaluated(&old, spec, &spec_path)? {
            removed += eval_plan::remove_evaluations(&run.dir)?;
        }
        if removed > 0 {
            println!(
                "suite: --eval-args or --split changed: {removed} evaluations removed, to be done again (the trained runs are kept)"
            );
        }
    } else if holds_files(out)? {
        bail!(
            "{}: not empty and holds no {SPEC_FILE}; a suite is written into a new folder",
            out.display()
        );
    }
    std::fs::create_dir_all(out.join("configs"))
        .with_context(|| format!("{}: cannot create", out.display()))?;
    for (name, config) in &spec.configs {
        let json = serde_json::to_string_pretty(config)?;
        write_atomic(&out.join("configs").join(name), json.as_bytes())?;
    }
    let mut jobs = String::new();
    for (i, run) in spec.runs.iter().enumerate() {
        writeln!(
            jobs,
            "{} bench-suite --out {} --job {}   # {}",
            shell_quote(&exe.display().to_string()),
            shell_quote(&out.display().to_string()),
            i + 1,
            run_name(run)
        )?;
    }
    write_atomic(&out.join("jobs.txt"), jobs.as_bytes())?;
    write_atomic(&spec_path, serde_json::to_string_pretty(spec)?.as_bytes())?;
    Ok(())
}

/// Whether `dir` exists and is not empty: a suite or a record is only written into a
/// new folder or one holding its own `suite.json`.
fn holds_files(dir: &Path) -> anyhow::Result<bool> {
    Ok(dir.exists()
        && std::fs::read_dir(dir)
            .with_context(|| format!("{}: cannot read", dir.display()))?
            .next()
            .is_some())
}

fn read_spec(out: &Path) -> anyhow::Result<SuiteSpec> {
    let path = out.join(SPEC_FILE);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a suite", path.display()))
}

/// Runs `maaf bench-suite`.
pub fn run(args: &BenchSuiteArgs, plugins: &Plugins) -> anyhow::Result<()> {
    let out = std::path::absolute(&args.out)
        .with_context(|| format!("{}: cannot resolve", args.out.display()))?;
    if let Some(n) = args.job {
        return run_job(&out, n);
    }
    if let Some(dir) = &args.record {
        return record_suite(&out, dir);
    }
    let spec = if args.report_only {
        read_spec(&out)?
    } else {
        let spec = plan::plan(args, &out, plugins)?;
        let exe = maaf_exe()?;
        write_suite(&spec, &out, &exe)?;
        println!(
            "suite: {} runs ({} configs) in {}; jobs: {}",
            spec.runs.len(),
            spec.configs.len(),
            out.display(),
            out.join("jobs.txt").display()
        );
        if args.jobs_only {
            println!(
                "run them:  bash {0}/jobs.txt   (or one line per machine; then: maaf bench-suite --out {0} --report-only)",
                out.display()
            );
            return Ok(());
        }
        let mut failed = Vec::new();
        for (i, r) in spec.runs.iter().enumerate() {
            let label = label(&spec, i);
            match run_one(&spec, &out, &exe, r) {
                Ok(what) => println!("{label}: {what}"),
                Err(e) => {
                    eprintln!("maaf: {label}: {e:#}");
                    failed.push(format!("{} ({e:#})", r.dir.display()));
                }
            }
        }
        if !failed.is_empty() {
            let report = write_suite_report(&spec.runs, &out)?;
            bail!(
                "{} of {} runs failed (report of the others: {}): {}",
                failed.len(),
                spec.runs.len(),
                report.markdown.display(),
                failed.join("; ")
            );
        }
        spec
    };
    let report = write_suite_report(&spec.runs_in(&out), &out)?;
    print!("{}", report.table);
    println!(
        "report: {} ({})",
        report.markdown.display(),
        report.json.display()
    );
    Ok(())
}

/// `--record DIR`: [`record::record`] of the suite in `out`, then what was copied.
fn record_suite(out: &Path, dir: &Path) -> anyhow::Result<()> {
    let read = read_spec(out)?;
    let spec = SuiteSpec {
        runs: read.runs_in(out),
        ..read
    };
    let dir =
        std::path::absolute(dir).with_context(|| format!("{}: cannot resolve", dir.display()))?;
    let done = record::record(&spec, out, &dir)?;
    println!(
        "recorded {} of {} runs into {}",
        done.copied.len(),
        spec.runs.len(),
        dir.display()
    );
    for d in &done.not_evaluated {
        println!("  not evaluated yet, left out: {}", d.display());
    }
    println!(
        "its report: maaf bench-suite --out {} --report-only",
        shell_quote(&dir.display().to_string())
    );
    Ok(())
}
