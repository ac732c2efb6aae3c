//! maaf-eval: evaluation of a trained run, its image and temporal metrics
//! ([`metrics`]) and reports ([`report`]), working on a
//! [`maaf_scene::TrainedScene`] and never on the trainer.
//!
//! Multi-scale evaluation of a trained run (docs/conventions.md).
//!
//! [`evaluate_run`] renders every view of a split at each evaluation scale, computes
//! PSNR and SSIM on the float renders (no 8-bit quantisation) against ground truth at
//! that resolution, saves 8-bit renders and colour-mapped error maps under
//! `RUN/eval/<scale>x/`, and writes `RUN/eval.json` with exactly the fields of the
//! docs/conventions.md contract ([`EvalReport`]).
//!
//! Evaluation scales are relative to the run's *training* scale: `2` and `4` zoom in,
//! `0.5` and `0.25` zoom out. The data set's scale is `train_scale * s`, which must
//! be `1 / k` for an integer `k` dividing the source image size; a scale asking for
//! more pixels than the source images have is refused before anything is rendered.
//!
//! Nothing is overwritten on error: outputs go to a temporary folder that replaces
//! `RUN/eval/` only when complete, then `eval.json` is written atomically.

pub mod camera_path;
pub mod eval_json;
pub mod export;
pub mod filter_agreement;
pub mod flow;
pub mod images;
mod measure;
pub mod metrics;
pub mod popping;
pub mod render;
pub mod report;
mod scales;
mod sequence;
pub mod temporal;

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use maaf_data::{Dataset, Split};
use maaf_filter::{FilterKind, FilterState};
use maaf_lpips::{Lpips, Net};
use maaf_scene::metrics::{ImageMetrics, mean_metrics};
use maaf_scene::{ModelRegistry, TrainedScene};

use crate::measure::{evaluate_scale, metrics_csv};
use crate::metrics::rings::RingErrors;
use crate::scales::{checked_scales, strided_views};

pub use eval_json::{
    EvalReport, ExtraMetric, PoppingResult, RegionSummary, ScaleResult, SkippedScale,
    TemporalResult, scale_label, trim_float,
};
pub use maaf_scene::{Error, write_atomic};
pub use metrics::image_metric::{ImageMetric, MetricRegistry};
pub use render::{load_scene_on, run_camera};
pub use scales::check_eval_options;
pub use sequence::{MAX_SEQUENCE_FRAMES, check_frame_count, frame_times};

/// The paper's evaluation scales relative to the training scale: 1/4x, 1/2x (zoom-out),
/// 1x, 2x and 4x (zoom-in).
pub const DEFAULT_SCALES: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];

/// Options of [`evaluate_run`].
#[derive(Clone, Debug)]
pub struct EvalOptions {
    /// Scales relative to the training scale (`2` = zoom-in 2x, `0.5` = zoom-out 2x).
    pub scales: Vec<f64>,
    /// Split whose views are rendered (the protocol uses `test`).
    pub split: Split,
    /// Evaluate only the first `n` views of the split (quick runs); `None` = all.
    /// Applied after `frame_stride`.
    pub max_views: Option<usize>,
    /// Evaluate only the views at every `n`-th distinct time of the split (the 1st,
    /// `n+1`-th, ... in time order), every camera at those times; 1 = all. A multi-view
    /// video's test split has cameras x frames views, so the protocol can evaluate a
    /// fixed stride of frames of every test camera.
    pub frame_stride: usize,
    /// Save 8-bit renders and error maps as PNG (metrics are computed either way).
    pub save_images: bool,
    /// Also measure temporal stability of a fixed-camera video at every scale
    /// ([`temporal::evaluate_temporal`]: W-Temporal Error, W-SSIM, W-LPIPS).
    pub temporal: bool,
    /// Backbone of LPIPS and W-LPIPS ([`Net::Alex`], the package's default, or
    /// [`Net::Vgg`], what 3DGS-family papers and the MAAF release report).
    pub lpips_net: Net,
    /// Per-image metrics of one's own computed on every view beside PSNR, SSIM and
    /// LPIPS ([`MetricRegistry::build`]): a `metrics.csv` column each and their means
    /// in `eval.json` ([`ScaleResult::extra`]). Empty by default.
    pub metrics: Vec<Arc<dyn ImageMetric>>,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            scales: DEFAULT_SCALES.to_vec(),
            split: Split::Test,
            max_views: None,
            frame_stride: 1,
            save_images: true,
            temporal: false,
            lpips_net: Net::Alex,
            metrics: Vec::new(),
        }
    }
}

/// Where [`evaluate_run`] writes the nu(t) traces of a motion-filter run
/// ([`filter_agreement::FilterStudy::analysis`]).
pub const FILTER_ANALYSIS_FILE: &str = "filter_analysis.json";

