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

use maaf_train::data::{BLACK, WHITE, background_name};

/// `--background` of every command: `white` (D-NeRF's `white_bkgd`), `black` (SaRO-GS's
/// D-NeRF configs) or `r,g,b` with components in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Background(pub [f32; 3]);

impl Background {
    /// Parses `white`, `black` or `r,g,b` (clap's value parser for `--background`).
    pub fn parse(s: &str) -> Result<Self, String> {
        match s.trim() {
            "white" => return Ok(Background(WHITE)),
            "black" => return Ok(Background(BLACK)),
            _ => {}
        }
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if parts.len() != 3 {
            return Err(format!("expected white, black or r,g,b, got `{s}`"));
        }
        let mut rgb = [0.0f32; 3];
        for (v, p) in rgb.iter_mut().zip(&parts) {
            *v = p
                .parse::<f32>()
                .ok()
                .filter(|x| (0.0..=1.0).contains(x))
                .ok_or_else(|| format!("`{p}` in `{s}` is not a number in [0, 1]"))?;
        }
        Ok(Background(rgb))
    }

    /// The colour.
    pub fn rgb(self) -> [f32; 3] {
        self.0
    }
}

/// The spelling [`Background::parse`] reads back: `white`, `black` or `r,g,b`.
impl std::fmt::Display for Background {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&background_name(self.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn background_spellings_parse_and_print_back() {
        for text in ["white", "black", "0.5,0.25,1"] {
            let bg = Background::parse(text).expect(text);
            assert_eq!(bg.to_string(), text);
            assert_eq!(Background::parse(&bg.to_string()), Ok(bg));
        }
        assert_eq!(Background::parse("1,1,1"), Ok(Background(WHITE)));
        for bad in ["grey", "1,1", "1,1,2", "a,b,c", "0,0,NaN"] {
            assert!(Background::parse(bad).is_err(), "{bad}");
        }
    }
}
