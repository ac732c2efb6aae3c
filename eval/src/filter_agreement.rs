//! Where a motion-aware filter could differ from the static one, measured on the
//! trained model: for every Gaussian and time bin at which it is drawn (opacity at
//! that time, temporal factor and filter compensation included, at least 1/255),
//! the ratio `nu(t) / nu_static` of each estimator's sampling rate to
//! Mip-Splatting's static nu on the canonical centres (paper Eq. 2, what the
//! `mip3d` filter uses). A ratio of 1 means the same filter; below 1 the
//! motion-aware filter is wider (`s / nu^2` grows as `1 / ratio^2`).
//!
//! Both estimators (the paper's KDE and maaf's windowed maximum) are recomputed from
//! the run's observation table, whichever the run trained with, so one run shows
//! how far either could move the filter away from the static one. The same
//! distribution is also given for the *moving* Gaussians alone: those whose drawn
//! centres span a bounding box with a diagonal of at least [`MOVING`] times the
//! camera extent (most Gaussians of a dynamic scene are static background).
//!
//! The same measurement picks the Gaussians of the report's nu(t) chart
//! ([`FilterStudy::analysis`]): the one whose drawn centre moves most and one that
//! does not move, with both estimators' curves and the static nu.

use maaf_autodiff::PerGaussian;
use maaf_filter::{AnalysisExport, FilterKind, FilterState, MotionCurves, MotionEstimator};
use serde::{Deserialize, Serialize};

use maaf_scene::TrainedScene;

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
    /// `"kde"` (the paper's) or `"window_max"` (maaf's).
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
pub fn filter_agreement(scene: &TrainedScene) -> Option<FilterAgreement> {
    FilterStudy::of(scene)?.agreement()
}

/// What `maaf eval` measures of a motion run's filter, computed once: the static nu,
/// both estimators' curves recomputed from the run's observations, and where the
/// model draws each Gaussian at every time bin.
pub struct FilterStudy<'a> {
    scene: &'a TrainedScene,
    /// Mip-Splatting's static nu on the canonical centres.
    nu_static: Vec<f32>,
    /// The curves of [`ESTIMATORS`], in that order.
    curves: Vec<MotionCurves>,
    drawn: DrawnPairs,
}

/// The estimators both outputs compare: the paper's and maaf's.
const ESTIMATORS: [MotionEstimator; 2] = [MotionEstimator::Kde, MotionEstimator::WindowMax];

impl<'a> FilterStudy<'a> {
    /// The study of `scene`'s run, or `None` when it is not a motion run or its
    /// curves or static nu cannot be computed (nothing observed).
    pub fn of(scene: &'a TrainedScene) -> Option<Self> {
        let cfg = &scene.config.filter;
        if cfg.kind != FilterKind::Motion {
            return None;
        }
        let nu_static = scene.static_nu().ok()?;
        let curves: Vec<MotionCurves> = ESTIMATORS
            .iter()
            .map(|&estimator| {
                let c = maaf_filter::FilterConfig {
                    estimator,
                    ..cfg.clone()
                };
                MotionCurves::refresh(&scene.observations, &c).ok()
            })
            .collect::<Option<_>>()?;
        let drawn = DrawnPairs::of(scene, &curves[0]);
        Some(FilterStudy {
            scene,
            nu_static,
            curves,
            drawn,
        })
    }

    /// The distribution of `nu(t) / nu_static` over the drawn pairs, all and moving
    /// (`None` when no Gaussian is drawn).
    pub fn agreement(&self) -> Option<FilterAgreement> {
        let who = &self.drawn.pairs;
        if who.is_empty() {
            return None;
        }
        let moving = |n: usize| self.drawn.motion[n] >= MOVING;
        let ratios = |only_moving: bool| -> Vec<Vec<f64>> {
            self.curves
                .iter()
                .map(|c| {
                    who.iter()
                        .filter(|&&(n, _)| !only_moving || moving(n))
                        .map(|&(n, s)| f64::from(c.nu(n, s)) / f64::from(self.nu_static[n]))
                        .collect()
                })
                .collect()
        };
        let summaries = |rs: Vec<Vec<f64>>| -> Vec<RatioSummary> {
            if rs[0].is_empty() {
                return Vec::new();
            }
            ESTIMATORS
                .iter()
                .zip(rs)
                .map(|(&e, r)| summarise(e, r))
                .collect()
        };
        let seen = |n: usize| self.drawn.bins[n] > 0;
        let rows = self.nu_static.len();
        let moving_ratios = ratios(true);
        Some(FilterAgreement {
            pairs: who.len(),
            gaussians: (0..rows).filter(|&n| seen(n)).count(),
            moving_pairs: moving_ratios[0].len(),
            moving_gaussians: (0..rows).filter(|&n| seen(n) && moving(n)).count(),
            ratios: summaries(ratios(false)),
            moving_ratios: summaries(moving_ratios),
        })
    }

