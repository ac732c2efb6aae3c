//! Where a motion-aware filter could differ from the static one, measured on the
//! trained model: for every Gaussian and time bin at which it is drawn (opacity at
//! that time, temporal factor and filter compensation included, at least 1/255),
//! the ratio `nu(t) / nu_static` of each estimator's sampling rate to
//! Mip-Splatting's static nu on the canonical centres (paper Eq. 2, what the
//! `mip3d` filter uses). A ratio of 1 means the same filter; below 1 the
//! motion-aware filter is wider (`s / nu^2` grows as `1 / ratio^2`).
//!
//! Both estimators (the paper's KDE and our windowed maximum) are recomputed from
//! the run's observation table, whichever the run trained with, so one run shows
//! how far either could move the filter away from the static one. The same
//! distribution is also given for the *moving* Gaussians alone: those whose drawn
//! centres span a bounding box with a diagonal of at least [`MOVING`] times the
//! camera extent (most Gaussians of a dynamic scene are static background).

use maaf_filter::{FilterKind, MotionCurves, MotionEstimator};
use serde::{Deserialize, Serialize};

use crate::trainer::{Trainer, camera_extent};

/// Where `maaf eval` writes the agreement of a motion-filter run (in `RUN/eval/`).
pub const FILTER_AGREEMENT_FILE: &str = "filter_agreement.json";

/// Drawn opacity from which a Gaussian counts at a time (3DGS's alpha floor).
const DRAWN: f32 = 1.0 / 255.0;

/// A Gaussian is moving when its drawn centres span at least this fraction of the
/// camera extent (3DGS's scene radius).
pub const MOVING: f64 = 0.05;

/// Distribution of `nu(t) / nu_static` over the drawn (Gaussian, time bin) pairs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RatioSummary {
    /// `"kde"` (the paper's) or `"window_max"` (ours).
    pub estimator: String,
    /// 5th, 50th and 95th percentiles of the ratio.
    pub p05: f64,
    /// Median ratio.
    pub p50: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Share of pairs with ratio below 0.9 (filter over 23 % wider in variance).
    pub below_0_9: f64,
    /// Share of pairs with ratio above 1.1.
    pub above_1_1: f64,
}

/// [`filter_agreement`]'s result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FilterAgreement {
    /// Drawn (Gaussian, time bin) pairs measured.
    pub pairs: usize,
    /// Gaussians drawn at some bin.
    pub gaussians: usize,
    /// One summary per estimator, over all drawn pairs.
    pub ratios: Vec<RatioSummary>,
    /// Drawn pairs of moving Gaussians.
    pub moving_pairs: usize,
    /// Moving Gaussians (drawn centres span [`MOVING`] x the camera extent).
    pub moving_gaussians: usize,
    /// One summary per estimator over the moving Gaussians' pairs (empty if none).
    pub moving_ratios: Vec<RatioSummary>,
}

/// Measures the agreement of a motion-filter run (`None` for other filters, or when
/// no Gaussian is drawn or observed).
pub fn filter_agreement(trainer: &Trainer) -> Option<FilterAgreement> {
    let cfg = &trainer.config.filter;
    if cfg.kind != FilterKind::Motion {
        return None;
    }
    let nu_static = trainer.static_nu().ok()?;
    let estimators = [MotionEstimator::Kde, MotionEstimator::WindowMax];
    let curves: Vec<MotionCurves> = estimators
        .iter()
        .map(|&estimator| {
            let c = maaf_filter::FilterConfig {
                estimator,
                ..cfg.clone()
            };
            MotionCurves::refresh(&trainer.observations, &c).ok()
        })
        .collect::<Option<_>>()?;
    let drawn = drawn_pairs(trainer, &curves, &nu_static);
    if drawn.who.is_empty() {
        return None;
    }
    let DrawnPairs {
        who,
        ratios,
        moving,
    } = drawn;
    let moving_ratios: Vec<Vec<f64>> = ratios
        .iter()
        .map(|r| {
            r.iter()
                .zip(&who)
                .filter(|(_, n)| moving[**n])
                .map(|(v, _)| *v)
                .collect()
        })
        .collect();
    let summaries = |rs: Vec<Vec<f64>>| -> Vec<RatioSummary> {
        if rs[0].is_empty() {
            return Vec::new();
        }
        estimators
            .iter()
            .zip(rs)
            .map(|(&e, r)| summarise(e, r))
            .collect()
    };
    let mut seen = vec![false; nu_static.len()];
    who.iter().for_each(|&n| seen[n] = true);
    Some(FilterAgreement {
        pairs: who.len(),
        gaussians: seen.iter().filter(|&&d| d).count(),
        moving_pairs: moving_ratios[0].len(),
        moving_gaussians: moving.iter().zip(&seen).filter(|(m, d)| **m && **d).count(),
        ratios: summaries(ratios),
        moving_ratios: summaries(moving_ratios),
    })
}

