//! `maaf bench-suite`: the D-NeRF protocol over a folder of scenes. Every scene x preset
//! x filter x background (x seed, with `--seeds`) is one run (train with the preset,
//! then `maaf eval` at 1/4x..4x on the scene's evaluation split), written as a job list
//! like `maaf sweep` (`jobs.txt`, one `maaf bench-suite --out OUT --job N` line per run,
//! so scenes can run on several machines and a line run again resumes its run) and,
//! without `--jobs-only`, run here one at a time, skipping evaluated runs and resuming
//! interrupted ones. Then one report ([`maaf_eval::report::suite`]): the paper's Tab. 2
//! layout with the published rows beside maaf's. `--record` keeps the measurements of
//! a suite without its run folders ([`record`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_eval::eval_json::other_background_name;
use maaf_eval::report::suite::{SuiteRun, write_suite_report};
use maaf_filter::FilterKind;
use maaf_scene::TrainConfig;
use maaf_scene::write_atomic;
use maaf_train::Plugins;
use maaf_train::sweep::{shell_quote, split_args};
use serde::{Deserialize, Serialize};

use super::train::{FilterArg, SettingsArgs, config_from};

mod eval_plan;
mod record;

/// Arguments of `maaf bench-suite`.
#[derive(clap::Args, Debug)]
pub struct BenchSuiteArgs {
    /// Suite folder: suite.json, configs/, runs/SCENE/PRESET-FILTER-BACKGROUND/,
    /// jobs.txt, report.md and report.json. Invoked again with the same options, the
    /// suite continues where it stopped.
    #[arg(long)]
    pub out: PathBuf,
    /// Folder of D-NeRF scenes: every subfolder holding transforms_train.json is a
    /// scene [default: none; required unless --report-only, --job or --record].
    #[arg(long, required_unless_present_any = ["report_only", "job", "record"])]
    pub data: Option<PathBuf>,
    /// Only these scenes (folder names, comma-separated) [default: every scene].
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Preset files (configs/*.json; repeat or comma-separate), one method each, named
    /// by the file's stem [default: none; required unless --report-only, --job or --record].
    #[arg(
        long = "preset",
        value_delimiter = ',',
        required_unless_present_any = ["report_only", "job", "record"]
    )]
    pub presets: Vec<PathBuf>,
    /// 3D filters, one run each.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "none,mip3d,motion"
    )]
    pub filters: Vec<FilterArg>,
    /// Backgrounds the RGBA images are composited on, for training and evaluation
    /// alike, one run each (black: the authors' D-NeRF runs; docs/cli.md says why it
    /// is the default); `random` trains each view on its own random colour
    /// (`random_background`) and evaluates on black.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "black")]
    pub backgrounds: Vec<SuiteBackground>,
    /// Evaluation split per scene, SCENE=SPLIT (comma-separated); every other scene is
    /// evaluated on test. Lego's test split does not match its training split, so lego
    /// is evaluated on val as Deformable-3DGS does; a scene named here but absent from
    /// --data is ignored.
    #[arg(long = "split", value_delimiter = ',', default_value = "lego=val")]
    pub splits: Vec<String>,
    /// Seeds (comma-separated), one run each per scene x preset x filter x background,
    /// so that the report can say how far two runs differ by chance (its seeds table)
    /// and average each scene over its seeds; the run folders end in `-seedN`
    /// [default: the preset's seed, one run each].
    #[arg(long, value_delimiter = ',')]
    pub seeds: Vec<u64>,
    /// Iterations of every run (quick checks) [default: each preset's].
    #[arg(long)]
    pub iters: Option<usize>,
    /// Extra arguments of `maaf eval` for every run, as one string split as a shell
    /// would (quotes group words).
    #[arg(long, default_value = "--no-images", allow_hyphen_values = true)]
    pub eval_args: String,
    /// Also evaluate every run on these backgrounds (`white` and/or `black`), after its
    /// own evaluation: `RUN/eval-on-NAME.json`, which the report tabulates beside the
    /// run's own PSNR (a model trained on black shows its black floaters on white); a
    /// run's own background is left out [default: none].
    #[arg(long, value_enum, value_delimiter = ',')]
    pub also_eval_on: Vec<SuiteBackground>,
    /// Write the run folders' configs and jobs.txt and stop (run the lines anywhere,
    /// then `maaf bench-suite --out OUT --report-only`).
    #[arg(long)]
    pub jobs_only: bool,
    /// Only write the report from the runs evaluated so far (reads OUT/suite.json;
    /// the options that plan a suite are refused with it).
    #[arg(long, conflicts_with_all = PLANNING)]
    pub report_only: bool,
    /// Only run job N of the suite written in --out (1-based, the line number in
    /// jobs.txt), as the whole suite would: skipped when evaluated, resumed from its
    /// newest checkpoint when interrupted, else trained; then evaluated. Reads
    /// OUT/suite.json (the options that plan a suite are refused with it); no report
    /// is written (`--report-only` does that) [default: every job].
    #[arg(long, conflicts_with_all = PLANNING, conflicts_with = "report_only")]
    pub job: Option<usize>,
    /// Copy the measurements of the suite in --out (suite.json and each evaluated
    /// run's eval.json, summary.json and eval-on-*.json, a few kB per run) into DIR, a
    /// record that `--report-only --out DIR` reports without the run folders; into an
    /// earlier record, the runs are added to it (docs/cli.md). Reads OUT/suite.json
    /// (the options that plan a suite are refused with it) [default: none].
    #[arg(long, value_name = "DIR", conflicts_with_all = PLANNING, conflicts_with_all = ["report_only", "job"])]
    pub record: Option<PathBuf>,
}

/// The options that plan a suite: `--job` and `--report-only` read the plan from
/// OUT/suite.json, so these given with them would be ignored; clap refuses them.
const PLANNING: [&str; 11] = [
    "jobs_only",
    "data",
    "scenes",
    "presets",
    "filters",
    "backgrounds",
    "splits",
    "seeds",
    "iters",
    "eval_args",
    "also_eval_on",
];

/// `--backgrounds` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SuiteBackground {
    /// White (D-NeRF's `white_bkgd`, maaf's default elsewhere).
    White,
    /// Black (SaRO-GS's and the MAAF authors' D-NeRF runs).
    Black,
    /// A random colour per training view, the ground truth composited on the same
    /// (config key `random_background`); the data set is opened on black, so the run
    /// is evaluated on black like the others and compares with Tab. 2.
    Random,
}

impl SuiteBackground {
    /// The run's label in folder names and the report.
    fn name(self) -> &'static str {
        match self {
            SuiteBackground::White => "white",
            SuiteBackground::Black => "black",
            SuiteBackground::Random => "random",
        }
    }

    /// The `--background` of `maaf train` (the data set's background).
    fn data(self) -> &'static str {
        match self {
            SuiteBackground::White => "white",
            SuiteBackground::Black | SuiteBackground::Random => "black",
        }
    }

    /// The background a run's label names.
    fn of_run(run: &SuiteRun) -> anyhow::Result<Self> {
        <Self as clap::ValueEnum>::from_str(&run.background, false)
            .map_err(|_| anyhow::anyhow!("suite.json: unknown background {:?}", run.background))
    }

    /// Suffix of the config file of its runs: the random background's runs train with
    /// their own config (the preset's plus `random_background`).
    fn config_suffix(self) -> &'static str {
        match self {
            SuiteBackground::Random => "-random",
            SuiteBackground::White | SuiteBackground::Black => "",
        }
    }
}

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
fn plan(args: &BenchSuiteArgs, out: &Path, plugins: &Plugins) -> anyhow::Result<SuiteSpec> {
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
fn config_file(preset: &str, filter: &str, bg: SuiteBackground) -> String {
    format!("{preset}-{filter}{}.json", bg.config_suffix())
}

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
fn run_one(spec: &SuiteSpec, out: &Path, exe: &Path, run: &SuiteRun) -> anyhow::Result<String> {
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
fn run_name(r: &SuiteRun) -> String {
    match r.seed {
        Some(seed) => format!("{} {} / seed {seed}", r.scene, r.method()),
        None => format!("{} {}", r.scene, r.method()),
    }
}

/// `[N/M] scene method`: how the suite's output names run `i` (0-based).
fn label(spec: &SuiteSpec, i: usize) -> String {
    format!(
        "[{}/{}] {}",
        i + 1,
        spec.runs.len(),
        run_name(&spec.runs[i])
    )
}

/// The running `maaf` executable, which spawns the runs' commands.
fn maaf_exe() -> anyhow::Result<PathBuf> {
    std::env::current_exe().context("cannot locate the maaf executable")
}

/// `--job n`: run `n` (1-based) of the suite written in `out`, by [`run_one`]'s rule.
fn run_job(out: &Path, n: usize) -> anyhow::Result<()> {
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
        let spec = plan(args, &out, plugins)?;
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
