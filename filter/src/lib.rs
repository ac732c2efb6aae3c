//! maaf-filter (see DESIGN.md).
