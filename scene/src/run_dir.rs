//! Repairing a run folder after a kill, before anything reads or continues it.

use std::path::Path;

use crate::Error;

/// Repairs the run folder `out` after a kill: puts back a parked `model/` or
/// checkpoint ([`maaf_io::recover_parked_in`]) and removes every leftover temporary
/// in the run folder, `checkpoints/` and `eval/`. Returns how many temporaries it
/// removed.
pub fn repair_run_dir(out: &Path) -> Result<usize, Error> {
    let checkpoints = out.join("checkpoints");
    for dir in [out, checkpoints.as_path()] {
        maaf_io::recover_parked_in(dir).map_err(|e| Error::io(dir, e))?;
    }
    let mut removed = 0;
    for dir in [out.to_path_buf(), checkpoints, out.join("eval")] {
        removed += maaf_io::remove_stale_temps(&dir).map_err(|e| Error::io(&dir, e))?;
    }
    Ok(removed)
}
