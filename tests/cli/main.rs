//! The root crate's integration tests as one test binary (one link of the whole
//! workspace instead of one per file): the CLI as a user runs it, and the end-to-end
//! gradient check through the public API.

mod bad_input;
mod bench_suite;
mod cli_habits;
mod compare;
mod config_doc;
mod counts;
mod custom_plugins;
mod custom_terms;
mod data_identity;
mod e2e_gradcheck;
mod eval_scales;
mod export_eval;
mod litter;
mod log_columns;
mod moved_data;
mod panoptic;
mod presets;
mod resume_faults;
mod run_integrity;
mod silent_input;
mod suite_checks;
mod support;
mod sweep;
mod track;
