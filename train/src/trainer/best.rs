//! The run's model chosen on validation views (`keep_best`): every validation whose
//! PSNR beats the best so far saves the trainer into `RUN/best/`; at the end the last
//! state goes to `checkpoints/iter_N` and the best one becomes `model/`, what
//! evaluation and rendering read.
//!
//! The best so far is read back from `log.csv` on a resume (its `val_psnr` column, cut
//! back to the resumed checkpoint), so the checkpoints carry nothing new and a resumed
//! run chooses the same state as an uninterrupted one: the values are compared as the
//! log shows them (4 decimals), the earlier of two equal ones kept.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::Error;

/// Where a `keep_best` run keeps its best state while it trains.
pub const BEST_DIR: &str = "best";

/// The state a `keep_best` run chose (`summary.json`'s `chosen`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Chosen {
    /// Its iteration.
    pub iteration: usize,
    /// Its validation PSNR, dB, as `log.csv` shows it.
    pub val_psnr: f64,
}

/// The best validation so far of a `keep_best` run.
pub(super) struct BestSoFar {
    dir: PathBuf,
    chosen: Option<Chosen>,
}

impl BestSoFar {
    /// The best `val_psnr` of `log` (a run's `log.csv`, already cut back to the
    /// resumed iteration) whose state is in `RUN/best/`; none for a new run, or when
    /// `best/` is missing or holds a later state (a kill after its save: the replay
    /// reaches it again).
    pub(super) fn resume(run: &Path, log: &Path) -> Result<Self, Error> {
        let dir = run.join(BEST_DIR);
        // The best of the logged values; the earlier of two equal ones.
        let mut chosen: Option<Chosen> = None;
        for (iteration, val_psnr) in
            maaf_scene::run_log::logged_pairs(log, "iteration", "val_psnr")?
        {
            if chosen.is_none_or(|c| val_psnr > c.val_psnr) {
                chosen = Some(Chosen {
                    iteration: iteration as usize,
                    val_psnr,
                });
            }
        }
        let saved = maaf_io::readable_dir(&dir).and_then(|d| super::checkpoint_iteration(&d).ok());
        if chosen.is_some_and(|c| saved != Some(c.iteration)) {
            chosen = None;
        }
        Ok(BestSoFar { dir, chosen })
    }

    /// Takes the validation PSNR `shown` (as logged) at `iteration`; true when it is
    /// the best so far and the trainer is to be saved into [`Self::dir`].
    pub(super) fn offer(&mut self, iteration: usize, shown: &str) -> bool {
        let Ok(val_psnr) = shown.parse::<f64>() else {
            return false;
        };
        if !val_psnr.is_finite() || self.chosen.is_some_and(|c| val_psnr <= c.val_psnr) {
            return false;
        }
        self.chosen = Some(Chosen {
            iteration,
            val_psnr,
        });
        true
    }

    /// `RUN/best/`.
    pub(super) fn dir(&self) -> &Path {
        &self.dir
    }

    /// The state chosen so far.
    pub(super) fn chosen(&self) -> Option<Chosen> {
        self.chosen
    }

    /// Copies the best state into `model` whole or not at all
    /// ([`maaf_io::write_dir`]).
    pub(super) fn install(&self, model: &Path) -> Result<(), Error> {
        let from = maaf_io::readable_dir(&self.dir).ok_or_else(|| {
            Error::Input(format!("{}: the best state is missing", self.dir.display()))
        })?;
        maaf_io::write_dir(model, Error::io, |tmp| {
            maaf_io::copy_tree(&from, tmp).map_err(|e| Error::io(&from, e))
        })
    }
}
