//! The sampling-rate filter as a trait: what turns the training cameras, the
//! canonical centres and the recorded observations into a [`FilterState`]. The
//! built-in implementations are [`NoFilter`], [`StaticFilter`] (this file) and the
//! motion-aware [`crate::MotionFilter`] with either estimator (`motion.rs`); [`crate::FilterRegistry`] builds one by its config name. A user's
//! filter implements [`SamplingFilter`] and returns one of the states the renderer
//! already folds (a static nu per Gaussian, or curves nu(t)).

use maaf_splat::Camera;

use crate::config::{FilterConfig, FilterError};
use crate::mip::static_nu;
use crate::observations::ObservationTable;
use crate::state::FilterState;

/// What a filter may read when it is recomputed, supplied by the trainer. Methods,
/// not fields, so that inputs a filter does not use (the canonical centres of a
/// large model) are never built.
pub trait FilterInputs {
    /// Number of Gaussians the state must have rows for.
    fn gaussians(&self) -> usize;
    /// The Gaussians' canonical (time-independent) centres.
    fn canonical_centres(&self) -> Vec<[f32; 3]>;
    /// The training cameras.
    fn cameras(&self) -> &[Camera];
    /// The f/d observations recorded from training views; empty (no frames) unless
    /// the filter [`SamplingFilter::observes`].
    fn observations(&self) -> &ObservationTable;
}

/// A 3D smoothing filter: a per-Gaussian sampling rate nu (or nu(t)) that the
/// renderer turns into the variance `s3d / nu^2` it adds to each covariance (paper
/// Sec. 4; docs/conventions.md, "3D filter fold"). Recomputed outside the tape
/// before training and on the config's refresh schedule.
pub trait SamplingFilter: Send + Sync {
    /// The filter's name (the built-ins: `filter.kind`, and for `motion` the
    /// estimator as well).
    fn name(&self) -> &str;

    /// Whether it reads the observation table: the trainer then records the f/d of
    /// every Gaussian in the observed training views at every step (and once over
    /// all of them before the first refresh). Default: no.
    fn observes(&self) -> bool {
        false
    }

    /// After a training step, for one observed training view it drew: records in
    /// `table` what [`Self::compute`] reads at the next refresh. `centres` are the
    /// Gaussians' deformed centres at the view's time and `present[n]` whether
    /// Gaussian `n` exists then. Called only when [`Self::observes`]. Default: the
    /// f/d of every present Gaussian in frame `frame`
    /// ([`ObservationTable::record_present`]).
    fn observe(
        &self,
        table: &mut ObservationTable,
        frame: usize,
        camera: &Camera,
        centres: &[[f32; 3]],
        present: &[bool],
        cfg: &FilterConfig,
    ) -> Result<(), FilterError> {
        table.record_present(frame, camera, centres, present, cfg)
    }

    /// Whether it adds a 3D filter at all: the renderer then uses the 2D Mip filter
    /// (0.1 px^2 with compensation) as in the paper, otherwise the classic 3DGS
    /// dilation. Default: yes.
    fn smooths(&self) -> bool {
        true
    }

    /// The filter state for the current Gaussians (one row each), from `inputs`
    /// and the validated `cfg`. On an error the trainer logs it and keeps the
    /// previous state.
    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError>;
}

/// No 3D filter: variance 0 (`filter.kind = "none"`).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoFilter;

impl SamplingFilter for NoFilter {
    fn name(&self) -> &str {
        "none"
    }

    fn smooths(&self) -> bool {
        false
    }

    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        _cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError> {
        Ok(FilterState::None {
            rows: inputs.gaussians(),
        })
    }
}

/// Mip-Splatting's static 3D filter (`filter.kind = "mip3d"`): nu of the canonical
/// centres from the training cameras (paper Eq. 2, [`static_nu`]), the "SaRO-GS +
/// 3D filter" baseline.
#[derive(Clone, Copy, Debug, Default)]
pub struct StaticFilter;

impl SamplingFilter for StaticFilter {
    fn name(&self) -> &str {
        "mip3d"
    }

    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError> {
        let nu = static_nu(&inputs.canonical_centres(), inputs.cameras(), cfg)?;
        Ok(FilterState::Mip3d { s3d: cfg.s3d, nu })
    }
}
