//! The `maaf` command line as a library: [`Maaf`] runs it (the `maaf` binary is
//! `Maaf::new().run()`); one file per command, `command.rs` the list of them.

mod app;
mod command;

pub(crate) mod bench;
pub(crate) mod bench_suite;
pub(crate) mod cameras;
pub(crate) mod compare;
pub(crate) mod demo;
pub(crate) mod eval;
pub(crate) mod export_ply;
pub(crate) mod generate;
pub(crate) mod inspect;
pub(crate) mod render;
pub(crate) mod render_ply;
pub(crate) mod report;
pub(crate) mod sweep;
pub(crate) mod train;

pub use app::Maaf;

/// `--background` of every command (`white`, `black` or `r,g,b`; the default of every
/// command is the run's, else [`Background::default`], black).
use maaf_train::data::Background;
