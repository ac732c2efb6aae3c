//! maaf-train: the training loop, the objective's terms, the step benchmark and
//! sweeps, on the data sets of `maaf-data` and the representations of `maaf-models`
//! (re-exported as [`data`], [`models`] and [`params`]). What a trained run is
//! (`maaf-scene`) and its evaluation (`maaf-eval`) live below it and are re-exported
//! under their old paths ([`scene`], [`forward`], [`eval`], [`metrics`], [`report`]).
//! `docs/architecture.md` says how the modules fit and where things plug in.

pub mod bench;
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

/// The named parameter store every representation keeps its tensors in.
pub use maaf_models::params;

/// The trained run as a value (the `maaf-scene` crate): `TrainedScene`, its record,
/// the model registry.
pub use maaf_scene as scene;

/// One forward pass of the pipeline (`maaf-scene`); its objective is
/// [`loss::ForwardTerms`].
pub use maaf_scene::forward;

/// Evaluation of a trained run (the `maaf-eval` crate).
pub use maaf_eval as eval;

/// Evaluation metrics (`maaf-eval`).
pub use maaf_eval::metrics;

/// Reports over evaluated runs (`maaf-eval`).
pub use maaf_eval::report;

pub use maaf_scene::{Error, write_atomic};
pub use plugins::Plugins;
