//! maaf-train: the training loop, the objective's terms, the step benchmark and
//! sweeps, on the data sets of `maaf-data` and the representations of `maaf-models`
//! (re-exported as [`data`] and [`models`], the types the trainer's API takes). What a
//! trained run is (`maaf-scene`: `TrainConfig`, `TrainedScene`, the run's data
//! fingerprint, the image metrics of its validation) lives below it, each type at its
//! one path there; evaluation (`maaf-eval`) is a sibling the trainer never uses.
//! `docs/architecture.md` says how the modules fit and where things plug in.

pub mod bench;
pub mod budget;
mod load_run;
pub mod loss;
mod plugins;
pub mod sweep;
pub mod trainer;

pub use load_run::load_run;

/// The data sets a run trains on (the `maaf-data` crate): the trainer's public API
/// takes and returns its types.
pub use maaf_data as data;

/// The representations a run trains (the `maaf-models` crate).
pub use maaf_models as models;

pub use maaf_scene::{Error, write_atomic};
pub use plugins::Plugins;
