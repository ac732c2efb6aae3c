//! One evaluation scale's views rendered and measured (PSNR, SSIM, LPIPS, PSNR by
//! region, error by ring, the registered metrics of one's own) and, when asked,
//! saved as PNGs, with the scale's `metrics.csv`.

use std::path::Path;
use std::time::Instant;

use maaf_autodiff::Tensor;
use maaf_data::{Dataset, Image, Split};
use maaf_lpips::Lpips;
use maaf_scene::TrainedScene;
use maaf_scene::metrics::{ImageMetrics, error_map, image_metrics};
use rayon::prelude::*;

use crate::metrics::regions::{RegionPsnr, region_psnr};
use crate::metrics::rings::RingErrors;
use crate::scales::ResolvedScale;
use crate::{Error, EvalOptions, eval_settings, images, scale_label};

/// Per-view metrics of one scale (written as `RUN/eval/<scale>x/metrics.csv`).
#[derive(Clone, Debug)]
pub(crate) struct ViewResult {
    /// Index of the view in its split.
    pub(crate) index: usize,
    /// Time of the view.
    pub(crate) time: f64,
    /// PSNR and SSIM of the view.
    pub(crate) metrics: ImageMetrics,
    /// LPIPS of the view, or why there is none.
    pub(crate) lpips: Result<f64, String>,
    /// Wall seconds spent in LPIPS for this view.
    pub(crate) lpips_seconds: f64,
    /// PSNR by region, when the data set has the view's moving-object mask.
    pub(crate) regions: Option<RegionPsnr>,
    /// Squared error by distance from the silhouette, when the view has an alpha
    /// coverage.
    pub(crate) rings: Option<RingErrors>,
    /// The value of each of [`EvalOptions::metrics`], in its order.
    pub(crate) extra: Vec<f64>,
}

/// `metrics.csv` of one scale: `view,time,psnr,ssim,lpips`, then a column per metric
/// of `extra` (the names of [`EvalOptions::metrics`]), one row per view (LPIPS empty
/// where it was not computed).
pub(crate) fn metrics_csv(views: &[ViewResult], extra: &[&str]) -> Result<Vec<u8>, Error> {
    let bad = |e: String| Error::Input(format!("metrics.csv: {e}"));
    let mut w = csv::Writer::from_writer(Vec::new());
    let header = ["view", "time", "psnr", "ssim", "lpips"];
    w.write_record(header.iter().chain(extra))
        .map_err(|e| bad(e.to_string()))?;
    for v in views {
        let lpips = v
            .lpips
            .as_ref()
            .map_or(String::new(), |l| format!("{l:.6}"));
        let values = v.extra.iter().map(|x| format!("{x:.6}"));
        w.write_record(
            [
                v.index.to_string(),
                v.time.to_string(),
                format!("{:.6}", v.metrics.psnr),
                format!("{:.6}", v.metrics.ssim),
                lpips,
            ]
            .into_iter()
            .chain(values),
        )
        .map_err(|e| bad(e.to_string()))?;
    }
    w.into_inner().map_err(|e| bad(e.to_string()))
}

/// Renders, measures and (optionally) saves the views `indices` at one scale into `dir`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn evaluate_scale(
    scene: &TrainedScene,
    data: &Dataset,
    split: Split,
    indices: &[usize],
    scale: &ResolvedScale,
    options: &EvalOptions,
    lpips: &Result<Lpips, String>,
    dir: &Path,
) -> Result<Vec<ViewResult>, Error> {
    let views = indices
        .iter()
        .map(|&i| data.view(split, i, scale.source))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| Error::Input(e.to_string()))?;
    let settings = eval_settings(scene, data);
    // The model is not `Sync`: views are rendered one after the other (the renderer
    // is parallel inside), then metrics and PNG encoding run in parallel over a
    // chunk of views (bounded memory: one chunk of float images at a time).
    let mut results = Vec::with_capacity(views.len());
    for chunk in views.chunks(8) {
        let rendered: Vec<Tensor<f32>> = chunk
            .iter()
            .map(|v| scene.render_with(&v.camera, v.time, &settings))
            .collect();
        let masks: Vec<Option<Image>> = chunk
            .iter()
            .map(|v| match split {
                Split::Test => data.moving_mask(v.index, scale.source),
                _ => Ok(None),
            })
            .collect::<Result<_, _>>()
            .map_err(|e| Error::Input(e.to_string()))?;
        let part: Vec<ViewResult> = chunk
            .par_iter()
            .zip(rendered.par_iter().zip(masks.par_iter()))
            .map(|(v, (image, mask))| {
                measure_view(v, image, mask.as_ref(), scale, options, lpips, dir)
            })
            .collect::<Result<_, _>>()?;
        results.extend(part);
    }
    Ok(results)
}

/// Metrics of one rendered view (LPIPS when the model loaded), plus its PNGs when
/// asked (render, error map and ground truth, for the report's pictures).
fn measure_view(
    v: &maaf_data::View,
    image: &Tensor<f32>,
    mask: Option<&Image>,
    scale: &ResolvedScale,
    options: &EvalOptions,
    lpips: &Result<Lpips, String>,
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
    let regions = mask
        .map(|m| region_psnr(image, &gt, &m.data))
        .transpose()
        .map_err(|e| {
            Error::Input(format!(
                "view {} at scale {}: moving mask: {e}",
                v.index,
                scale_label(scale.relative)
            ))
        })?;
    let rings = v
        .coverage
        .as_ref()
        .map(|c| RingErrors::of_view(image, &gt, &c.data))
        .transpose()
        .map_err(|e| {
            Error::Input(format!(
                "view {} at scale {}: alpha coverage: {e}",
                v.index,
                scale_label(scale.relative)
            ))
        })?;
    let extra = options
        .metrics
        .iter()
        .map(|m| match m.compute(image, &gt) {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(x) => Err(format!("metric `{}` is {x}", m.name())),
            Err(e) => Err(format!("metric `{}`: {e}", m.name())),
        })
        .collect::<Result<Vec<f64>, String>>()
        .map_err(|e| {
            Error::Input(format!(
                "view {} at scale {}: {e}",
                v.index,
                scale_label(scale.relative)
            ))
        })?;
    let start = Instant::now();
    let lpips = match lpips {
        Ok(model) => model.distance(image, &gt).map_err(|e| e.to_string()),
        Err(reason) => Err(reason.clone()),
    };
    let lpips_seconds = start.elapsed().as_secs_f64();
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
        images::save_png(
            &images::to_rgb8(&gt)?,
            &dir.join(format!("gt_{:03}.png", v.index)),
        )?;
    }
    Ok(ViewResult {
        index: v.index,
        time: v.time,
        metrics,
        lpips,
        lpips_seconds,
        regions,
        rings,
        extra,
    })
}
