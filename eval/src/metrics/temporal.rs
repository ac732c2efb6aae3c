//! Temporal stability of a fixed-camera video (paper supplementary, "Temporal
//! Stability Metrics"): W-Temporal Error, W-SSIM and W-LPIPS of frames warped along
//! the forward flow.
//!
//! Flow convention ([`maaf_data::flow`], as the built-in generator writes it): for
//! the pixel `(x, y)` of frame `t`, whose centre is `(x + 0.5, y + 0.5)`, the flow
//! `(dx, dy)` points to where the same surface point is in frame `t + 1`; channel 2 is
//! 1 when that point is visible in frame `t + 1`. The exact flow of the built-in scene
//! and model flow ([`crate::flow`], a depth-consistency test) share this meaning,
//! so [`warp_forward`] treats their invalid pixels alike (frame `t` is kept there).

use maaf_autodiff::{Float, Tensor};
use maaf_lpips::{Lpips, LpipsError};
use maaf_scene::metrics::{MetricError, image_dims, ssim};
use rayon::prelude::*;

/// Why the temporal metrics could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum TemporalError {
    /// Frames of different shapes, or a frame that is not an image, or too small.
    #[error("temporal metrics: {0}")]
    Metric(#[from] MetricError),
    /// LPIPS failed on a warped pair.
    #[error("temporal metrics: {0}")]
    Lpips(#[from] LpipsError),
    /// A flow is not `[H, W, 3]` for `[H, W, C]` frames.
    #[error("temporal metrics: flow {index} has shape {shape:?}, expected [{h}, {w}, 3]")]
    FlowShape {
        /// Index `t` of the flow (from frame `t` to `t + 1`).
        index: usize,
        /// Its shape.
        shape: Vec<usize>,
        /// Frame height.
        h: usize,
        /// Frame width.
        w: usize,
    },
    /// Not `T >= 2` frames and `T - 1` flows.
    #[error(
        "temporal metrics need T >= 2 frames and T - 1 flows, got {frames} frames and {flows} flows"
    )]
    Count {
        /// Number of frames.
        frames: usize,
        /// Number of flows.
        flows: usize,
    },
}

/// Frame `t + 1` warped back onto frame `t` with the forward flow `F_{t -> t+1}`
/// (paper supplementary: "initialize the warped frame as I_t, then move pixels
/// according to the flow, overwriting target locations and leaving occluded regions
/// with their original values from I_t").
///
/// `warped = frame_t`; then for every pixel `p = (x, y)` of frame `t` whose flow is
/// valid, the pixel of frame `t + 1` that contains the moved centre,
/// `q = (floor(x + 0.5 + dx), floor(y + 0.5 + dy))`, is moved onto `p`:
/// `warped[p] = frame_next[q]` (nearest pixel, no interpolation). Pixels with invalid
/// flow (occluded in `t + 1`) or whose `q` leaves the image keep `frame_t[p]`. With a
/// flow defined on frame `t`'s pixels each target is written at most once.
///
/// `frame_next` and `frame_t` are `[H, W, C]`, `flow` is `[H, W, 3]`.
pub fn warp_forward<T: Float>(
    frame_next: &Tensor<T>,
    frame_t: &Tensor<T>,
    flow: &Tensor<T>,
) -> Result<Tensor<T>, TemporalError> {
    let (h, w, c) = image_dims(frame_next, frame_t)?;
    if flow.shape() != [h, w, 3] {
        return Err(TemporalError::FlowShape {
            index: 0,
            shape: flow.shape().to_vec(),
            h,
            w,
        });
    }
    let (next, f) = (frame_next.data(), flow.data());
    let mut out = frame_t.data().to_vec();
    out.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            let v = &f[(y * w + x) * 3..(y * w + x) * 3 + 3];
            if Float::to_f64(v[2]) < 0.5 {
                continue;
            }
            let qx = (x as f64 + 0.5 + Float::to_f64(v[0])).floor();
            let qy = (y as f64 + 0.5 + Float::to_f64(v[1])).floor();
            // Written so that a NaN flow also fails the test and keeps frame t.
            if !(qx >= 0.0 && qy >= 0.0 && qx < w as f64 && qy < h as f64) {
                continue;
            }
            let q = (qy as usize * w + qx as usize) * c;
            row[x * c..(x + 1) * c].copy_from_slice(&next[q..q + c]);
        }
    });
    Ok(Tensor::from_vec(out, &[h, w, c]))
}