/// The drawn (Gaussian, time bin) pairs of a run.
struct DrawnPairs {
    /// The Gaussian of each pair.
    who: Vec<usize>,
    /// Per estimator, the ratio `nu(t) / nu_static` of each pair.
    ratios: Vec<Vec<f64>>,
    /// Per Gaussian: its drawn centres span [`MOVING`] x the camera extent.
    moving: Vec<bool>,
}

/// Deforms the model (no render) at every time bin of `curves` and keeps the pairs
/// whose opacity reaches [`DRAWN`], with each curve's ratio to `nu_static`, and
/// marks the Gaussians whose drawn centres move.
fn drawn_pairs(trainer: &Trainer, curves: &[MotionCurves], nu_static: &[f32]) -> DrawnPairs {
    let n = nu_static.len();
    let mut who = Vec::new();
    let mut ratios = vec![Vec::new(); curves.len()];
    let (mut lo, mut hi) = (vec![[f32::INFINITY; 3]; n], vec![[f32::NEG_INFINITY; 3]; n]);
    for s in 0..curves[0].grid_t() {
        let [means, _, _, opacity, _] = trainer.frame_at(f64::from(curves[0].bin_time(s)));
        let centres = means.data().chunks_exact(3);
        for (k, (&o, p)) in opacity.data().iter().zip(centres).enumerate() {
            if o < DRAWN {
                continue;
            }
            who.push(k);
            for (r, c) in ratios.iter_mut().zip(curves) {
                r.push(f64::from(c.nu(k, s)) / f64::from(nu_static[k]));
            }
            for d in 0..3 {
                lo[k][d] = lo[k][d].min(p[d]);
                hi[k][d] = hi[k][d].max(p[d]);
            }
        }
    }
    let min_span = MOVING * camera_extent(trainer.cameras());
    let moving = lo
        .iter()
        .zip(&hi)
        .map(|(a, b)| {
            let d2: f64 = (0..3).map(|d| f64::from(b[d] - a[d]).powi(2)).sum();
            d2.is_finite() && d2.sqrt() >= min_span
        })
        .collect();
    DrawnPairs {
        who,
        ratios,
        moving,
    }
}

/// Percentiles and shares of one estimator's ratios.
fn summarise(estimator: MotionEstimator, mut r: Vec<f64>) -> RatioSummary {
    r.sort_by(f64::total_cmp);
    let q = |p: f64| r[((r.len() - 1) as f64 * p).round() as usize];
    let share =
        |f: &dyn Fn(f64) -> bool| r.iter().filter(|&&v| f(v)).count() as f64 / r.len() as f64;
    RatioSummary {
        estimator: match estimator {
            MotionEstimator::Kde => "kde",
            MotionEstimator::WindowMax => "window_max",
        }
        .into(),
        p05: q(0.05),
        p50: q(0.5),
        p95: q(0.95),
        below_0_9: share(&|v| v < 0.9),
        above_1_1: share(&|v| v > 1.1),
    }
}

impl FilterAgreement {
    /// The console line: every drawn pair, then the moving Gaussians' pairs.
    pub fn summary(&self) -> String {
        let line = |rs: &[RatioSummary]| {
            rs.iter()
                .map(|r| {
                    format!(
                        "{} p05 {:.3} p50 {:.3} p95 {:.3}, {:.1} % < 0.9, {:.1} % > 1.1",
                        r.estimator,
                        r.p05,
                        r.p50,
                        r.p95,
                        100.0 * r.below_0_9,
                        100.0 * r.above_1_1
                    )
                })
                .collect::<Vec<_>>()
                .join("; ")
        };
        format!(
            "nu(t)/nu_static over {} drawn pairs of {} Gaussians: {}; over the {} pairs of {} moving Gaussians: {}",
            self.pairs,
            self.gaussians,
            line(&self.ratios),
            self.moving_pairs,
            self.moving_gaussians,
            line(&self.moving_ratios)
        )
    }
}
