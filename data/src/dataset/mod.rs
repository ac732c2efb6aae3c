//! The `Dataset` API the trainer and evaluator use: views (composited image, camera,
//! time) of each split at any integer-ratio scale of the source images, decoded once and
//! cached per scale; the scene bounds for initialisation; the time range.
//!
//! Three formats open the same way ([`Dataset::open`] tells them apart): D-NeRF
//! (`transforms_train.json`, [`super::dnerf`]), Plenoptic Video (`poses_bounds.npy`
//! and `camXX/images/`, [`super::n3dv`]) and the Dynamic 3D Gaussians layout
//! (`train_meta.json`, [`super::dynamic3dgs`]), whose train and test cameras become the
//! same [`SplitMeta`]s.
//!
//! A *scale* is relative to the source image size: `0.25` of 800x800 is 200x200. It must
//! be `1 / k` for an integer `k` that divides both the width and height; the image is
//! then box-downsampled by `k` (premultiplied, then composited, see
//! [`super::downsample`]) and the camera is `Camera::scaled(1 / k)` (width, height, fx,
//! fy, cx, cy all divided by `k`; with pixel centres at `x + 0.5`, source pixel centre
//! `u` maps to `u / k` exactly). Scales above 1 (zoom-in beyond the source) have no
//! ground truth and are refused.
//!
//! This file holds the type and what it says of its splits; opening a folder is
//! `open.rs`, the views and their cache `cache.rs`, the test views' moving masks and
//! the training views' foreground masks `masks.rs`, and the points a run starts from
//! `initial_cloud.rs`.

mod cache;
mod initial_cloud;
mod masks;
mod open;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use maaf_splat::Camera;

use super::bounds::Aabb;
use super::dnerf::{Split, SplitMeta};
use super::error::DataError;
use super::flow::{downsample_flow, read_flow};
use super::image::Image;
use super::median_mask::Rgb8;
use crate::Background;

pub use initial_cloud::InitialCloud;
pub use masks::MaskSource;

/// Options for [`Dataset::open`].
#[derive(Clone, Debug, PartialEq)]
pub struct DatasetOptions {
    /// Background colour images are composited on, after downsampling.
    pub background: [f32; 3],
}

impl Default for DatasetOptions {
    /// The default background ([`Background::default`], black).
    fn default() -> Self {
        DatasetOptions {
            background: Background::default().rgb(),
        }
    }
}

/// One view at one scale: the composited image, its camera and its time.
#[derive(Clone, Debug)]
pub struct View {
    /// Split it belongs to.
    pub split: Split,
    /// Index in the split's json `frames`.
    pub index: usize,
    /// Composited RGB image `[H, W, 3]` in `[0, 1]` at this scale (shared with the cache).
    pub image: Arc<Image>,
    /// Coverage `a` `[H, W, 1]` of the source's alpha at this scale (box-averaged like
    /// the colour), `None` when every source pixel is opaque. With it the view can be
    /// composited on any other background `b`: `image + (1 - a) (b - background)`
    /// ([`crate::downsample::recomposite`]).
    pub coverage: Option<Arc<Image>>,
    /// Camera at this scale (OpenCV axes, intrinsics divided by the factor).
    pub camera: Camera,
    /// Time stamp from the json.
    pub time: f64,
}

/// Cache key: split, downsampling factor, view index.
type CacheKey = (Split, u32, usize);

/// One cached view: the composited image and its coverage ([`View::coverage`]).
type CachedImage = (Arc<Image>, Option<Arc<Image>>);

/// The on-disk format of a data set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `transforms_{train,val,test}.json` and RGBA PNGs ([`super::dnerf`]).
    DNerf,
    /// Plenoptic Video / N3DV: `poses_bounds.npy` and `camXX/images/` ([`super::n3dv`]).
    Plenoptic,
    /// Dynamic 3D Gaussians (CMU Panoptic): `train_meta.json`, `test_meta.json`, `ims/`,
    /// `seg/` ([`super::dynamic3dgs`]).
    Dynamic3dgs,
    /// A layout of one's own, read by a registered [`crate::DataFormat`]
    /// ([`Dataset::open_with`]).
    Custom,
}

/// A data set (D-NeRF or Plenoptic Video): parsed metadata of its splits plus a
/// per-scale image cache.
#[derive(Debug)]
pub struct Dataset {
    root: PathBuf,
    format: Format,
    background: [f32; 3],
    splits: BTreeMap<Split, SplitMeta>,
    bounds: Aabb,
    masks: MaskSource,
    /// Foreground mask of each training image that has one (image path -> mask path).
    train_masks: HashMap<PathBuf, PathBuf>,
    cache: Mutex<HashMap<CacheKey, CachedImage>>,
    /// Temporal median of each test camera group (for [`MaskSource::TemporalMedian`]).
    medians: Mutex<HashMap<usize, Arc<Rgb8>>>,
}

/// The integer downsampling factor `k = 1 / scale` for a `width x height` source, or a
/// message saying why the scale is refused (not positive, above 1, `1/scale` not an
/// integer within `1e-6`, or `k` not dividing both sides).
pub fn scale_factor(scale: f64, width: u32, height: u32) -> Result<u32, String> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err("must be a positive number".into());
    }
    if scale > 1.0 + 1e-9 {
        return Err(format!(
            "zoom-in beyond the source images has no ground truth; the largest scale is 1 ({width}x{height})"
        ));
    }
    let inv = 1.0 / scale;
    let k = inv.round();
    if (inv - k).abs() > 1e-6 * k {
        return Err(format!(
            "1/scale = {inv:.6} is not an integer downsampling factor"
        ));
    }
    let k = k as u32;
    if !width.is_multiple_of(k) || !height.is_multiple_of(k) {
        return Err(format!(
            "factor {k} does not divide the image size {width}x{height}"
        ));
    }
    Ok(k)
}

