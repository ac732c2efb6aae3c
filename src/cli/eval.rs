//! `maaf eval`: multi-scale evaluation of a trained run (writes `RUN/eval.json`),
//! optionally with temporal stability (`--temporal`).

use std::path::{Path, PathBuf};

use anyhow::bail;
use maaf_scene::run_data::recorded_data;
use maaf_scene::{SceneRecord, TrainedScene};
use maaf_train::Plugins;
use maaf_train::data::{Dataset, DatasetOptions, FormatRegistry, Split};

use super::Background;
use maaf_eval::{EvalOptions, MetricRegistry, evaluate_run_with, scale_label};
use maaf_lpips::Net;

/// [`maaf_eval::DEFAULT_SCALES`] as `--scales` takes them (comma-separated), so `--help` shows
/// a default that can be typed back.
pub const DEFAULT_SCALES_ARG: &str = "0.25,0.5,1,2,4";

/// Arguments of `maaf eval`.
#[derive(clap::Args, Debug)]
pub struct EvalArgs {
    /// Run directory written by `maaf train` (holds model/).
    #[arg(long)]
    pub run: PathBuf,
    /// Data folder the run was trained on [default: the one in RUN/data.json].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Scales relative to the training scale (2, 4 = zoom-in; 0.5, 0.25 = zoom-out).
    #[arg(long, value_delimiter = ',', default_value = DEFAULT_SCALES_ARG)]
    pub scales: Vec<f64>,
    /// Split to evaluate.
    #[arg(long, value_enum, default_value = "test")]
    pub split: SplitArg,
    /// Evaluate only the first N views (quick checks), after --frame-stride [default:
    /// every view].
    #[arg(long)]
    pub max_views: Option<usize>,
    /// Evaluate the views at every N-th distinct time only (all cameras at those
    /// times): a fixed stride of frames of a multi-view video's test cameras.
    #[arg(long, default_value_t = 1)]
    pub frame_stride: usize,
    /// Do not save renders and error maps (metrics only).
    #[arg(long)]
    pub no_images: bool,
    /// Background the data is composited on and the model rendered on: white, black,
    /// or r,g,b in [0, 1]. Another than the run's own writes RUN/eval-on-NAME.json and
    /// RUN/eval-on-NAME/ beside the run's eval.json (what the model put into empty
    /// space shows there) [default: the run's].
    #[arg(long, value_parser = Background::parse)]
    pub background: Option<Background>,
    /// Also measure temporal stability (W-Temporal Error, W-SSIM, W-LPIPS) of a
    /// fixed-camera video at each scale, with exact flow (when the data has it) and
    /// model flow.
    #[arg(long)]
    pub temporal: bool,
    /// LPIPS backbone: alex (AlexNet, committed weights) or vgg (VGG16, as 3DGS-family
    /// papers and the MAAF release report; fetch its weights once with `bash
    /// lpips/tools/fetch_vgg_weights.sh`; 13x AlexNet's time at 800x800).
    #[arg(long, default_value = "alex")]
    pub lpips_net: Net,
    /// Per-image metrics of one's own to compute, comma-separated: names a program
    /// registers (maaf::cli::Maaf::metric, docs/extending.md; plain maaf has none)
    /// [default: every registered one].
    #[arg(long, value_delimiter = ',')]
    pub metrics: Option<Vec<String>>,
}

impl EvalArgs {
    /// The evaluation these arguments ask for, without metrics of one's own
    /// ([`EvalArgs::with_metrics`] adds them).
    pub fn options(&self) -> EvalOptions {
        EvalOptions {
            scales: self.scales.clone(),
            split: self.split.into(),
            max_views: self.max_views,
            frame_stride: self.frame_stride,
            save_images: !self.no_images,
            temporal: self.temporal,
            lpips_net: self.lpips_net,
            metrics: Vec::new(),
        }
    }

    /// [`EvalArgs::options`] with the metrics of `registry` that `--metrics` names
    /// (every one without it); an unknown name is refused, naming the registered ones.
    pub fn with_metrics(&self, registry: &MetricRegistry) -> anyhow::Result<EvalOptions> {
        let metrics = registry
            .build(self.metrics.as_deref())
            .map_err(|e| match self.metrics {
                Some(_) => anyhow::anyhow!("--metrics: {e}"),
                None => anyhow::anyhow!("{e}"),
            })?;
        Ok(EvalOptions {
            metrics,
            ..self.options()
        })
    }
}

/// `--split` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SplitArg {
    /// transforms_test.json.
    Test,
    /// transforms_val.json.
    Val,
    /// transforms_train.json.
    Train,
}

impl From<SplitArg> for Split {
    fn from(s: SplitArg) -> Self {
        match s {
            SplitArg::Test => Split::Test,
            SplitArg::Val => Split::Val,
            SplitArg::Train => Split::Train,
        }
    }
}

