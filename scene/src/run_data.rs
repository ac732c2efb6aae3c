//! The data set a run was trained on: its fingerprint, written as `RUN/data.json` when
//! the run starts and checked before a resume, a branch or an evaluation, so a run is
//! never continued or scored on other data (docs/architecture.md, "The run's data
//! set").

use std::path::{Path, PathBuf};

use maaf_data::{Dataset, Split, SplitMeta};
use serde::{Deserialize, Serialize};

use crate::{Error, Opened, write_atomic};

/// What a run was trained on, written as `RUN/data.json` by [`record_data`] when the
/// run starts; `maaf_train::load_run`, evaluation and a resumed training refuse a data set that differs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DataFingerprint {
    /// Data folder, absolute (the default data of `train --resume`, `eval`, `render`;
    /// a moved folder still matches when given explicitly).
    pub root: PathBuf,
    /// Number of training views.
    pub train_views: usize,
    /// Number of test views.
    pub test_views: usize,
    /// Source image width of the training split.
    pub width: u32,
    /// Source image height of the training split.
    pub height: u32,
    /// Background colour the images were composited on.
    pub background: [f32; 3],
    /// [`frames_fingerprint`] of the training split: 16 hex digits over every training
    /// frame's file name, time, intrinsics, pose and image size. Absent in runs
    /// written before it existed, which are checked by the fields above only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<String>,
    /// [`pixels_fingerprint`] of the training images: 16 hex digits over every
    /// training image file's size and CRC-32, so the same cameras over other images
    /// are another data set. Absent in runs written before it existed, which are
    /// checked without it and gain it on their next resume.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixels: Option<String>,
}

/// FNV-1a 64 of the byte strings `feed` passes to its callback, as 16 hex digits.
fn fnv1a(feed: impl FnOnce(&mut dyn FnMut(&[u8]))) -> String {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    feed(&mut |bytes: &[u8]| {
        for &b in bytes {
            hash ^= u64::from(b);
            hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
        }
    });
    format!("{hash:016x}")
}

/// A fingerprint of a split's image files (FNV-1a 64 over, per frame in split order,
/// the file's size and the CRC-32 of its bytes), as 16 hex digits: the pixels the
/// frames fingerprint does not cover. Reads every file (in parallel); an unreadable
/// one is an error naming it.
pub fn pixels_fingerprint(meta: &SplitMeta) -> Result<String, Error> {
    use rayon::prelude::*;
    let sums = meta
        .frames
        .par_iter()
        .map(|frame| {
            let bytes = std::fs::read(&frame.file).map_err(|e| Error::io(&frame.file, e))?;
            Ok((bytes.len() as u64, crc32fast::hash(&bytes)))
        })
        .collect::<Result<Vec<(u64, u32)>, Error>>()?;
    Ok(fnv1a(|feed| {
        for (len, crc) in sums {
            feed(&len.to_le_bytes());
            feed(&crc.to_le_bytes());
        }
    }))
}

/// A fingerprint of a split's frames and cameras (FNV-1a 64 over, per frame, the
/// image path relative to the data folder, the time and the camera's size,
/// intrinsics and world-to-camera matrix, as bit patterns), as 16 hex digits.
/// Computed from the [`SplitMeta`] every loader produces, so any data format is
/// covered; two folders with the same frames and cameras have the same fingerprint.
pub fn frames_fingerprint(meta: &SplitMeta, root: &Path) -> String {
    fnv1a(|feed| {
        feed(&meta.width.to_le_bytes());
        feed(&meta.height.to_le_bytes());
        for frame in &meta.frames {
            let name = frame.file.strip_prefix(root).unwrap_or(&frame.file);
            let name = name.to_string_lossy();
            feed(&(name.len() as u64).to_le_bytes());
            feed(name.as_bytes());
            let c = &frame.camera;
            feed(&c.width.to_le_bytes());
            feed(&c.height.to_le_bytes());
            let pose = c.world_to_camera.iter().flatten();
            for v in [frame.time, c.fx, c.fy, c.cx, c.cy].iter().chain(pose) {
                feed(&v.to_bits().to_le_bytes());
            }
        }
    })
}

impl DataFingerprint {
    /// The fingerprint of `data`.
    pub fn of(data: &Dataset) -> Result<Self, Error> {
        let meta = data
            .split(Split::Train)
            .map_err(|e| Error::Input(e.to_string()))?;
        // Absolute, so the run can be evaluated from any working folder.
        let root = std::fs::canonicalize(data.root()).map_err(|e| Error::io(data.root(), e))?;
        Ok(DataFingerprint {
            root,
            train_views: data.len(Split::Train),
            test_views: data.len(Split::Test),
            width: meta.width,
            height: meta.height,
            background: data.background(),
            frames: Some(frames_fingerprint(meta, data.root())),
            pixels: Some(pixels_fingerprint(meta)?),
        })
    }

