//! Multi-scale evaluation of a trained run (DESIGN.md sections 7 and 8).
//!
//! [`evaluate_run`] renders every view of a split at each evaluation scale, computes
//! PSNR and SSIM on the float renders (no 8-bit quantisation) against ground truth at
//! that resolution, saves 8-bit renders and colour-mapped error maps under
//! `RUN/eval/<scale>x/`, and writes `RUN/eval.json` with exactly the fields of the
//! DESIGN.md section 8 contract ([`EvalReport`]).
//!
//! Evaluation scales are relative to the run's *training* scale: `2` and `4` zoom in,
//! `0.5` and `0.25` zoom out. The data set's scale is `train_scale * s`, which must
//! be `1 / k` for an integer `k` dividing the source image size; a scale asking for
//! more pixels than the source images have is refused before anything is rendered.
//!
//! Nothing is overwritten on error: outputs go to a temporary folder that replaces
//! `RUN/eval/` only when complete, then `eval.json` is written atomically.

pub mod images;
pub mod render;

use std::path::Path;
use std::time::Instant;

use maaf_autodiff::{PerGaussian, Tensor};
use maaf_filter::{AnalysisExport, FilterState};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::data::{Dataset, Split};
use crate::metrics::{ImageMetrics, error_map, image_metrics, mean_metrics};
use crate::trainer::Trainer;
use crate::{Error, write_atomic};

pub use render::{load_run, render_image, run_camera};

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
    pub max_views: Option<usize>,
    /// Save 8-bit renders and error maps as PNG (metrics are computed either way).
    pub save_images: bool,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            scales: DEFAULT_SCALES.to_vec(),
            split: Split::Test,
            max_views: None,
            save_images: true,
        }
    }
}

/// Metrics at one evaluation scale (an entry of `eval.json`'s `scales`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleResult {
    /// Scale relative to the training scale.
    pub scale: f64,
    /// Rendered width, pixels.
    pub width: u32,
    /// Rendered height, pixels.
    pub height: u32,
    /// Mean over views of the per-image PSNR, dB (data range 1).
    pub psnr: f64,
    /// Mean over views of the per-image SSIM (scikit-image convention).
    pub ssim: f64,
    /// LPIPS: `null` (no weights offline; a later issue may fill it).
    pub lpips: Option<f64>,
    /// Flow-warped temporal error: `null` until the temporal-stability issue lands.
    pub warp_error: Option<f64>,
}

/// `RUN/eval.json`: exactly the field names of the DESIGN.md section 8 contract.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalReport {
    /// Representation name (`saro`).
    pub model: String,
    /// Filter: `none`, `mip3d` or `motion`.
    pub filter: String,
    /// Training scale relative to the source images.
    pub train_scale: f64,
    /// Iterations trained.
    pub iterations: usize,
    /// Training wall time, seconds (all phases, summed over resumed sessions).
    pub train_seconds: f64,
    /// Number of Gaussians.
    pub num_gaussians: usize,
    /// Bytes of the representation's parameters (`num_scalars * 4`).
    pub model_bytes: u64,
    /// Bytes of the filter state (`bytes_per_gaussian * num_gaussians`).
    pub filter_bytes: u64,
    /// Background colour the renders and ground truth are composited on.
    pub background: [f32; 3],
    /// Whether renders were quantised to 8 bits before the metrics (always `false`).
    pub quantized_8bit: bool,
    /// One entry per evaluation scale, in the order asked.
    pub scales: Vec<ScaleResult>,
}

impl EvalReport {
    /// Mean PSNR over the scales (the "Avg." column of the paper's tables).
    pub fn mean_psnr(&self) -> f64 {
        mean(self.scales.iter().map(|s| s.psnr))
    }

    /// Mean SSIM over the scales.
    pub fn mean_ssim(&self) -> f64 {
        mean(self.scales.iter().map(|s| s.ssim))
    }

    /// Model plus filter bytes.
    pub fn total_bytes(&self) -> u64 {
        self.model_bytes + self.filter_bytes
    }

