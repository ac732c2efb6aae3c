//! maaf-train (see DESIGN.md).

pub mod loss;
pub mod data;
pub mod models;
