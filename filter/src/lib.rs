//! maaf-filter: the 3D smoothing filters of maaf (DESIGN.md section 4).
//!
//! * [`static_nu`]: Mip-Splatting's static sampling rate (paper Eq. 2) on canonical
//!   centres, the "SaRO-GS + 3D filter" baseline.
//! * [`MotionCurves`]: the paper's motion-aware sampling rate nu_k(t) (Sec. 4,
//!   Algorithm 1) from per-Gaussian observations ([`ObservationTable`]), computed
//!   without the `D x T` density and stored as `T + 8` bytes per Gaussian.
//! * [`FilterState::variance_at`]: the per-Gaussian variance `s3d / nu^2` that the
//!   renderer's `apply_3d_filter` adds. Nothing here touches a tape.
//!
//! # How the trainer uses it
//! ```text
//! cfg.validate()?                                   // at start-up
//! let mut obs = ObservationTable::for_frames(&frames, n);   // Motion only
//! // every training step, after deform(t) and before/after rendering:
//! obs.record_centres(frame_idx, &cameras[cam], &deformed_means, &cfg)?;
//! // when cfg.refresh.due(iter, total, densified):
//! //   (optionally obs.observe_all(&frames, &cameras, &cfg, |t| deform_means(t))? for a fresh pass)
//! state = FilterState::Motion { s3d: cfg.s3d, curves: MotionCurves::refresh(&obs, &cfg)? };
//! //   or FilterState::Mip3d { s3d: cfg.s3d, nu: static_nu(&canonical_means, &cameras, &cfg)? }
//! // each step: let var = state.variance_at(t);  -> splat::apply_3d_filter(.., var)
//! // densification: state.select_rows(&index); obs.select_rows(&index);
//! ```

mod config;
pub mod export;
mod kernels;
mod mip;
mod motion;
mod observations;
pub mod reference;
mod state;

pub use config::{FilterConfig, FilterError, FilterKind, RefreshSchedule};
pub use export::{AnalysisExport, GaussianTrace};
pub use kernels::Kernels;
pub use mip::{Viewer, static_nu, variance_from_nu};
pub use motion::{FALLBACK, MotionCurves};
pub use observations::{Frame, ObservationTable};
pub use state::FilterState;
