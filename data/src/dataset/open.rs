//! Opening a data folder ([`Dataset::open`]): its format told apart by the files it
//! holds (the built-in layouts first, then the registered ones), its splits read by
//! that format's loader and checked once for every format
//! (valid cameras, one image size), and the training times optionally capped.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::Mutex;

use maaf_splat::Camera;

use super::{Dataset, DatasetOptions, Format, MaskSource, spread};
use crate::bounds::bounds_from_cameras;
use crate::dnerf::{Split, SplitMeta, read_split};
use crate::dynamic3dgs::{TRAIN_META, read_dynamic3dgs};
use crate::error::DataError;
use crate::format::{DataFormat, FormatRegistry};
use crate::n3dv::{POSES_BOUNDS, read_plenoptic};

impl Dataset {
    /// Opens a data folder. A folder with `transforms_train.json` is D-NeRF: it reads
    /// `transforms_train.json` and `transforms_test.json` (required),
    /// `transforms_val.json` and `transforms_video.json` (optional; skipped when absent,
    /// checked when present). Otherwise a folder with `poses_bounds.npy` is Plenoptic
    /// Video ([`read_plenoptic`]), and one with `train_meta.json` the Dynamic 3D
    /// Gaussians layout ([`read_dynamic3dgs`]). Every image header is read; no image is
    /// decoded.
    pub fn open(root: &Path, options: DatasetOptions) -> Result<Self, DataError> {
        Self::open_capped(root, options, None)
    }

    /// [`Dataset::open`], reading a folder that none of the built-in layouts claims
    /// with the first of `formats` that detects it (registration order). The
    /// built-in layouts come first, so a registered format never changes how a
    /// D-NeRF, Plenoptic Video or Dynamic 3D Gaussians folder reads.
    pub fn open_with(
        root: &Path,
        options: DatasetOptions,
        formats: &FormatRegistry,
    ) -> Result<Self, DataError> {
        Self::open_from(root, options, None, formats)
    }

    /// [`Dataset::open`], keeping at most `max_train_times` distinct time stamps of the
    /// `train` split (every view at a kept time), evenly spread over the sorted distinct
    /// times: indices `round(j (n - 1) / (m - 1))`, `j = 0..m`, of the `n` times (the
    /// first when `m <= 1`). Times stay as stored. This bounds the memory of
    /// [`Dataset::train_views`] for multi-view videos (cameras x frames views, `12 W H`
    /// bytes each at the loaded scale); `None` keeps everything, as [`Dataset::open`].
    pub fn open_capped(
        root: &Path,
        options: DatasetOptions,
        max_train_times: Option<usize>,
    ) -> Result<Self, DataError> {
        Self::open_from(root, options, max_train_times, &FormatRegistry::new())
    }

