//! `maaf train`: train a 4D Gaussian model on a D-NeRF-format data set.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_filter::{FilterConfig, FilterKind, MotionEstimator};
use maaf_scene::metrics::psnr;
use maaf_scene::run_data::recorded_data;
use maaf_scene::{TrainConfig, TrainedScene, WallBudget};
use maaf_train::Plugins;
use maaf_train::data::{Dataset, DatasetOptions, Split};
use maaf_train::models::ModelConfig;
use maaf_train::trainer::{branch_run_with_plugins, train_run_with_plugins};

use super::Background;

/// Arguments of `maaf train`.
#[derive(clap::Args, Debug)]
pub struct TrainArgs {
    /// Run directory to create (config.json, log.csv, checkpoints/, model/); required
    /// unless --resume names the run.
    #[arg(long, required_unless_present = "resume")]
    pub out: Option<PathBuf>,
    /// Continue the run in this directory from its newest complete checkpoint, with its
    /// settings (only --iters may change the budget; absent, the run's is kept).
    #[arg(long)]
    pub resume: Option<PathBuf>,
    /// Start the new run (--out) from another run's checkpoint folder
    /// (RUN/checkpoints/iter_N or RUN/model) with this run's settings: a branch
    /// continues the checkpoint's iteration, model, optimiser and filter state, so
    /// late-stage options are compared without training the shared prefix again.
    /// The filter kind and training scale must be the checkpoint's.
    #[arg(long, conflicts_with = "resume")]
    pub from: Option<PathBuf>,
    /// With --from: branch onto a data set other than the one the checkpoint was
    /// trained on, on purpose (without it another data set is refused, naming both).
    #[arg(long, requires = "from")]
    pub other_data: bool,
    /// Data folder (D-NeRF, Plenoptic Video or the Dynamic 3D Gaussians layout)
    /// [default: none for a new run; with --resume, the run's, recorded in
    /// RUN/data.json].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// The training settings.
    #[command(flatten)]
    pub settings: SettingsArgs,
}

/// The training settings of a run (shared by `maaf train` and `maaf sweep`).
#[derive(clap::Args, Debug)]
pub struct SettingsArgs {
    /// 4D representation: `saro` (SaRO-GS), `deform` (Deformable-3DGS), `track` (Dynamic
    /// 3D Gaussians' tracking) or one the program registers (docs/extending.md); its
    /// settings: the `model` section of --config [default: the config's, else saro].
    #[arg(long)]
    pub model: Option<String>,
    /// 3D smoothing filter: `none` (classic 0.3 px^2 2D dilation), `mip3d`
    /// (Mip-Splatting's static 3D filter + 2D Mip filter), `motion` (the motion-aware
    /// nu(t) by the paper's KDE + 2D Mip filter), `window_max` (the motion-aware
    /// filter with maaf's windowed-maximum estimator, as `"filter": {"kind": "motion",
    /// "estimator": "window_max"}`) or one the program registers [default: the
    /// config's, else motion].
    #[arg(long)]
    pub filter: Option<String>,
    /// Training scale relative to the source images [default: the config's, else 0.25,
    /// the D-NeRF protocol].
    #[arg(long)]
    pub train_scale: Option<f64>,
    /// Iterations [default: the config's, else 20000, the D-NeRF protocol].
    #[arg(long)]
    pub iters: Option<usize>,
    /// Wall time for the whole run (90s, 10m, 1.5h, 1h30m): a short measured warm-up
    /// chooses one factor that scales the schedule (iterations, densification and
    /// reset windows, Gaussian cap) to finish in it; `RUN/budget.json` records the
    /// plan [default: the config's `budget`, else none: the schedule as written].
    #[arg(long)]
    pub budget: Option<WallBudget>,
    /// Training views per iteration, their gradients averaged (SaRO-GS configs: 4)
    /// [default: the config's, else 1].
    #[arg(long)]
    pub batch: Option<usize>,
    /// Seed of initialisation, view order and densification [default: the config's,
    /// else 0].
    #[arg(long)]
    pub seed: Option<u64>,
    /// JSON file with a full or partial TrainConfig (flags override it; presets in
    /// configs/, every key in docs/config.md) [default: none: the defaults].
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Background the RGBA images are composited on and the model rendered on: white,
    /// black, or r,g,b in [0, 1] [default: the config's `background`, else black, the
    /// paper's D-NeRF protocol].
    #[arg(long, value_parser = Background::parse)]
    pub background: Option<Background>,
}

/// The built-in filters, as `maaf bench-suite --filters` takes them.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum FilterArg {
    /// No 3D filter (classic 0.3 px^2 2D dilation).
    None,
    /// Mip-Splatting's static 3D filter (+ 2D Mip filter).
    Mip3d,
    /// The motion-aware filter nu(t) (+ 2D Mip filter).
    Motion,
}

