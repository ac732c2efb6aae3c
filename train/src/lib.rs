//! maaf-train: representations, the training pipeline, evaluation and reports, on the
//! data sets of `maaf-data` (re-exported as [`data`]).
//! `docs/architecture.md` says how the modules fit and where things plug in.

pub mod bench;
mod error;
pub mod eval;
pub mod forward;
pub mod loss;
pub mod metrics;
pub mod models;
pub mod params;
pub mod report;
pub mod sweep;
pub mod trainer;

/// The data sets a run trains on (the `maaf-data` crate): the trainer's public API
/// takes and returns its types.
pub use maaf_data as data;

pub use error::{Error, write_atomic};
