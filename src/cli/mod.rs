//! Subcommand implementations of the `maaf` binary, one file per command.

pub mod generate;
pub mod inspect;
pub mod render_ply;
