//! What every frame-sequence output (`render-video`, `export-ply --frames`) shares: the
//! frame times and the refusal to replace a folder holding anything but its own
//! earlier frames.

use std::path::Path;

use crate::Error;

/// Most frames of a sequence: the frames are named `frame_NNNN` with four digits,
/// which every viewer sorts by name (at 10 frames per second, a GIF of 17 minutes).
pub const MAX_SEQUENCE_FRAMES: usize = 10_000;

/// Refuses a frame count outside `1..=`[`MAX_SEQUENCE_FRAMES`], naming `--frames`:
/// checked before anything of the sequence is built.
pub fn check_frame_count(frames: usize) -> Result<(), Error> {
    if !(1..=MAX_SEQUENCE_FRAMES).contains(&frames) {
        return Err(Error::Input(format!(
            "--frames {frames}: must be in 1..={MAX_SEQUENCE_FRAMES} (frames are numbered frame_NNNN)"
        )));
    }
    Ok(())
}

/// The `frames` times of a sequence over `[t0, t1]`:
/// `t_i = t0 + (t1 - t0) i / (frames - 1)` (just `t0` for one frame);
/// [`check_frame_count`] first.
pub fn frame_times((t0, t1): (f64, f64), frames: usize) -> Result<Vec<f64>, Error> {
    check_frame_count(frames)?;
    Ok((0..frames)
        .map(|i| {
            if frames == 1 {
                t0
            } else {
                t0 + (t1 - t0) * i as f64 / (frames - 1) as f64
            }
        })
        .collect())
}

/// Refuses an existing folder `out` holding a file that `ours` does not accept (one
/// line naming it and `what` wrote the accepted files); `Ok` when `out` is absent.
pub(crate) fn check_own_folder(
    out: &Path,
    what: &str,
    ours: impl Fn(&str) -> bool,
) -> Result<(), Error> {
    if !out.exists() {
        return Ok(());
    }
    let entries = std::fs::read_dir(out).map_err(|e| Error::io(out, e))?;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if !ours(&name) {
            return Err(Error::Input(format!(
                "{}: holds `{name}`, which is not a frame of an earlier {what}; give a new or empty folder",
                out.display()
            )));
        }
    }
    Ok(())
}
