//! Subcommand implementations of the `maaf` binary, one file per command.

pub mod compare;
pub mod demo;
pub mod eval;
pub mod generate;
pub mod inspect;
pub mod render;
pub mod render_ply;
pub mod report;
pub mod train;