impl Dataset {
    /// The format the folder was read as.
    pub fn format(&self) -> Format {
        self.format
    }

    /// The data folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The background colour images are composited on.
    pub fn background(&self) -> [f32; 3] {
        self.background
    }

    /// The splits present, in the order train, val, test, video.
    pub fn splits(&self) -> impl Iterator<Item = &SplitMeta> {
        self.splits.values()
    }

    /// Metadata of one split, or an error naming its json if it is absent.
    pub fn split(&self, split: Split) -> Result<&SplitMeta, DataError> {
        self.splits.get(&split).ok_or_else(|| {
            DataError::request(
                &self.root.join(split.json_name()),
                "split not present in this data set",
            )
        })
    }

    /// Number of views of a split (0 when absent).
    pub fn len(&self, split: Split) -> usize {
        self.splits.get(&split).map_or(0, |m| m.frames.len())
    }

    /// Whether the data set has no training views (never true for an opened data set).
    pub fn is_empty(&self) -> bool {
        self.len(Split::Train) == 0
    }

    /// The integer factor for `scale` on `split`'s images, or an error naming its json.
    pub fn factor(&self, split: Split, scale: f64) -> Result<u32, DataError> {
        let meta = self.split(split)?;
        scale_factor(scale, meta.width, meta.height).map_err(|message| DataError::Scale {
            path: meta.json.display().to_string(),
            scale,
            message,
        })
    }

    /// Image size `(width, height)` of `split` at `scale`.
    pub fn size(&self, split: Split, scale: f64) -> Result<(u32, u32), DataError> {
        let k = self.factor(split, scale)?;
        let meta = self.split(split)?;
        Ok((meta.width / k, meta.height / k))
    }

    /// Camera of view `index` at `scale` (`Camera::scaled(1 / k)`).
    pub fn camera(&self, split: Split, index: usize, scale: f64) -> Result<Camera, DataError> {
        let k = self.factor(split, scale)?;
        let frame = self.frame(split, index)?;
        Ok(frame.camera.scaled(1.0 / k as f64))
    }

    /// All cameras of a split at `scale`.
    pub fn cameras(&self, split: Split, scale: f64) -> Result<Vec<Camera>, DataError> {
        let k = self.factor(split, scale)?;
        Ok(self
            .split(split)?
            .frames
            .iter()
            .map(|f| f.camera.scaled(1.0 / k as f64))
            .collect())
    }

    /// Time stamps of a split, in json order (empty when absent).
    pub fn times(&self, split: Split) -> Vec<f64> {
        self.splits
            .get(&split)
            .map_or_else(Vec::new, |m| m.frames.iter().map(|f| f.time).collect())
    }

    /// `(min, max)` of the time stamps over all splits present.
    pub fn time_range(&self) -> (f64, f64) {
        self.splits
            .values()
            .flat_map(|m| m.frames.iter().map(|f| f.time))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
                (lo.min(t), hi.max(t))
            })
    }

    /// Scene bounds for initialisation: the training json's `scene_bounds` when present,
    /// else [`bounds_from_cameras`](crate::bounds::bounds_from_cameras) of the training cameras.
    pub fn scene_bounds(&self) -> Aabb {
        self.bounds
    }

    /// Forward flow of `video` frame `index` at `scale` (`[H, W, 3]`: dx, dy in pixels of
    /// that scale, valid), or `None` when the frame has no `flow_path` (the last frame).
    pub fn flow(&self, index: usize, scale: f64) -> Result<Option<Image>, DataError> {
        let k = self.factor(Split::Video, scale)?;
        let frame = self.frame(Split::Video, index)?;
        let Some(path) = &frame.flow else {
            return Ok(None);
        };
        let full = read_flow(path)?;
        let meta = self.split(Split::Video)?;
        if (full.width, full.height) != (meta.width, meta.height) {
            return Err(DataError::Image {
                path: path.display().to_string(),
                message: format!(
                    "flow is {}x{} but the video images are {}x{}",
                    full.width, full.height, meta.width, meta.height
                ),
            });
        }
        Ok(downsample_flow(&full, k))
    }

    fn frame(&self, split: Split, index: usize) -> Result<&super::dnerf::Frame, DataError> {
        let meta = self.split(split)?;
        meta.frames.get(index).ok_or_else(|| {
            DataError::request(
                &meta.json,
                format!("view {index} out of range ({} views)", meta.frames.len()),
            )
        })
    }
}

/// At most `m` of the sorted `values`, evenly spread: indices `round(j (n - 1) / (m -
/// 1))`, `j = 0..m` (the first when `m <= 1`; all when `m >= n`).
fn spread(values: &[f64], m: usize) -> Vec<f64> {
    let n = values.len();
    if m >= n {
        return values.to_vec();
    }
    match m {
        0 | 1 => values.first().copied().into_iter().collect(),
        _ => (0..m)
            .map(|j| values[(j as f64 * (n - 1) as f64 / (m - 1) as f64).round() as usize])
            .collect(),
    }
}