impl From<FilterArg> for FilterKind {
    fn from(f: FilterArg) -> Self {
        match f {
            FilterArg::None => FilterKind::None,
            FilterArg::Mip3d => FilterKind::Mip3d,
            FilterArg::Motion => FilterKind::Motion,
        }
    }
}

/// Builds the configuration: defaults, then `--config`, then flags.
pub fn config_from(args: &SettingsArgs) -> anyhow::Result<TrainConfig> {
    let mut config = match &args.config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read", path.display()))?;
            let value: serde_json::Value = serde_json::from_str(&text)
                .with_context(|| format!("{}: invalid training config", path.display()))?;
            if !value.is_object() {
                bail!(
                    "{}: invalid training config: expected a JSON object {{\"iterations\": ..}}, got {}",
                    path.display(),
                    json_kind(&value)
                );
            }
            serde_json::from_value(value)
                .with_context(|| format!("{}: invalid training config", path.display()))?
        }
        None => TrainConfig::default(),
    };
    if let Some(kind) = &args.model
        && kind != config.model.kind()
    {
        config.model = ModelConfig::default_of(kind).map_err(anyhow::Error::msg)?;
    }
    if let Some(f) = &args.filter {
        set_filter(&mut config.filter, f);
    }
    if let Some(s) = args.train_scale {
        config.train_scale = s;
    }
    if let Some(i) = args.iters {
        config.iterations = i;
    }
    if let Some(b) = args.budget {
        config.budget = Some(b);
    }
    if let Some(b) = args.batch {
        config.batch = b;
    }
    if let Some(s) = args.seed {
        config.seed = s;
    }
    if let Some(b) = args.background {
        config.background = b;
    }
    config.validate()?;
    Ok(config)
}

/// Sets the filter `--filter NAME` names: `window_max` is the motion filter with the
/// windowed-maximum estimator, any other name the filter kind of that name.
fn set_filter(filter: &mut FilterConfig, name: &str) {
    if name == "window_max" {
        filter.kind = FilterKind::Motion;
        filter.estimator = MotionEstimator::WindowMax;
    } else {
        filter.kind = FilterKind::from_name(name);
    }
}