    /// Refuses `now` (the data set at hand) when it is not this recorded one: another
    /// frames fingerprint (or, for a record without one, another view count or image
    /// size), or another background ([`Self::check_frames`] plus the background: what
    /// a resumed training needs). The message names both folders.
    pub fn check(&self, now: &DataFingerprint, run: &Path) -> Result<(), Error> {
        self.check_frames(now, run)?;
        if self.background != now.background {
            return Err(Error::Input(format!(
                "{}: background {:?} differs from the {:?} the run {} was trained on",
                now.root.display(),
                now.background,
                self.background,
                run.display()
            )));
        }
        Ok(())
    }

    /// [`Self::check`] without the background: the same frames, composited on any
    /// background (an evaluation may move the ground truth onto another one).
    pub fn check_frames(&self, now: &DataFingerprint, run: &Path) -> Result<(), Error> {
        let differs = match (&self.frames, &now.frames) {
            (Some(a), Some(b)) if a != b => Some(format!(
                "its training frames and cameras differ (fingerprint {b}, the run's {a})"
            )),
            (Some(_), Some(_)) => match (&self.pixels, &now.pixels) {
                (Some(a), Some(b)) if a != b => Some(format!(
                    "its training images differ in their bytes (pixels fingerprint {b}, the run's {a})"
                )),
                _ => None,
            },
            _ if (self.train_views, self.width, self.height)
                != (now.train_views, now.width, now.height) =>
            {
                Some(format!(
                    "it has {} training views of {}x{}, the run's has {} of {}x{}",
                    now.train_views,
                    now.width,
                    now.height,
                    self.train_views,
                    self.width,
                    self.height
                ))
            }
            _ => None,
        };
        if let Some(why) = differs {
            return Err(Error::Input(format!(
                "{}: is not the data set the run {} was trained on ({}): {why}",
                now.root.display(),
                run.display(),
                self.root.display()
            )));
        }
        Ok(())
    }
}

/// Writes `RUN/data.json` (the data set's [`DataFingerprint`]), so a resumed training
/// and later evaluations can refuse a different data set. A run records it when it
/// starts (`maaf_train::trainer::train_run`).
pub fn record_data(run: &Path, data: &Dataset) -> Result<(), Error> {
    let fp = DataFingerprint::of(data)?;
    let json =
        serde_json::to_vec_pretty(&fp).map_err(|e| Error::Input(format!("data.json: {e}")))?;
    write_atomic(&run.join("data.json"), &json)
}

/// Checks `data` against the run's `RUN/data.json` ([`DataFingerprint::check`]) when
/// there is one, then records it: a run resumed on another data set is refused before
/// anything of it changes; a record without a fingerprint (an older run) gains one;
/// a moved data folder with the same frames is recorded at its new place.
pub fn check_and_record_data(run: &Path, data: &Dataset) -> Result<(), Error> {
    let now = DataFingerprint::of(data)?;
    if let Some(rec) = recorded_data(run)? {
        rec.check(&now, run)?;
        if rec == now {
            return Ok(());
        }
    }
    record_data(run, data)
}

/// Reads `RUN/data.json` if the run has one.
pub fn recorded_data(run: &Path) -> Result<Option<DataFingerprint>, Error> {
    let path = run.join("data.json");
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| Error::Input(format!("{}: {e}", path.display())))
}

/// The run folder holding the checkpoint folder `dir`: `RUN` of `RUN/model` or
/// `RUN/checkpoints/iter_N`; `None` for a folder elsewhere.
fn checkpoint_run(dir: &Path) -> Option<PathBuf> {
    let parent = dir.parent()?;
    if dir.file_name()? == "model" {
        return Some(parent.to_path_buf());
    }
    (parent.file_name()? == "checkpoints").then(|| maaf_io::parent_of(parent).to_path_buf())
}

/// Refuses `data` unless it is the data set the checkpoint folder `dir` was trained
/// on: by the `data.json` of the run holding it ([`DataFingerprint::check_frames`])
/// when there is one, else by the checkpoint's scene record (every training view's
/// camera at the training scale and its time), which every checkpoint written since
/// the record exists holds. A checkpoint with neither is not checked. What a resume
/// of a run without `data.json` and a branch (`--from`) onto another run's
/// checkpoint check; the message names both data sets.
pub fn check_checkpoint_data(dir: &Path, data: &Dataset) -> Result<(), Error> {
    if let Some(run) = checkpoint_run(dir)
        && let Some(rec) = recorded_data(&run)?
    {
        return rec.check_frames(&DataFingerprint::of(data)?, &run);
    }
    let opened = Opened::open(dir)?;
    let Some(record) = opened.scene_record()? else {
        return Ok(());
    };
    let input = |e: maaf_data::DataError| Error::Input(e.to_string());
    let cameras = data
        .cameras(Split::Train, opened.state.config.train_scale)
        .map_err(input)?;
    if cameras != record.cameras || data.times(Split::Train) != record.times {
        return Err(Error::Input(format!(
            "{}: is not the data set the checkpoint {} was trained on: its {} training views' cameras or times differ from the {} the checkpoint records",
            data.root().display(),
            dir.display(),
            cameras.len(),
            record.cameras.len()
        )));
    }
    Ok(())
}
