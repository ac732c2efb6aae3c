//! Subcommand implementations of the `maaf` binary, one file per command.

pub mod bench;
pub mod compare;
pub mod demo;
pub mod eval;
pub mod export_ply;
pub mod generate;
pub mod inspect;
pub mod render;
pub mod render_ply;
pub mod report;
pub mod sweep;
pub mod train;

use maaf_train::data::{BLACK, WHITE};

/// `--background` values (shared by `train`, `eval`, `render`).
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum BackgroundArg {
    /// White, as D-NeRF's `white_bkgd`.
    White,
    /// Black, as SaRO-GS's D-NeRF configs.
    Black,
}

impl BackgroundArg {
    /// The colour.
    pub fn rgb(self) -> [f32; 3] {
        match self {
            BackgroundArg::White => WHITE,
            BackgroundArg::Black => BLACK,
        }
    }
}
