//! maaf-train: data, representations, the training pipeline, evaluation and reports.
//! `docs/architecture.md` says how the modules fit and where things plug in.

pub mod bench;
pub mod data;
mod error;
pub mod eval;
pub mod forward;
pub mod loss;
pub mod metrics;
pub mod models;
pub mod params;
pub mod report;
pub mod scene;
pub mod sweep;
pub mod trainer;

pub use error::{Error, write_atomic};
