//! maaf-train (see DESIGN.md).
