//! The motion-aware filter's refresh: nu_k(t) from the recorded observations by the
//! configured estimator, the paper's KDE (`kde.rs`) or maaf's windowed maximum
//! (`window_max.rs`), stored as [`MotionCurves`] (`curves.rs`); and the two
//! [`SamplingFilter`]s that use it.

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

/// The paper's motion-aware filter (`filter.kind = "motion"`, `estimator = "kde"`):
/// nu_k(t) by the KDE of Algorithm 1 over the recorded observations.
#[derive(Clone, Copy, Debug, Default)]
pub struct MotionKdeFilter;

/// maaf's windowed maximum (`filter.kind = "motion"`, `estimator = "window_max"`):
/// nu_k(t) = the largest f/d observed within `h_t` of t (`window_max.rs`).
#[derive(Clone, Copy, Debug, Default)]
pub struct WindowMaxFilter;

/// The motion filter's state from the trainer's observations by `estimator`.
fn motion_state(
    inputs: &dyn FilterInputs,
    cfg: &FilterConfig,
    estimator: MotionEstimator,
) -> Result<FilterState, FilterError> {
    let cfg = FilterConfig {
        estimator,
        ..cfg.clone()
    };
    let curves = MotionCurves::refresh(inputs.observations(), &cfg)?;
    Ok(FilterState::Motion {
        s3d: cfg.s3d,
        curves,
    })
}

impl SamplingFilter for MotionKdeFilter {
    fn name(&self) -> &str {
        "motion"
    }

    fn observes(&self) -> bool {
        true
    }

    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError> {
        motion_state(inputs, cfg, MotionEstimator::Kde)
    }
}

impl SamplingFilter for WindowMaxFilter {
    fn name(&self) -> &str {
        "window_max"
    }

    fn observes(&self) -> bool {
        true
    }

    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError> {
        motion_state(inputs, cfg, MotionEstimator::WindowMax)
    }
}
