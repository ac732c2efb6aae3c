//! Filter refreshes, outside the tape: static nu from the canonical centres
//! (`mip3d`), nu(t) from the recorded observations (`motion`; paper Alg. 1).

use maaf_autodiff::Tensor;
use maaf_filter::{FilterError, FilterKind, FilterState, MotionCurves, static_nu};

use super::{Trainer, log_line};

/// Rows of an `[N, 3]` tensor as points (the observation table's input).
pub(super) fn centres(t: &Tensor<f32>) -> Vec<[f32; 3]> {
    t.data()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}

impl Trainer {
    /// Computes the filter if no step or checkpoint has yet (Mip-Splatting computes
    /// it once before training): for `motion` a full observation pass over every
    /// training (camera, time) first, with the deformed centres of each distinct
    /// time (the field is queried once). Called by the first [`Trainer::step`];
    /// call it before rendering a trainer that has not stepped.
    pub fn ensure_filter(&mut self) {
        if self.filter_ready {
            return;
        }
        self.filter_ready = true;
        if self.config.filter.kind == FilterKind::Motion {
            let mut times: Vec<f32> = self.observed.iter().map(|f| f.time).collect();
            times.sort_by(f32::total_cmp);
            times.dedup();
            let at: Vec<f64> = times.iter().map(|&t| f64::from(t)).collect();
            let all = self.model.centres_at_times(&at);
            let result = self.observations.observe_all(
                &self.observed,
                &self.cameras,
                &self.config.filter,
                |t| {
                    let k = times.partition_point(|&x| x < t).min(all.len() - 1);
                    centres(&all[k])
                },
            );
            if let Err(e) = result {
                log_line(&format!("observation pass failed: {e}"));
            }
        }
        self.refresh_filter();
    }

    /// Mip-Splatting's static nu (paper Eq. 2) of the canonical centres from the
    /// training cameras: what the `mip3d` filter uses.
    pub(crate) fn static_nu(&self) -> Result<Vec<f32>, FilterError> {
        let canon = centres(&self.model.canonical().means);
        static_nu(&canon, &self.cameras, &self.config.filter)
    }

    /// Recomputes the 3D filter: static nu from the canonical centres for `mip3d`,
    /// nu(t) from the recorded observations for `motion`. On a failure (logged) the
    /// previous filter stays.
    pub fn refresh_filter(&mut self) {
        let n = self.model.num_gaussians();
        let cfg = &self.config.filter;
        self.filter = match cfg.kind {
            FilterKind::None => FilterState::None { rows: n },
            FilterKind::Mip3d => match self.static_nu() {
                Ok(nu) => FilterState::Mip3d { s3d: cfg.s3d, nu },
                Err(e) => {
                    log_line(&format!("filter refresh skipped: {e}"));
                    return;
                }
            },
            FilterKind::Motion => match MotionCurves::refresh(&self.observations, cfg) {
                Ok(curves) => FilterState::Motion {
                    s3d: cfg.s3d,
                    curves,
                },
                Err(e) => {
                    log_line(&format!("filter refresh skipped: {e}"));
                    return;
                }
            },
        };
    }
}