/// Builds the contract fields that describe the run (everything but `scales`).
pub fn run_report(scene: &TrainedScene, data: &Dataset) -> EvalReport {
    let n = scene.num_gaussians();
    EvalReport {
        model: scene.model.label(),
        filter: filter_name(scene),
        train_scale: scene.config.train_scale,
        iterations: scene.iteration,
        train_seconds: scene.train_seconds,
        num_gaussians: n,
        model_bytes: scene.num_scalars() as u64 * 4,
        filter_bytes: (scene.filter.bytes_per_gaussian() * n) as u64,
        background: data.background(),
        trained_background: (scene.record.background != data.background())
            .then_some(scene.record.background),
        quantized_8bit: false,
        frame_stride: 1,
        lpips_net: Net::Alex.name().to_string(),
        scales: Vec::new(),
        skipped_scales: Vec::new(),
        extra_metrics: Default::default(),
    }
}

/// The run's filter as eval.json and the report name it: a program's own filter by
/// its registered name, a built-in by the state it draws (`window_max` draws motion
/// curves, `motion`; the report tells the estimators apart).
fn filter_name(scene: &TrainedScene) -> String {
    if let FilterKind::Custom(name) = &scene.config.filter.kind {
        return name.clone();
    }
    match &scene.filter {
        FilterState::None { .. } => "none",
        FilterState::Mip3d { .. } => "mip3d",
        FilterState::Motion { .. } => "motion",
    }
    .to_string()
}

/// Evaluates the run in `run` (a built-in representation) on `data` (the data set it
/// was trained on): [`evaluate_run_with`] and [`ModelRegistry::builtin`].
pub fn evaluate_run(
    run: &Path,
    data: &Dataset,
    options: &EvalOptions,
) -> Result<EvalReport, Error> {
    evaluate_run_with(run, data, options, &ModelRegistry::builtin())
}

/// Evaluates the run in `run` on `data` (the data set it was trained on) at every
/// scale of `options` and writes `RUN/eval.json` plus `RUN/eval/<scale>x/` (renders,
/// error maps, per-view `metrics.csv`) and, for a motion-filter run,
/// `RUN/eval/filter_analysis.json` (nu(t) of a static and the most moving Gaussian,
/// for the report's chart) and `RUN/eval/filter_agreement.json`. Prints one progress
/// line per scale to stderr.
///
/// The model is loaded as a [`TrainedScene`] (its representation through `registry`):
/// of the data set only the views scored are read.
///
/// Errors (one line, nothing written): the run being trained or evaluated by another
/// process, no trained model in `run`, a representation `registry` does not know, a
/// data set that does not match the run, an impossible scale.
pub fn evaluate_run_with(
    run: &Path,
    data: &Dataset,
    options: &EvalOptions,
    registry: &ModelRegistry,
) -> Result<EvalReport, Error> {
    // The evaluation writes into the run: it holds the run's lock exclusively (no
    // trainer replaces the model it reads, no other evaluation shares its outputs)
    // and so may sweep what a killed evaluation left behind.
    // A folder without a model (a checkpoint folder, a run killed early) is refused
    // before the lock, which would leave a lock file in it.
    maaf_scene::model_dir(run)?;
    let _lock = if run.is_dir() {
        let doing = format!("evaluated (pid {})", std::process::id());
        let lock =
            maaf_io::RunLock::exclusive(run, &doing).map_err(|e| Error::Input(e.to_string()))?;
        maaf_scene::repair_run_dir(run)?;
        Some(lock)
    } else {
        None
    };
    let scene = load_scene_on(run, data, registry)?;
    evaluate_scene(&scene, run, data, options)
}

/// The scene's render settings on the data set's background (the run's own unless the
/// evaluation moved the ground truth onto another, [`EvalReport::name`]).
pub(crate) fn eval_settings(scene: &TrainedScene, data: &Dataset) -> maaf_splat::RenderSettings {
    maaf_splat::RenderSettings {
        background: data.background().map(f64::from),
        ..scene.render_settings()
    }
}

