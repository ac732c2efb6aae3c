//! The motion-aware filter's refresh: nu_k(t) from the recorded observations by the
//! configured estimator, the paper's KDE (`kde.rs`) or maaf's windowed maximum
//! (`window_max.rs`), stored as [`MotionCurves`] (`curves.rs`); and the
//! [`SamplingFilter`] that uses it, [`MotionFilter`].

use crate::config::{FilterConfig, FilterError, MotionEstimator};
use crate::curves::MotionCurves;
use crate::observations::ObservationTable;
use crate::sampling::{FilterInputs, SamplingFilter};
use crate::state::FilterState;
use crate::{kde, window_max};

impl MotionCurves {
    /// Recomputes every Gaussian's curve from `table` with `cfg.estimator`: the
    /// fast path of Algorithm 1 (the paper's KDE) or maaf's windowed maximum
    /// (`window_max.rs`), parallel over Gaussians. Errors with the config error if `cfg` is invalid
    /// (re-checked here, it costs nothing) and with [`FilterError::NothingVisible`]
    /// if the table has Gaussians but no observation.
    pub fn refresh(table: &ObservationTable, cfg: &FilterConfig) -> Result<Self, FilterError> {
        cfg.validate()?;
        let (codes, x_max) = match cfg.estimator {
            MotionEstimator::Kde => kde::codes(table, cfg),
            MotionEstimator::WindowMax => window_max::codes(table, cfg),
        };
        MotionCurves::from_codes(cfg, codes, x_max)
    }
}

/// The motion-aware filter: nu_k(t) from the recorded observations by its
/// estimator, the paper's KDE of Algorithm 1 (`filter.kind = "motion"`, registered as
/// `motion`) or maaf's windowed maximum, the largest f/d observed within `h_t` of t
/// (`estimator = "window_max"`, registered as `window_max`; `window_max.rs`).
#[derive(Clone, Copy, Debug)]
pub struct MotionFilter(pub MotionEstimator);

impl SamplingFilter for MotionFilter {
    fn name(&self) -> &str {
        match self.0 {
            MotionEstimator::Kde => "motion",
            MotionEstimator::WindowMax => "window_max",
        }
    }

    fn observes(&self) -> bool {
        true
    }

    /// The curves of the observations by this filter's estimator, whatever
    /// `cfg.estimator` says.
    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError> {
        let cfg = FilterConfig {
            estimator: self.0,
            ..cfg.clone()
        };
        let curves = MotionCurves::refresh(inputs.observations(), &cfg)?;
        Ok(FilterState::Motion {
            s3d: cfg.s3d,
            curves,
        })
    }
}
