//! maaf-train (see DESIGN.md).

pub mod loss;
