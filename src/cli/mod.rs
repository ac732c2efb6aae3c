//! Subcommand implementations of the `maaf` binary, one file per command.

pub mod render_ply;
