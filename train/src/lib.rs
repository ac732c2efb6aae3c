//! maaf-train (see DESIGN.md).

pub mod loss;
pub mod metrics;
pub mod data;
pub mod models;
pub mod trainer;
pub mod eval;
pub mod report;