    /// [`Dataset::open_capped`] with the registered `formats` ([`Dataset::open_with`]).
    fn open_from(
        root: &Path,
        options: DatasetOptions,
        max_train_times: Option<usize>,
        formats: &FormatRegistry,
    ) -> Result<Self, DataError> {
        if !root.is_dir() {
            return Err(DataError::request(root, "data folder does not exist"));
        }
        let dnerf = root.join(Split::Train.json_name());
        let mut train_masks = HashMap::new();
        let (format, mut splits, masks) = if !dnerf.exists() && root.join(POSES_BOUNDS).exists() {
            let p = read_plenoptic(root)?;
            (Format::Plenoptic, p.splits, MaskSource::Files(p.masks))
        } else if !dnerf.exists() && root.join(TRAIN_META).exists() {
            let d = read_dynamic3dgs(root)?;
            for v in &d.train.views {
                if let Some(m) = &v.mask {
                    train_masks.insert(v.image.clone(), m.clone());
                }
            }
            let masks = if d.test.views.iter().all(|v| v.mask.is_some()) {
                MaskSource::Files(d.test.views.iter().map(|v| v.mask.clone()).collect())
            } else {
                let ids = d.test.cameras();
                MaskSource::TemporalMedian {
                    camera: d
                        .test
                        .views
                        .iter()
                        .map(|v| ids.iter().position(|&c| c == v.cam_id).unwrap_or(0))
                        .collect(),
                }
            };
            (Format::Dynamic3dgs, d.splits(), masks)
        } else if dnerf.exists() || root.join(Split::Test.json_name()).exists() {
            let mut splits = BTreeMap::new();
            for split in Split::ALL {
                let required = matches!(split, Split::Train | Split::Test);
                if !required && !root.join(split.json_name()).exists() {
                    continue;
                }
                splits.insert(split, read_split(root, split)?);
            }
            (Format::DNerf, splits, MaskSource::None)
        } else if let Some((name, format)) = formats.detect(root) {
            (
                Format::Custom,
                custom_splits(root, name, format)?,
                MaskSource::None,
            )
        } else {
            let registered = match formats.names() {
                names if names.is_empty() => String::new(),
                names => format!(
                    ", and no registered data format ({}) detects it",
                    names.join(", ")
                ),
            };
            return Err(DataError::request(
                root,
                format!(
                    "neither transforms_train.json (D-NeRF), poses_bounds.npy (Plenoptic Video) nor train_meta.json (Dynamic 3D Gaussians) found{registered}"
                ),
            ));
        };
        check_splits(&splits)?;
        if let (Some(m), Some(train)) = (max_train_times, splits.get_mut(&Split::Train)) {
            keep_times(train, m);
        }
        let train = &splits[&Split::Train];
        let bounds = match train.scene_bounds {
            Some(b) => b,
            None => {
                let cams: Vec<Camera> = train.frames.iter().map(|f| f.camera.clone()).collect();
                bounds_from_cameras(&cams)
                    .ok_or_else(|| DataError::field(&train.json, "frames", "is empty"))?
            }
        };
        Ok(Dataset {
            root: root.to_path_buf(),
            format,
            background: options.background,
            splits,
            bounds,
            masks,
            train_masks,
            cache: Mutex::new(HashMap::new()),
            medians: Mutex::new(HashMap::new()),
        })
    }
}

/// The splits a registered format `name` reads from `root`, each once, `train` and
/// `test` among them.
fn custom_splits(
    root: &Path,
    name: &str,
    format: &dyn DataFormat,
) -> Result<BTreeMap<Split, SplitMeta>, DataError> {
    let mut splits = BTreeMap::new();
    for meta in format.load(root)? {
        let split = meta.split;
        if splits.insert(split, meta).is_some() {
            return Err(DataError::request(
                root,
                format!("data format `{name}` read the {split} split twice"),
            ));
        }
    }
    for split in [Split::Train, Split::Test] {
        if !splits.contains_key(&split) {
            return Err(DataError::request(
                root,
                format!("data format `{name}` read no {split} split (train and test are required)"),
            ));
        }
    }
    Ok(splits)
}

/// What every loader's splits must satisfy, checked once for all formats: every
/// frame's camera passes [`Camera::validate`] (positive finite focal lengths, a field
/// of view below [`maaf_splat::camera::MAX_FOV_DEGREES`], a finite pose within
/// [`maaf_splat::camera::MAX_TRANSLATION`]; a loader may build cameras field by
/// field), and every split's images have the training images' size (evaluation
/// scales, `1x` included, are relative to the training images).
fn check_splits(splits: &BTreeMap<Split, SplitMeta>) -> Result<(), DataError> {
    let train = splits
        .get(&Split::Train)
        .ok_or_else(|| DataError::request(Path::new(&Split::Train.json_name()), "missing"))?;
    for meta in splits.values() {
        for (i, frame) in meta.frames.iter().enumerate() {
            frame
                .camera
                .validate(&frame.file.display().to_string())
                .map_err(|e| {
                    DataError::field(&meta.json, format!("frames[{i}] camera"), e.to_string())
                })?;
        }
        if (meta.width, meta.height) != (train.width, train.height) {
            return Err(DataError::field(
                &meta.json,
                "frames",
                format!(
                    "its images are {}x{} but the training images are {}x{}: every split must have the training images' size",
                    meta.width, meta.height, train.width, train.height
                ),
            ));
        }
    }
    Ok(())
}

/// Keeps the views of `meta` at no more than `m` of its distinct times, evenly spread
/// (see [`Dataset::open_capped`]).
fn keep_times(meta: &mut SplitMeta, m: usize) {
    let mut times: Vec<f64> = meta.frames.iter().map(|f| f.time).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    if m >= times.len() {
        return;
    }
    let kept = spread(&times, m);
    meta.frames.retain(|f| kept.contains(&f.time));
}