    /// Reads `RUN/eval.json`.
    pub fn read(run: &Path) -> Result<Self, Error> {
        let path = run.join("eval.json");
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        serde_json::from_str(&text)
            .map_err(|e| Error::Input(format!("{}: not an eval.json: {e}", path.display())))
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Folder name of a scale's outputs: `1x`, `2x`, `0.5x`, `0.25x`.
pub fn scale_label(scale: f64) -> String {
    format!("{}x", trim_float(scale))
}

/// `0.5` -> `0.5`, `2.0` -> `2`: the shortest decimal spelling of a scale.
pub fn trim_float(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

/// One resolved evaluation scale: relative, source-relative, output size.
#[derive(Clone, Copy, Debug)]
struct ResolvedScale {
    relative: f64,
    source: f64,
    width: u32,
    height: u32,
}

/// Checks every scale against the data before anything is rendered: positive,
/// finite, not repeated, no more pixels than the source images, an integer
/// downsampling factor of them.
fn resolve_scales(
    data: &Dataset,
    split: Split,
    train_scale: f64,
    scales: &[f64],
) -> Result<Vec<ResolvedScale>, Error> {
    if scales.is_empty() {
        return Err(Error::Input("no evaluation scale given".into()));
    }
    let meta = data.split(split).map_err(|e| Error::Input(e.to_string()))?;
    let (sw, sh) = (meta.width, meta.height);
    let mut out: Vec<ResolvedScale> = Vec::new();
    for &s in scales {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::Input(format!(
                "scale {s}: must be a positive number (relative to the training scale, e.g. 0.25,0.5,1,2,4)"
            )));
        }
        if out.iter().any(|r| (r.relative - s).abs() < 1e-9) {
            return Err(Error::Input(format!("scale {s} is given twice")));
        }
        let source = train_scale * s;
        let want = (
            (sw as f64 * source).round() as u64,
            (sh as f64 * source).round() as u64,
        );
        if source > 1.0 + 1e-9 {
            return Err(Error::Input(format!(
                "scale {}x needs {}x{} ground truth but the source images are {sw}x{sh} (training scale {}: at most {}x)",
                trim_float(s),
                want.0,
                want.1,
                trim_float(train_scale),
                trim_float(1.0 / train_scale)
            )));
        }
        let (width, height) = data.size(split, source).map_err(|e| {
            Error::Input(format!(
                "scale {}x (source scale {}): {e}",
                trim_float(s),
                trim_float(source)
            ))
        })?;
        out.push(ResolvedScale {
            relative: s,
            source,
            width,
            height,
        });
    }
    Ok(out)
}

/// Per-view metrics of one scale (written as `RUN/eval/<scale>x/metrics.csv`).
#[derive(Clone, Debug)]
struct ViewResult {
    index: usize,
    time: f64,
    metrics: ImageMetrics,
}

/// Renders, measures and (optionally) saves every view at one scale into `dir`.
fn evaluate_scale(
    trainer: &Trainer,
    data: &Dataset,
    split: Split,
    scale: &ResolvedScale,
    options: &EvalOptions,
    dir: &Path,
) -> Result<Vec<ViewResult>, Error> {
    let mut views = data
        .views(split, scale.source)
        .map_err(|e| Error::Input(e.to_string()))?;
    if let Some(n) = options.max_views {
        views.truncate(n);
    }
    let settings = trainer.render_settings(trainer.iteration);
    // The model is not `Sync`: views are rendered one after the other (the renderer
    // is parallel inside), then metrics and PNG encoding run in parallel over a
    // chunk of views (bounded memory: one chunk of float images at a time).
    let mut results = Vec::with_capacity(views.len());
    for chunk in views.chunks(8) {
        let rendered: Vec<Tensor<f32>> = chunk
            .iter()
            .map(|v| render_image(trainer, &v.camera, v.time, &settings))
            .collect();
        let part: Vec<ViewResult> = chunk
            .par_iter()
            .zip(rendered.par_iter())
            .map(|(v, image)| measure_view(v, image, scale, options, dir))
            .collect::<Result<_, _>>()?;
        results.extend(part);
    }
    Ok(results)
}

/// Metrics of one rendered view, plus its PNGs when asked.
fn measure_view(
    v: &crate::data::View,
    image: &Tensor<f32>,
    scale: &ResolvedScale,
    options: &EvalOptions,
    dir: &Path,
) -> Result<ViewResult, Error> {
    let gt = v.image.to_tensor();
    let metrics = image_metrics(image, &gt).map_err(|e| {
        Error::Input(format!(
            "view {} at scale {}: {e}",
            v.index,
            scale_label(scale.relative)
        ))
    })?;
    if options.save_images {
        let err = error_map(image, &gt).map_err(|e| Error::Input(e.to_string()))?;
        images::save_png(
            &images::to_rgb8(image)?,
            &dir.join(format!("render_{:03}.png", v.index)),
        )?;
        images::save_png(
            &images::error_to_rgb8(&err)?,
            &dir.join(format!("error_{:03}.png", v.index)),
        )?;
    }
    Ok(ViewResult {
        index: v.index,
        time: v.time,
        metrics,
    })
}

/// Picks the Gaussians to show in the nu(t) chart: among Gaussians observed in at
/// least a quarter of the training frames, the one whose motion-aware nu varies least over time ("static") and
/// the one whose nu varies most ("moving"), by the range of its curve relative to
/// its mean.
pub fn pick_static_and_moving(trainer: &Trainer) -> Option<Vec<(usize, String)>> {
    let FilterState::Motion { curves, .. } = &trainer.filter else {
        return None;
    };
    let n = curves.rows().min(trainer.observations.rows());
    // Well-observed Gaussians only: seen in at least a quarter of the training frames.
    let min_obs = (trainer.observations.num_frames() / 4).max(2);
    let mut best: Option<(f32, usize)> = None;
    let mut worst: Option<(f32, usize)> = None;
    for k in 0..n {
        if curves.x_max()[k] <= 0.0 || trainer.observations.observations(k).len() < min_obs {
            continue;
        }
        let c = curves.curve(k);
        let (lo, hi, sum) = c.iter().fold(
            (f32::INFINITY, f32::NEG_INFINITY, 0.0f32),
            |(lo, hi, s), &v| (lo.min(v), hi.max(v), s + v),
        );
        let m = sum / c.len().max(1) as f32;
        if !(m.is_finite() && m > 0.0 && hi.is_finite()) {
            continue;
        }
        let spread = (hi - lo) / m;
        if best.is_none_or(|(b, _)| spread < b) {
            best = Some((spread, k));
        }
        if worst.is_none_or(|(w, _)| spread > w) {
            worst = Some((spread, k));
        }
    }
    let (_, s) = best?;
    let (_, m) = worst?;
    Some(vec![(s, "static".into()), (m, "moving".into())])
}

/// Where [`evaluate_run`] writes the nu(t) traces of a motion-filter run.
pub const FILTER_ANALYSIS_FILE: &str = "filter_analysis.json";

/// The observations and nu(t) curves of a static and a moving Gaussian of a motion
/// run, or `None` for other filters.
pub fn filter_analysis(trainer: &Trainer) -> Option<AnalysisExport> {
    let FilterState::Motion { curves, .. } = &trainer.filter else {
        return None;
    };
    let chosen = pick_static_and_moving(trainer)?;
    AnalysisExport::collect(&trainer.observations, curves, &chosen, None).ok()
}

/// Builds the contract fields that describe the run (everything but `scales`).
pub fn run_report(trainer: &Trainer, data: &Dataset) -> EvalReport {
    let n = trainer.num_gaussians();
    EvalReport {
        model: trainer.model.name().to_string(),
        filter: filter_name(&trainer.filter),
        train_scale: trainer.config.train_scale,
        iterations: trainer.iteration,
        train_seconds: trainer.timings.total(),
        num_gaussians: n,
        model_bytes: trainer.model.num_scalars() as u64 * 4,
        filter_bytes: (trainer.filter.bytes_per_gaussian() * n) as u64,
        background: data.background(),
        quantized_8bit: false,
        scales: Vec::new(),
    }
}

fn filter_name(f: &FilterState) -> String {
    match f {
        FilterState::None { .. } => "none",
        FilterState::Mip3d { .. } => "mip3d",
        FilterState::Motion { .. } => "motion",
    }
    .to_string()
}

/// Evaluates the run in `run` on `data` (the data set it was trained on) at every
/// scale of `options` and writes `RUN/eval.json` plus `RUN/eval/<scale>x/` (renders,
/// error maps, per-view `metrics.csv`) and, for a motion-filter run,
/// `RUN/eval/filter_analysis.json` (nu(t) of a static and a moving Gaussian, for the
/// report's chart). Prints one progress line per scale to stderr.
///
/// Errors (one line, nothing written): no trained model in `run`, a data set that
/// does not match the run, an impossible scale.
pub fn evaluate_run(
    run: &Path,
    data: &Dataset,
    options: &EvalOptions,
) -> Result<EvalReport, Error> {
    let trainer = load_run(run, data)?;
    evaluate_trainer(&trainer, run, data, options)
}

/// [`evaluate_run`] for a run already loaded with [`load_run`] (saves loading it
/// twice when the caller also renders videos).
pub fn evaluate_trainer(
    trainer: &Trainer,
    run: &Path,
    data: &Dataset,
    options: &EvalOptions,
) -> Result<EvalReport, Error> {
    let split = options.split;
    if data.len(split) == 0 {
        return Err(Error::Input(format!(
            "{}: the {split:?} split has no views",
            data.root().display()
        )));
    }
    if options.max_views == Some(0) {
        return Err(Error::Input("--max-views must be at least 1".into()));
    }
    let scales = resolve_scales(data, split, trainer.config.train_scale, &options.scales)?;
    let mut report = run_report(trainer, data);

    let final_dir = run.join("eval");
    let tmp_dir = maaf_io::temp_sibling(&final_dir);
    if tmp_dir.exists() {
        std::fs::remove_dir_all(&tmp_dir).map_err(|e| Error::io(&tmp_dir, e))?;
    }
    let result = (|| {
        let sources: Vec<f64> = scales.iter().map(|s| s.source).collect();
        data.preload(split, &sources)
            .map_err(|e| Error::Input(e.to_string()))?;
        for s in &scales {
            let start = Instant::now();
            let dir = tmp_dir.join(scale_label(s.relative));
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            let views = evaluate_scale(trainer, data, split, s, options, &dir)?;
            let per: Vec<ImageMetrics> = views.iter().map(|v| v.metrics).collect();
            let m =
                mean_metrics(&per).ok_or_else(|| Error::Input("no views were evaluated".into()))?;
            let mut csv = String::from("view,time,psnr,ssim\n");
            for v in &views {
                csv.push_str(&format!(
                    "{},{},{:.6},{:.6}\n",
                    v.index, v.time, v.metrics.psnr, v.metrics.ssim
                ));
            }
            write_atomic(&dir.join("metrics.csv"), csv.as_bytes())?;
            eprintln!(
                "maaf: eval {:>5} {}x{}: PSNR {:.2} dB  SSIM {:.4}  ({} views, {:.1} s)",
                scale_label(s.relative),
                s.width,
                s.height,
                m.psnr,
                m.ssim,
                views.len(),
                start.elapsed().as_secs_f64()
            );
            report.scales.push(ScaleResult {
                scale: s.relative,
                width: s.width,
                height: s.height,
                psnr: m.psnr,
                ssim: m.ssim,
                lpips: None,
                warp_error: None,
            });
        }
        if let Some(export) = filter_analysis(trainer) {
            write_atomic(
                &tmp_dir.join(FILTER_ANALYSIS_FILE),
                export.to_json().as_bytes(),
            )?;
        }
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp_dir);
        return Err(e);
    }
    // Swap the complete folder into place, then write eval.json.
    maaf_io::replace_dir(&tmp_dir, &final_dir).map_err(|e| Error::io(&final_dir, e))?;
    let json =
        serde_json::to_vec_pretty(&report).map_err(|e| Error::Input(format!("eval.json: {e}")))?;
    write_atomic(&run.join("eval.json"), &json)?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels() {
        assert_eq!(scale_label(1.0), "1x");
        assert_eq!(scale_label(0.25), "0.25x");
        assert_eq!(scale_label(4.0), "4x");
        assert_eq!(trim_float(0.125), "0.125");
    }

    #[test]
    fn report_has_the_contract_fields() {
        let r = EvalReport {
            model: "saro".into(),
            filter: "motion".into(),
            train_scale: 0.25,
            iterations: 1,
            train_seconds: 1.0,
            num_gaussians: 2,
            model_bytes: 3,
            filter_bytes: 4,
            background: [1.0; 3],
            quantized_8bit: false,
            scales: vec![ScaleResult {
                scale: 4.0,
                width: 8,
                height: 8,
                psnr: 30.0,
                ssim: 0.9,
                lpips: None,
                warp_error: None,
            }],
        };
        let v: serde_json::Value =
            serde_json::from_slice(&serde_json::to_vec(&r).expect("json")).expect("value");
        let keys: Vec<&str> = v
            .as_object()
            .expect("object")
            .keys()
            .map(String::as_str)
            .collect();
        let mut want = vec![
            "model",
            "filter",
            "train_scale",
            "iterations",
            "train_seconds",
            "num_gaussians",
            "model_bytes",
            "filter_bytes",
            "background",
            "quantized_8bit",
            "scales",
        ];
        want.sort_unstable();
        let mut got = keys.clone();
        got.sort_unstable();
        assert_eq!(got, want);
        assert!(v["scales"][0]["lpips"].is_null());
        assert!(v["scales"][0]["warp_error"].is_null());
    }
}