/// Opens the data set of `run`: `data` if given, else the folder in `RUN/data.json`
/// (an error naming it and suggesting --data when it is gone), in a built-in layout or
/// one of `formats`; the background from `background`, else the recorded one, else the
/// default (black).
pub fn open_run_data(
    run: &Path,
    data: Option<&Path>,
    background: Option<Background>,
    formats: &FormatRegistry,
) -> anyhow::Result<Dataset> {
    let recorded = recorded_data(run)?;
    let root = match (data, &recorded) {
        (Some(d), _) => d.to_path_buf(),
        (None, Some(r)) if !r.root.is_dir() => bail!(
            "{}: the run's data folder {} is gone; pass --data DIR with the data set's new place",
            run.display(),
            r.root.display()
        ),
        (None, Some(r)) => r.root.clone(),
        (None, None) => bail!(
            "{}: no data.json records the training data; pass --data DIR",
            run.display()
        ),
    };
    let background = match (background, &recorded) {
        (Some(b), _) => b.rgb(),
        (None, Some(r)) => r.background,
        (None, None) => Background::default().rgb(),
    };
    Ok(Dataset::open_with(
        &root,
        DatasetOptions { background },
        formats,
    )?)
}

/// Loads the trained scene of `run` (a representation `plugins` knows) without its
/// data set; a run saved before checkpoints recorded their cameras takes them from `data`,
/// else from the data set [`open_run_data`] opens with `data_dir` and `background`.
pub fn load_scene(
    run: &Path,
    data_dir: Option<&Path>,
    background: Option<Background>,
    data: Option<&Dataset>,
    plugins: &Plugins,
) -> anyhow::Result<TrainedScene> {
    let scene = TrainedScene::load_or(run, &plugins.models, |config| {
        let opened;
        let data = match data {
            Some(d) => d,
            None => {
                opened = open_run_data(run, data_dir, background, &plugins.formats)
                    .map_err(|e| maaf_scene::Error::Input(e.to_string()))?;
                &opened
            }
        };
        SceneRecord::of_data(data, config)
    })?;
    Ok(scene)
}

/// The shared lock of `run` for a command that reads it and writes elsewhere (render,
/// export, bench): refused while a trainer or an evaluation holds it, so the model
/// read is never one being replaced; `None` for a run folder that cannot hold a lock
/// file (read-only). A folder without a trained model (a checkpoint folder, a run
/// killed before its model) is refused before a lock file is put into it.
pub fn read_lock(run: &Path) -> anyhow::Result<Option<maaf_io::RunLock>> {
    maaf_scene::model_dir(run)?;
    Ok(maaf_io::RunLock::shared(run)?)
}

/// Runs `maaf eval`, with the metrics of one's own in `metrics`.
pub fn run(args: &EvalArgs, plugins: &Plugins, metrics: &MetricRegistry) -> anyhow::Result<()> {
    let options = args.with_metrics(metrics)?;
    // A folder without a model is named as such before its data set is looked for.
    maaf_scene::model_dir(&args.run)?;
    let data = open_run_data(
        &args.run,
        args.data.as_deref(),
        args.background,
        &plugins.formats,
    )?;
    let report = evaluate_run_with(&args.run, &data, &options, &plugins.models)?;
    println!(
        "{} / {} at training scale {}: {} Gaussians, {:.1} MB (+{:.1} MB filter)",
        report.model,
        report.filter,
        report.train_scale,
        report.num_gaussians,
        report.model_bytes as f64 / 1e6,
        report.filter_bytes as f64 / 1e6
    );
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
    let extra: Vec<&String> = report.extra_metrics.keys().collect();
    let columns = |cells: Vec<String>| cells.iter().map(|c| format!(" {c} |")).collect::<String>();
    println!(
        "| scale | size | PSNR | SSIM | LPIPS | W-Temporal Error | W-SSIM | W-LPIPS | flow |{}",
        columns(extra.iter().map(|n| n.to_string()).collect())
    );
    println!(
        "|---|---|---|---|---|---|---|---|---|{}",
        "---|".repeat(extra.len())
    );
    for s in &report.scales {
        println!(
            "| {} | {}x{} | {:.2} | {:.4} | {} | {} | {} | {} | {} |{}",
            scale_label(s.scale),
            s.width,
            s.height,
            s.psnr,
            s.ssim,
            opt(s.lpips),
            opt(s.warp_error),
            opt(s.w_ssim),
            opt(s.w_lpips),
            s.flow.as_deref().unwrap_or("-"),
            columns(
                extra
                    .iter()
                    .map(|n| opt(s.extra.get(*n).copied()))
                    .collect()
            )
        );
    }
    println!(
        "| avg | | {:.2} | {:.4} | | | | | |{}",
        report.mean_psnr(),
        report.mean_ssim(),
        " |".repeat(extra.len())
    );
    if let Some(note) = report.scales.iter().find_map(|s| s.lpips_note.as_ref()) {
        println!("LPIPS missing at some scale: {note}");
    }
    println!(
        "wrote {}",
        args.run.join(format!("{}.json", report.name())).display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_eval::DEFAULT_SCALES;

    #[test]
    fn the_scales_default_as_typed_is_the_library_default() {
        let parsed: Vec<f64> = DEFAULT_SCALES_ARG
            .split(',')
            .map(|v| v.parse().expect("number"))
            .collect();
        assert_eq!(parsed, DEFAULT_SCALES);
    }
}
