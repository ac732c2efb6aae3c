//! Running a suite's runs, each as far as it is not done yet (trained, resumed or only
//! evaluated, then evaluated on the other backgrounds asked for), through child `maaf`
//! processes that end with the suite; `--job N` runs one of them.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_eval::eval_json::other_background_name;
use maaf_eval::report::suite::SuiteRun;
use maaf_train::sweep::split_args;

use super::args::SuiteBackground;
use super::plan::config_file;
use super::{SPEC_FILE, SuiteSpec, read_spec};

/// The config file of a run.
fn config_path(out: &Path, run: &SuiteRun, bg: SuiteBackground) -> PathBuf {
    out.join("configs")
        .join(config_file(&run.preset, &run.filter, bg))
}

/// `maaf train` arguments of a new run (`--seed` when the suite gives seeds).
fn train_args(spec: &SuiteSpec, out: &Path, run: &SuiteRun) -> anyhow::Result<Vec<String>> {
    let scene = spec.data.join(&run.scene);
    let bg = SuiteBackground::of_run(run)?;
    let mut args = [
        "train",
        "--data",
        &scene.display().to_string(),
        "--out",
        &run.dir.display().to_string(),
        "--config",
        &config_path(out, run, bg).display().to_string(),
        "--background",
        bg.data(),
    ]
    .map(String::from)
    .to_vec();
    if let Some(seed) = run.seed {
        args.extend(["--seed".to_string(), seed.to_string()]);
    }
    Ok(args)
}

/// `maaf eval` arguments of a run, on `background` when it is another than the run's.
fn eval_args(
    spec: &SuiteSpec,
    run: &SuiteRun,
    background: Option<&str>,
) -> anyhow::Result<Vec<String>> {
    let mut v: Vec<String> = ["eval", "--run", &run.dir.display().to_string()]
        .map(String::from)
        .to_vec();
    v.extend(["--split".to_string(), run.split.clone()]);
    if let Some(bg) = background {
        v.extend(["--background".to_string(), bg.to_string()]);
    }
    v.extend(split_args(&spec.eval_args, "--eval-args")?);
    Ok(v)
}

/// The `--also-eval-on` backgrounds of a run still to be evaluated on: not the run's
/// own data background, and without `RUN/eval-on-NAME.json` yet.
fn other_evaluations<'a>(spec: &'a SuiteSpec, run: &SuiteRun) -> anyhow::Result<Vec<&'a str>> {
    let own = SuiteBackground::of_run(run)?.data();
    Ok(spec
        .also_eval_on
        .iter()
        .map(String::as_str)
        .filter(|&bg| bg != own)
        .filter(|bg| {
            !run.dir
                .join(format!("{}.json", other_background_name(bg)))
                .is_file()
        })
        .collect())
}

/// Runs `exe args`, inheriting the terminal, as a child that ends with this process
/// ([`maaf_io::process::child_command`]: a suite killed, even by `kill -9`, leaves
/// no training or evaluation running); an error names the command.
fn spawn(exe: &Path, args: &[String]) -> anyhow::Result<()> {
    let status = maaf_io::process::child_command(exe)
        .args(args)
        .status()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    if !status.success() {
        bail!("maaf {} exited with {status}", args.join(" "));
    }
    Ok(())
}

/// Trains (or resumes) and evaluates one run, as far as it is not done yet.
pub(super) fn run_one(
    spec: &SuiteSpec,
    out: &Path,
    exe: &Path,
    run: &SuiteRun,
) -> anyhow::Result<String> {
    let others = other_evaluations(spec, run)?;
    let evaluated = run.dir.join("eval.json").is_file();
    let mut what = if evaluated {
        if others.is_empty() {
            return Ok("skipped (evaluated)".into());
        }
        "was evaluated"
    } else if run.dir.join("summary.json").is_file() {
        "evaluated"
    } else if run.dir.join("config.json").is_file() {
        let dir = run.dir.display().to_string();
        spawn(exe, &["train".into(), "--resume".into(), dir])?;
        "resumed and evaluated"
    } else {
        spawn(exe, &train_args(spec, out, run)?)?;
        "trained and evaluated"
    }
    .to_string();
    if !evaluated {
        evaluate(exe, spec, run, None)?;
    }
    for bg in &others {
        evaluate(exe, spec, run, Some(bg))?;
    }
    if !others.is_empty() {
        let _ = write!(what, ", also on {}", others.join(", "));
    }
    Ok(what)
}

/// Evaluates `run` (on `background` when it is another than the run's) and checks
/// that the evaluation wrote its file: `maaf eval` exiting 0 without it (arguments
/// that printed something else) is a failed evaluation, not a done one.
fn evaluate(
    exe: &Path,
    spec: &SuiteSpec,
    run: &SuiteRun,
    background: Option<&str>,
) -> anyhow::Result<()> {
    let args = eval_args(spec, run, background)?;
    spawn(exe, &args)?;
    let name = background.map_or_else(|| "eval".to_string(), other_background_name);
    let file = run.dir.join(format!("{name}.json"));
    if !file.is_file() {
        bail!(
            "maaf {} exited 0 but wrote no {}",
            args.join(" "),
            file.display()
        );
    }
    Ok(())
}

/// `scene method` of a run, with its seed when the suite gives seeds.
pub(super) fn run_name(r: &SuiteRun) -> String {
    match r.seed {
        Some(seed) => format!("{} {} / seed {seed}", r.scene, r.method()),
        None => format!("{} {}", r.scene, r.method()),
    }
}

/// `[N/M] scene method`: how the suite's output names run `i` (0-based).
pub(super) fn label(spec: &SuiteSpec, i: usize) -> String {
    format!(
        "[{}/{}] {}",
        i + 1,
        spec.runs.len(),
        run_name(&spec.runs[i])
    )
}

/// The running `maaf` executable, which spawns the runs' commands.
pub(super) fn maaf_exe() -> anyhow::Result<PathBuf> {
    std::env::current_exe().context("cannot locate the maaf executable")
}

/// `--job n`: run `n` (1-based) of the suite written in `out`, by [`run_one`]'s rule.
pub(super) fn run_job(out: &Path, n: usize) -> anyhow::Result<()> {
    let spec = read_spec(out)?;
    spec.refuse_record(out)?;
    let i = n
        .checked_sub(1)
        .filter(|&i| i < spec.runs.len())
        .ok_or_else(|| {
            anyhow::anyhow!(
                "--job {n}: {} holds jobs 1..={}",
                out.join(SPEC_FILE).display(),
                spec.runs.len()
            )
        })?;
    let what = run_one(&spec, out, &maaf_exe()?, &spec.runs[i])?;
    println!("{}: {what}", label(&spec, i));
    Ok(())
}