/// [`evaluate_run`] for a run already loaded (saves loading it twice when the caller
/// also renders videos, or evaluates a trainer's `maaf_train::trainer::Trainer::into_scene`).
pub fn evaluate_scene(
    scene: &TrainedScene,
    run: &Path,
    data: &Dataset,
    options: &EvalOptions,
) -> Result<EvalReport, Error> {
    let split = options.split;
    let (scales, skipped) = checked_scales(data, scene.config.train_scale, options)?;
    let indices = strided_views(data, split, options.frame_stride, options.max_views);
    for k in &skipped {
        log::warn!("eval: scale {}x skipped: {}", trim_float(k.scale), k.reason);
    }
    let mut report = run_report(scene, data);
    report.skipped_scales = skipped;
    report.frame_stride = options.frame_stride;
    // LPIPS is optional: without weights every scale gets `lpips: null` and the reason.
    let lpips = Lpips::load_default(options.lpips_net).map_err(|e| e.to_string());
    report.lpips_net = options.lpips_net.name().to_string();
    report.extra_metrics = options
        .metrics
        .iter()
        .map(|m| {
            let info = ExtraMetric {
                higher_is_better: m.higher_is_better(),
            };
            (m.name().to_string(), info)
        })
        .collect();

    let name = report.name();
    let final_dir = run.join(&name);
    let tmp_dir = maaf_io::temp_sibling(&final_dir);
    if tmp_dir.exists() {
        std::fs::remove_dir_all(&tmp_dir).map_err(|e| Error::io(&tmp_dir, e))?;
    }
    let result = (|| {
        let sources: Vec<f64> = scales.iter().map(|s| s.source).collect();
        data.preload(split, &indices, &sources)
            .map_err(|e| Error::Input(e.to_string()))?;
        for s in &scales {
            let start = Instant::now();
            let dir = tmp_dir.join(scale_label(s.relative));
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            let views = evaluate_scale(scene, data, split, &indices, s, options, &lpips, &dir)?;
            let per: Vec<ImageMetrics> = views.iter().map(|v| v.metrics).collect();
            let m =
                mean_metrics(&per).ok_or_else(|| Error::Input("no views were evaluated".into()))?;
            if !(m.psnr.is_finite() && m.ssim.is_finite()) {
                return Err(Error::Input(format!(
                    "{}: the model renders non-finite pixels at scale {} (PSNR {}, SSIM {}): the run diverged; eval.json not written",
                    run.display(),
                    scale_label(s.relative),
                    m.psnr,
                    m.ssim
                )));
            }
            let names: Vec<&str> = options.metrics.iter().map(|m| m.name()).collect();
            write_atomic(&dir.join("metrics.csv"), &metrics_csv(&views, &names)?)?;
            let mut result = ScaleResult::new(s.relative, (s.width, s.height), m.psnr, m.ssim);
            for (k, name) in names.iter().enumerate() {
                let value = eval_json::mean(views.iter().map(|v| v.extra[k]));
                result.extra.insert(name.to_string(), value);
            }
            match views
                .iter()
                .map(|v| v.lpips.clone())
                .collect::<Result<Vec<f64>, String>>()
            {
                Ok(values) => result.lpips = Some(eval_json::mean(values.into_iter())),
                Err(reason) => result.lpips_note = Some(reason),
            }
            result.regions = RegionSummary::of(views.iter().filter_map(|v| v.regions));
            result.rings = RingErrors::total(views.iter().filter_map(|v| v.rings));
            if !result.extra.is_empty() {
                let values: Vec<String> = result
                    .extra
                    .iter()
                    .map(|(n, v)| format!("{n} {v:.4}"))
                    .collect();
                log::info!(
                    "eval {:>5} metrics: {}",
                    scale_label(s.relative),
                    values.join("  ")
                );
            }
            if let Some(r) = &result.regions {
                log::info!("eval {:>5} by region: {}", scale_label(s.relative), r);
            }
            let lpips_seconds: f64 = views.iter().map(|v| v.lpips_seconds).sum();
            log::info!(
                "eval {:>5} {}x{}: PSNR {:.2} dB  SSIM {:.4}  LPIPS {}  ({} views, {:.1} s; LPIPS {:.2} s per view)",
                scale_label(s.relative),
                s.width,
                s.height,
                m.psnr,
                m.ssim,
                result.lpips.map_or("-".to_string(), |l| format!("{l:.4}")),
                views.len(),
                start.elapsed().as_secs_f64(),
                lpips_seconds / views.len() as f64
            );
            if options.temporal {
                let start = Instant::now();
                let model = lpips.as_ref().ok();
                let (flows, popping) = temporal::evaluate_temporal(scene, data, s.source, model)?;
                result.temporal = flows;
                temporal::set_primary(&mut result);
                log::info!(
                    "temporal {:>5}: {}; popping {:.1} Gaussians per step, mass {:.3} % ({:.1} s)",
                    scale_label(s.relative),
                    result
                        .temporal
                        .iter()
                        .map(|t| format!(
                            "{} flow: W-error {:.4} W-SSIM {:.4}",
                            t.flow, t.warp_error, t.w_ssim
                        ))
                        .collect::<Vec<_>>()
                        .join(", "),
                    popping.mean_pops(),
                    100.0 * popping.mean_mass(),
                    start.elapsed().as_secs_f64()
                );
                result.popping = Some(popping);
            }
            report.scales.push(result);
        }
        let study = filter_agreement::FilterStudy::of(scene);
        if let Some(export) = study.as_ref().and_then(|s| s.analysis()) {
            write_atomic(
                &tmp_dir.join(FILTER_ANALYSIS_FILE),
                export.to_json().as_bytes(),
            )?;
        }
        if let Some(agreement) = study.as_ref().and_then(|s| s.agreement()) {
            log::info!("filter agreement: {}", agreement.summary());
            let json = serde_json::to_string_pretty(&agreement)
                .map_err(|e| Error::Input(format!("filter agreement: {e}")))?;
            write_atomic(
                &tmp_dir.join(filter_agreement::FILTER_AGREEMENT_FILE),
                json.as_bytes(),
            )?;
        }
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp_dir);
        return Err(e);
    }
    // Swap the complete folder into place, then write NAME.json.
    maaf_io::replace_dir(&tmp_dir, &final_dir).map_err(|e| Error::io(&final_dir, e))?;
    let json = serde_json::to_vec_pretty(&report)
        .map_err(|e| Error::Input(format!("{name}.json: {e}")))?;
    write_atomic(&run.join(format!("{name}.json")), &json)?;
    Ok(report)
}
