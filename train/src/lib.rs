//! maaf-train (see DESIGN.md).

pub mod data;
pub mod eval;
pub mod loss;
pub mod metrics;
pub mod models;
pub mod report;
pub mod trainer;
