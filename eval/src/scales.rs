//! Which scales and views an evaluation scores, settled before anything is rendered:
//! every scale checked against the data (skipped with its reason when its ground truth
//! cannot be made or scored), and the split's views at every `frame_stride`-th time.

use maaf_data::{Dataset, Split};

use crate::{Error, EvalOptions, SkippedScale, trim_float};

/// One resolved evaluation scale: relative, source-relative, output size.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ResolvedScale {
    /// The scale relative to the run's training scale.
    pub(crate) relative: f64,
    /// The scale relative to the source images.
    pub(crate) source: f64,
    /// Output width, pixels.
    pub(crate) width: u32,
    /// Output height, pixels.
    pub(crate) height: u32,
}

/// Checks every scale against the data before anything is rendered: positive,
/// finite and not repeated, else an error. A scale whose ground truth cannot be made
/// (more pixels than the source images, or a downsampling factor that does not divide
/// them) or cannot be scored (images smaller than the SSIM window) is skipped with its
/// reason; an error only when every scale is.
fn resolve_scales(
    data: &Dataset,
    split: Split,
    train_scale: f64,
    scales: &[f64],
) -> Result<(Vec<ResolvedScale>, Vec<SkippedScale>), Error> {
    if scales.is_empty() {
        return Err(Error::Input("no evaluation scale given".into()));
    }
    let meta = data.split(split).map_err(|e| Error::Input(e.to_string()))?;
    let (sw, sh) = (meta.width, meta.height);
    let mut out: Vec<ResolvedScale> = Vec::new();
    let mut skipped = Vec::new();
    for (i, &s) in scales.iter().enumerate() {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::Input(format!(
                "scale {s}: must be a positive number (relative to the training scale, e.g. 0.25,0.5,1,2,4)"
            )));
        }
        if scales[..i].iter().any(|r| (r - s).abs() < 1e-9) {
            return Err(Error::Input(format!("scale {s} is given twice")));
        }
        let source = train_scale * s;
        let size = if source > 1.0 + 1e-9 {
            Err(format!(
                "needs {}x{} ground truth but the source images are {sw}x{sh} (training scale {}: at most {}x)",
                (sw as f64 * source).round(),
                (sh as f64 * source).round(),
                trim_float(train_scale),
                trim_float(1.0 / train_scale)
            ))
        } else {
            data.size(split, source)
                .map_err(|e| format!("source scale {}: {e}", trim_float(source)))
                .and_then(|(w, h)| {
                    let window = maaf_scene::metrics::ssim_window::SSIM_WINDOW as u32;
                    if w < window || h < window {
                        Err(format!(
                            "its {w}x{h} images are smaller than the {window}x{window} SSIM window"
                        ))
                    } else {
                        Ok((w, h))
                    }
                })
        };
        match size {
            Ok((width, height)) => out.push(ResolvedScale {
                relative: s,
                source,
                width,
                height,
            }),
            Err(reason) => skipped.push(SkippedScale { scale: s, reason }),
        }
    }
    if out.is_empty() {
        let why: Vec<String> = skipped
            .iter()
            .map(|k| format!("{}x {}", trim_float(k.scale), k.reason))
            .collect();
        return Err(Error::Input(format!(
            "{}: none of the scales can be evaluated: {}",
            data.root().display(),
            why.join("; ")
        )));
    }
    Ok((out, skipped))
}

/// Checks `options` against `data` for a run trained at `train_scale`, as an
/// evaluation does before rendering anything: the split has views, `max_views` and
/// `frame_stride` are at least 1, and every scale is valid and at least one can be
/// evaluated (`resolve_scales`; the others are skipped).
/// A caller that plans evaluations (a suite, before training its runs) calls it to
/// refuse an evaluation that could never run.
pub fn check_eval_options(
    data: &Dataset,
    train_scale: f64,
    options: &EvalOptions,
) -> Result<(), Error> {
    checked_scales(data, train_scale, options).map(|_| ())
}

/// [`check_eval_options`], returning the resolved scales and the skipped ones.
pub(crate) fn checked_scales(
    data: &Dataset,
    train_scale: f64,
    options: &EvalOptions,
) -> Result<(Vec<ResolvedScale>, Vec<SkippedScale>), Error> {
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
    if options.frame_stride == 0 {
        return Err(Error::Input("--frame-stride must be at least 1".into()));
    }
    resolve_scales(data, split, train_scale, &options.scales)
}

/// The views of `split` at every `stride`-th distinct time (ranked in time order),
/// in split order, then at most `max` of them.
pub(crate) fn strided_views(
    data: &Dataset,
    split: Split,
    stride: usize,
    max: Option<usize>,
) -> Vec<usize> {
    let times = data.times(split);
    let mut distinct = times.clone();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    let mut out: Vec<usize> = (0..times.len())
        .filter(|&i| {
            distinct
                .binary_search_by(|t| t.total_cmp(&times[i]))
                .is_ok_and(|rank| rank % stride == 0)
        })
        .collect();
    if let Some(n) = max {
        out.truncate(n);
    }
    out
}
