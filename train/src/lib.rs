//! maaf-train: the training pipeline, evaluation and reports, on the data sets of
//! `maaf-data` and the representations of `maaf-models` (re-exported as [`data`],
//! [`models`] and [`params`]).
//! `docs/architecture.md` says how the modules fit and where things plug in.

pub mod bench;
mod error;
pub mod eval;
pub mod forward;
pub mod loss;
pub mod metrics;
mod plugins;
pub mod report;
pub mod scene;
pub mod sweep;
pub mod trainer;

/// The data sets a run trains on (the `maaf-data` crate): the trainer's public API
/// takes and returns its types.
pub use maaf_data as data;

/// The representations a run trains (the `maaf-models` crate).
pub use maaf_models as models;

/// The named parameter store every representation keeps its tensors in.
pub use maaf_models::params;

pub use error::{Error, write_atomic};
pub use plugins::Plugins;
