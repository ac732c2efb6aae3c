//! The motion-aware filter's refresh: nu_k(t) from the recorded observations by the
//! configured estimator, the paper's KDE (`kde.rs`) or our windowed maximum
//! (`window_max.rs`), stored as [`MotionCurves`] (`curves.rs`).

use crate::config::{FilterConfig, FilterError, MotionEstimator};
use crate::curves::MotionCurves;
use crate::observations::ObservationTable;
use crate::{kde, window_max};

impl MotionCurves {
    /// Recomputes every Gaussian's curve from `table` with `cfg.estimator`: the
    /// fast path of Algorithm 1 (the paper's KDE) or our windowed maximum
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