/// What a JSON value is, for messages.
fn json_kind(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// The configuration of the run being resumed: its `config.json`, with the budget of
/// `--iters` if given (said on stderr when it changes). Any other setting flag that
/// differs from the run's is refused: a resumed run keeps its settings, so that it
/// continues exactly as an uninterrupted run would have.
fn resumed_config(args: &SettingsArgs, run: &Path) -> anyhow::Result<TrainConfig> {
    let path = run.join("config.json");
    let text = std::fs::read_to_string(&path).map_err(|e| {
        anyhow::anyhow!(
            "{}: no run to resume ({e}); start one with --out",
            path.display()
        )
    })?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: invalid run config: {e}", path.display()))?;
    let recorded_background = value.get("background").is_some();
    let mut config: TrainConfig = serde_json::from_value(value)
        .map_err(|e| anyhow::anyhow!("{}: invalid run config: {e}", path.display()))?;
    if !recorded_background {
        // A run from before the key: data.json recorded its background (white when
        // even that is missing, the training default then).
        let recorded = recorded_data(run)?;
        config.background = Background(recorded.map_or(maaf_train::data::WHITE, |r| r.background));
    }
    if let Some(file) = &args.config {
        bail!(
            "--config {}: a resumed run keeps the settings in {}; only --iters may change",
            file.display(),
            path.display()
        );
    }
    let conflicts = [
        args.model
            .as_ref()
            .filter(|m| m.as_str() != config.model.kind())
            .map(|m| format!("--model {m} (the run's is {})", config.model.kind())),
        args.filter
            .as_deref()
            .filter(|f| *f != config.filter.filter_name())
            .map(|f| {
                format!(
                    "--filter {f} (the run's is {})",
                    config.filter.filter_name()
                )
            }),
        args.train_scale
            .filter(|s| *s != config.train_scale)
            .map(|s| format!("--train-scale {s} (the run's is {})", config.train_scale)),
        args.seed
            .filter(|s| *s != config.seed)
            .map(|s| format!("--seed {s} (the run's is {})", config.seed)),
        args.batch
            .filter(|b| *b != config.batch)
            .map(|b| format!("--batch {b} (the run's is {})", config.batch)),
        args.background
            .filter(|b| *b != config.background)
            .map(|b| format!("--background {b} (the run's is {})", config.background)),
        args.budget
            .map(|b| format!("--budget {b} (the run's schedule was chosen when it started)")),
    ];
    if let Some(c) = conflicts.into_iter().flatten().next() {
        bail!(
            "{c}: a resumed run keeps its settings ({}); only --iters may change",
            path.display()
        );
    }
    if let Some(iters) = args.iters
        && iters != config.iterations
    {
        eprintln!(
            "maaf: --iters {iters}: the run's budget changes from {} to {iters} iterations",
            config.iterations
        );
        config.iterations = iters;
    }
    config.validate()?;
    Ok(config)
}

/// The data folder of the run being resumed: `--data` when given (train_run refuses
/// it unless its frames and cameras are the recorded ones), else `RUN/data.json`'s.
fn resumed_data(data: Option<&Path>, run: &Path) -> anyhow::Result<PathBuf> {
    match (data, recorded_data(run)?) {
        (Some(d), _) => Ok(d.to_path_buf()),
        (None, Some(r)) => Ok(r.root),
        (None, None) => bail!(
            "{}: records no data set (no data.json, a run of an older version); pass --data DIR",
            run.display()
        ),
    }
}

/// Runs `maaf train`; `plugins` are the terms, representations, filters and
/// strategies its config may name.
pub fn run(args: &TrainArgs, plugins: &Plugins) -> anyhow::Result<()> {
    let settings = &args.settings;
    if let Some(data) = &args.data
        && data.to_str().is_none()
    {
        bail!(
            "--data {}: the folder name is not valid UTF-8, which RUN/data.json cannot record; rename it",
            data.display()
        );
    }
    let out = match (&args.out, &args.resume) {
        (Some(o), Some(r)) if o != r => bail!(
            "--out {} and --resume {} name different runs",
            o.display(),
            r.display()
        ),
        (_, Some(r)) => r.clone(),
        (Some(o), None) => o.clone(),
        (None, None) => bail!("--out RUN is required (or --resume RUN)"),
    };
    let (config, root) = match &args.resume {
        Some(run) => (
            resumed_config(settings, run)?,
            resumed_data(args.data.as_deref(), run)?,
        ),
        None => match &args.data {
            Some(data) => (config_from(settings)?, data.clone()),
            None => bail!("--data DIR is required (the training data folder)"),
        },
    };
    // Names the program does not register are refused before the data is read.
    let what = match (&args.resume, &settings.config) {
        (Some(run), _) => run.join("config.json").display().to_string(),
        (None, Some(file)) => file.display().to_string(),
        (None, None) => "config".to_string(),
    };
    plugins.check(&config, &what)?;
    let background = config.background.rgb();
    let data = Dataset::open_with(&root, DatasetOptions { background }, &plugins.formats)?;
    // One trainer per run folder, for the whole command (test PSNR included).
    let doing = format!("trained (maaf train, pid {})", std::process::id());
    let _lock = maaf_io::RunLock::exclusive(&out, &doing)?;
    if args.resume.is_none()
        && ["config.json", "log.csv", "checkpoints", "model"]
            .iter()
            .any(|f| out.join(f).exists())
    {
        bail!(
            "{}: already holds a run; continue it with --resume {} or choose another --out",
            out.display(),
            out.display()
        );
    }
    let mut summary = match &args.from {
        Some(from) => branch_run_with_plugins(&data, config, &out, from, plugins, args.other_data)?,
        None => train_run_with_plugins(&data, config, &out, args.resume.is_some(), plugins)?,
    };
    let since = summary
        .last_reset
        .map_or("ever".to_string(), |r| format!("since the reset at {r}"));
    println!(
        "trained {} iterations in {:.1} s: {} Gaussians ({} without a gradient {since}, {} of them at its cap), {} skipped steps",
        summary.iterations,
        summary.train_seconds,
        summary.num_gaussians,
        summary.dead_gaussians,
        summary.dead_at_cap,
        summary.skipped_steps
    );
    print!("{}", summary.timings.report(summary.iterations));
    let scene = TrainedScene::load(&out, &plugins.models)?;
    let scale = scene.config.train_scale;
    let mut total = 0.0;
    let views = data.views(Split::Test, scale)?;
    for v in &views {
        let image = scene.render(&v.camera, v.time);
        total += psnr(&image, &v.image.to_tensor())?;
    }
    if !views.is_empty() {
        let mean = total / views.len() as f64;
        summary.test_psnr = Some(mean);
        // +inf is a perfect render; NaN (or -inf) a model that renders non-finite values.
        if mean.is_nan() || mean == f64::NEG_INFINITY {
            let failure = format!(
                "the test PSNR is {mean} dB: the model renders non-finite values, the run failed"
            );
            summary.failure = Some(failure.clone());
            summary.write(&out)?;
            bail!("{}: {failure}", out.display());
        }
        summary.write(&out)?;
        println!(
            "test PSNR at the training scale ({} views): {:.2} dB",
            views.len(),
            mean
        );
    }
    println!("run written to {}", out.display());
    Ok(())
}