/// Flow warping error of one step (paper supplementary, Eq. "E_warp"):
/// `E_warp(I_t, I_{t+1}) = (1 / N) sum_{i=1..N} |I_t^(i) - Î_{t+1}^(i)|_2^2`, `N = H W`
/// pixels and `|.|_2^2` the squared norm over the `C` channels, i.e. `C` times the
/// per-value mean squared error. Accumulated in f64.
pub fn warp_error<T: Float>(frame_t: &Tensor<T>, warped: &Tensor<T>) -> Result<f64, TemporalError> {
    let (h, w, _) = image_dims(warped, frame_t)?;
    let total: f64 = frame_t
        .data()
        .iter()
        .zip(warped.data())
        .map(|(&a, &b)| {
            let d = Float::to_f64(a) - Float::to_f64(b);
            d * d
        })
        .sum();
    Ok(total / (h * w) as f64)
}

/// Metrics of one step `t -> t + 1`, all between `I_t` and `Î_{t+1}` ([`warp_forward`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepMetrics {
    /// [`warp_error`].
    pub warp_error: f64,
    /// Evaluation SSIM ([`ssim`]) of `Î_{t+1}` against `I_t`.
    pub ssim: f64,
    /// LPIPS ([`maaf_lpips::Lpips::distance`]) when a model was given.
    pub lpips: Option<f64>,
}

/// Temporal stability of a video (paper supplementary):
/// `W-Temporal Error = sum_{t=1}^{T-1} E_warp(I_t, I_{t+1})` (a sum, not a mean),
/// `W-SSIM = (1 / (T-1)) sum_t SSIM(I_t, Î_{t+1})`,
/// `W-LPIPS = (1 / (T-1)) sum_t LPIPS(I_t, Î_{t+1})`.
#[derive(Clone, Debug, PartialEq)]
pub struct TemporalMetrics {
    /// One entry per step `t -> t + 1` (the warping error over time, for the chart).
    pub per_step: Vec<StepMetrics>,
    /// W-Temporal Error (lower is better).
    pub warp_error: f64,
    /// W-SSIM (higher is better).
    pub w_ssim: f64,
    /// W-LPIPS (lower is better); `None` without an LPIPS model.
    pub w_lpips: Option<f64>,
}

/// [`TemporalMetrics`] of `T` frames `[H, W, 3]` on [0, 1] and the `T - 1` forward
/// flows `[H, W, 3]` between them (`flows[t]` from frame `t` to `t + 1`). Frames must
/// be at least 11 x 11 (SSIM window), and at least [`maaf_lpips::Net::min_size`] with LPIPS.
pub fn temporal_metrics(
    frames: &[Tensor<f32>],
    flows: &[Tensor<f32>],
    lpips: Option<&Lpips>,
) -> Result<TemporalMetrics, TemporalError> {
    if frames.len() < 2 || flows.len() + 1 != frames.len() {
        return Err(TemporalError::Count {
            frames: frames.len(),
            flows: flows.len(),
        });
    }
    let mut per_step = Vec::with_capacity(flows.len());
    for (t, flow) in flows.iter().enumerate() {
        let warped = warp_forward(&frames[t + 1], &frames[t], flow).map_err(|e| match e {
            TemporalError::FlowShape { shape, h, w, .. } => TemporalError::FlowShape {
                index: t,
                shape,
                h,
                w,
            },
            other => other,
        })?;
        per_step.push(StepMetrics {
            warp_error: warp_error(&frames[t], &warped)?,
            ssim: ssim(&warped, &frames[t])?,
            lpips: lpips.map(|m| m.distance(&warped, &frames[t])).transpose()?,
        });
    }
    let n = per_step.len() as f64;
    Ok(TemporalMetrics {
        warp_error: per_step.iter().map(|s| s.warp_error).sum(),
        w_ssim: per_step.iter().map(|s| s.ssim).sum::<f64>() / n,
        w_lpips: lpips.map(|_| per_step.iter().filter_map(|s| s.lpips).sum::<f64>() / n),
        per_step,
    })
}
