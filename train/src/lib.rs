//! maaf-train (see DESIGN.md).

pub mod loss;
pub mod models;