    /// The report's nu(t) chart data: the Gaussian whose drawn centre moves most
    /// (labelled "moving" when it reaches [`MOVING`], else "most mobile") and the one
    /// that moves least ("static"), among those drawn at a quarter of the time bins
    /// and observed in a quarter of the training frames. Each trace holds the curve
    /// the run's filter uses, the other estimator's curve, the static nu and the drawn
    /// motion. `None` when no Gaussian qualifies.
    pub fn analysis(&self) -> Option<AnalysisExport> {
        let FilterState::Motion { curves, .. } = &self.scene.filter else {
            return None;
        };
        let table = &self.scene.observations;
        let min_obs = (table.num_frames() / 4).max(2);
        let min_bins = (self.curves[0].grid_t() / 4).max(1);
        let rows = curves.rows().min(table.rows()).min(self.nu_static.len());
        let candidates: Vec<usize> = (0..rows)
            .filter(|&n| {
                self.drawn.bins[n] >= min_bins
                    && curves.x_max()[n] > 0.0
                    && table.observations(n).len() >= min_obs
            })
            .collect();
        let motion = |a: &usize, b: &usize| self.drawn.motion[*a].total_cmp(&self.drawn.motion[*b]);
        // Among equally still Gaussians, the one drawn at the most bins.
        let still = candidates
            .iter()
            .copied()
            .min_by(|a, b| motion(a, b).then(self.drawn.bins[*b].cmp(&self.drawn.bins[*a])))?;
        let mobile = candidates.iter().copied().max_by(motion)?;
        let label = if self.drawn.motion[mobile] >= MOVING {
            "moving"
        } else {
            "most mobile"
        };
        let chosen = [(still, "static".to_string()), (mobile, label.to_string())];
        let used = self.scene.config.filter.estimator;
        let mut export =
            AnalysisExport::collect(table, curves, used, &chosen, Some(&self.nu_static)).ok()?;
        for (&e, c) in ESTIMATORS.iter().zip(&self.curves) {
            if e != used {
                export.compare(e, c).ok()?;
            }
        }
        for g in &mut export.gaussians {
            g.drawn_motion = Some(self.drawn.motion[g.index] as f32);
        }
        Some(export)
    }
}

/// Where the model draws its Gaussians over a curve grid's time bins.
struct DrawnPairs {
    /// The drawn (Gaussian, time bin) pairs.
    pairs: Vec<(usize, usize)>,
    /// Per Gaussian: the diagonal of its drawn centres' bounding box over the camera
    /// extent (0 when drawn at fewer than two bins).
    motion: Vec<f64>,
    /// Per Gaussian: how many bins it is drawn at.
    bins: Vec<usize>,
}

impl DrawnPairs {
    /// Deforms the model (no render) at every time bin of `grid` and keeps the pairs
    /// whose opacity reaches [`DRAWN`], with each Gaussian's drawn-centre motion.
    fn of(scene: &TrainedScene, grid: &MotionCurves) -> Self {
        let n = grid.rows();
        let mut pairs = Vec::new();
        let mut bins = vec![0; n];
        let (mut lo, mut hi) = (vec![[f32::INFINITY; 3]; n], vec![[f32::NEG_INFINITY; 3]; n]);
        for s in 0..grid.grid_t() {
            let [means, _, _, opacity, _] = scene.model_gaussians_at(f64::from(grid.bin_time(s)));
            let centres = means.data().chunks_exact(3);
            for (k, (&o, p)) in opacity.data().iter().zip(centres).enumerate().take(n) {
                if o < DRAWN {
                    continue;
                }
                pairs.push((k, s));
                bins[k] += 1;
                for d in 0..3 {
                    lo[k][d] = lo[k][d].min(p[d]);
                    hi[k][d] = hi[k][d].max(p[d]);
                }
            }
        }
        // One camera centre has no extent: then any drawn motion counts as moving.
        let extent = scene.extent().max(f64::MIN_POSITIVE);
        let motion = lo
            .iter()
            .zip(&hi)
            .zip(&bins)
            .map(|((a, b), &count)| {
                if count < 2 {
                    return 0.0;
                }
                let d2: f64 = (0..3).map(|d| f64::from(b[d] - a[d]).powi(2)).sum();
                d2.sqrt() / extent
            })
            .collect();
        DrawnPairs {
            pairs,
            motion,
            bins,
        }
    }
}

/// Percentiles and shares of one estimator's ratios.
fn summarise(estimator: MotionEstimator, mut r: Vec<f64>) -> RatioSummary {
    r.sort_by(f64::total_cmp);
    let q = |p: f64| r[((r.len() - 1) as f64 * p).round() as usize];
    let share =
        |f: &dyn Fn(f64) -> bool| r.iter().filter(|&&v| f(v)).count() as f64 / r.len() as f64;
    RatioSummary {
        estimator: estimator.name().into(),
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
        let all = format!(
            "nu(t)/nu_static over {} drawn pairs of {} Gaussians: {}",
            self.pairs,
            self.gaussians,
            line(&self.ratios)
        );
        if self.moving_ratios.is_empty() {
            return format!("{all}; no moving Gaussian");
        }
        format!(
            "{all}; over the {} pairs of {} moving Gaussians: {}",
            self.moving_pairs,
            self.moving_gaussians,
            line(&self.moving_ratios)
        )
    }
}
