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

mod cache;
mod masks;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use maaf_splat::Camera;

use super::bounds::{Aabb, bounds_from_cameras};
use super::dnerf::{Split, SplitMeta, read_split};
use super::dynamic3dgs::{TRAIN_META, read_dynamic3dgs};
use super::error::DataError;
use super::flow::{downsample_flow, read_flow};
use super::image::Image;
use super::median_mask::Rgb8;
use super::n3dv::{POSES_BOUNDS, read_plenoptic};
use super::points::{POINTS_FILE, read_points};
use super::visual_hull::{HullOptions, HullStep, HullView, hull_cloud};
use crate::{Background, PointCloud};

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
}

/// The points a run starts from ([`Dataset::initial_cloud`]).
#[derive(Clone, Debug)]
pub struct InitialCloud {
    /// The points.
    pub cloud: PointCloud,
    /// How many of them (the first ones) lie on visual hulls; 0 for a shipped cloud.
    pub hull_points: usize,
    /// One line saying where the points come from.
    pub description: String,
    /// One line to print as a warning: the visual hull put no point into the cloud.
    pub warning: Option<String>,
}

/// Where the moving-pixel masks of the `test` views come from.
#[derive(Clone, Debug, Default)]
pub enum MaskSource {
    /// The data set has none.
    #[default]
    None,
    /// One coverage file per test view (8-bit grey, `None` where a view has none).
    Files(Vec<Option<PathBuf>>),
    /// Background subtraction against each test camera's temporal median
    /// ([`super::median_mask`]); `camera[i]` is the camera group of test view `i`.
    TemporalMedian {
        /// Camera group of every test view.
        camera: Vec<usize>,
    },
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
        } else {
            return Err(DataError::request(
                root,
                "neither transforms_train.json (D-NeRF), poses_bounds.npy (Plenoptic Video) nor train_meta.json (Dynamic 3D Gaussians) found",
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

    /// The initial point cloud the folder ships (`points3d.ply`,
    /// [`super::points`]), read now; `None` when there is none.
    pub fn point_cloud(&self) -> Result<Option<PointCloud>, DataError> {
        let path = self.root.join(POINTS_FILE);
        if path.exists() {
            read_points(&path).map(Some)
        } else {
            Ok(None)
        }
    }

    /// The points a run starts from when the folder ships a point cloud or can carve
    /// one, with a line saying which: `points3d.ply` subsampled to `budget`; else, when
    /// the training images have foreground masks (the Dynamic 3D Gaussians layout),
    /// [`hull_cloud`] over at most `HullOptions::steps` evenly spread training times with
    /// `hull_fraction` of the budget on the hulls and the rest static, with `shell` on
    /// the capture dome's wall and floor ([`crate::shell`]), or with `first_time` the
    /// whole hull share on the earliest training time (a model that starts from one
    /// frame); `None` otherwise (the trainer then draws random points).
    pub fn initial_cloud(
        &self,
        budget: usize,
        hull_fraction: f64,
        shell: bool,
        first_time: bool,
        seed: u64,
    ) -> Result<Option<InitialCloud>, DataError> {
        if let Some(cloud) = self.point_cloud()? {
            let n = cloud.len();
            let cloud = cloud.subsample(budget, seed);
            let description = format!("{} of the {n} points of {POINTS_FILE}", cloud.len());
            return Ok(Some(InitialCloud {
                cloud,
                hull_points: 0,
                description,
                warning: None,
            }));
        }
        if self.train_masks.is_empty() {
            return Ok(None);
        }
        let start = std::time::Instant::now();
        let train = self.split(Split::Train)?;
        let mut times: Vec<f64> = train.frames.iter().map(|f| f.time).collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        if first_time {
            times.truncate(1);
        }
        let options = HullOptions {
            dynamic_fraction: hull_fraction,
            shell,
            ..HullOptions::default()
        };
        let picked = spread(&times, options.steps);
        let steps: Vec<HullStep> = picked
            .iter()
            .map(|&time| HullStep {
                time,
                views: train
                    .frames
                    .iter()
                    .filter(|f| f.time == time)
                    .filter_map(|f| {
                        self.train_mask(&f.file).map(|m| HullView {
                            camera: f.camera.clone(),
                            image: f.file.clone(),
                            mask: m.to_path_buf(),
                        })
                    })
                    .collect(),
            })
            .collect();
        let mut centres: Vec<glam::DVec3> =
            train.frames.iter().map(|f| f.camera.center()).collect();
        centres.dedup();
        let (cloud, dynamic) = hull_cloud(&steps, &centres, budget, &options, seed)?;
        let description = format!(
            "{} points: {dynamic} on the visual hulls of the foreground masks at {} times (at most {:.0} % of the budget), {} static {} ({:.1} s)",
            cloud.len(),
            steps.len(),
            100.0 * options.dynamic_fraction,
            cloud.len() - dynamic,
            if shell {
                "on the capture dome's wall and floor (random in the box where rays miss it)"
            } else {
                "at random in the box of the cameras and the hulls"
            },
            start.elapsed().as_secs_f64()
        );
        let warning = (dynamic == 0 && hull_fraction > 0.0 && budget > 0).then(|| {
            format!(
                "the visual hull of the foreground masks put no point into the initial cloud (no region is seen in the foreground of {} cameras at once: small or coarse masks?); training starts from random static points only",
                options.min_views
            )
        });
        Ok(Some(InitialCloud {
            cloud,
            hull_points: dynamic,
            description,
            warning,
        }))
    }

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
    /// else [`bounds_from_cameras`] of the training cameras.
    pub fn scene_bounds(&self) -> Aabb {
        self.bounds
    }

    /// One view at `scale`; decodes its image only if this (view, scale) is not cached.
    pub fn view(&self, split: Split, index: usize, scale: f64) -> Result<View, DataError> {
        let k = self.factor(split, scale)?;
        self.load(split, &[index], &[k])?;
        self.cached_view(split, index, k)
    }

    /// All views of a split at `scale` (decoded in parallel on first use, then cached).
    pub fn views(&self, split: Split, scale: f64) -> Result<Vec<View>, DataError> {
        let k = self.factor(split, scale)?;
        let all: Vec<usize> = (0..self.len(split)).collect();
        self.load(split, &all, &[k])?;
        all.into_iter()
            .map(|i| self.cached_view(split, i, k))
            .collect()
    }

    /// Training views at `scale`.
    pub fn train_views(&self, scale: f64) -> Result<Vec<View>, DataError> {
        self.views(Split::Train, scale)
    }

    /// Test views at `scale`.
    pub fn test_views(&self, scale: f64) -> Result<Vec<View>, DataError> {
        self.views(Split::Test, scale)
    }

    /// Decodes the views `indices` of `split` once each and fills the cache for all
    /// `scales` at once (the multi-scale evaluation asks for several scales of the same
    /// test images).
    pub fn preload(
        &self,
        split: Split,
        indices: &[usize],
        scales: &[f64],
    ) -> Result<(), DataError> {
        let ks = scales
            .iter()
            .map(|&s| self.factor(split, s))
            .collect::<Result<Vec<u32>, _>>()?;
        self.load(split, indices, &ks)
    }

    /// Drops every cached image of `split` (the trainer keeps its own copy of the
    /// training images; a later request decodes them again).
    pub fn evict(&self, split: Split) {
        if let Ok(mut cache) = self.cache.lock() {
            cache.retain(|(s, _, _), _| *s != split);
        }
    }

    /// Number of (view, scale) images currently cached.
    pub fn cached_images(&self) -> usize {
        self.cache.lock().map_or(0, |c| c.len())
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

    /// Moving-object coverage of `test` frame `index` at `scale` (`[H, W, 1]`, the
    /// fraction of each pixel that sees a moving object, box-averaged over the `k x k`
    /// source pixels), or `None` when the data set has no masks. Generated scenes ship
    /// exact masks (`cam00/masks/`, or `seg/` of every camera in the Dynamic 3D
    /// Gaussians layout); real Dynamic 3D Gaussians test cameras get theirs by
    /// background subtraction ([`MaskSource::TemporalMedian`]).
    pub fn moving_mask(&self, index: usize, scale: f64) -> Result<Option<Image>, DataError> {
        let k = self.factor(Split::Test, scale)?;
        let frame = self.frame(Split::Test, index)?;
        let full = match &self.masks {
            MaskSource::None => return Ok(None),
            MaskSource::Files(files) => match files.get(index) {
                Some(Some(path)) => masks::read_coverage(path, &frame.camera)?,
                _ => return Ok(None),
            },
            MaskSource::TemporalMedian { camera } => {
                let group = camera.get(index).copied().unwrap_or(0);
                masks::median_coverage(self, group, camera, &frame.file)?
            }
        };
        masks::downsample_coverage(full, k, scale, &frame.file)
    }

    /// Where the test views' moving masks come from.
    pub fn mask_source(&self) -> &MaskSource {
        &self.masks
    }

    /// Foreground coverage of `train` view `index` at `scale` (`[H, W, 1]`, the
    /// fraction of each pixel its mask file calls foreground, box-averaged over the
    /// `k x k` source pixels), or `None` when the view has no mask file (only the
    /// Dynamic 3D Gaussians layout's `seg/` gives training views masks).
    pub fn train_foreground(&self, index: usize, scale: f64) -> Result<Option<Image>, DataError> {
        let k = self.factor(Split::Train, scale)?;
        let frame = self.frame(Split::Train, index)?;
        let Some(path) = self.train_mask(&frame.file) else {
            return Ok(None);
        };
        let full = masks::read_coverage(path, &frame.camera)?;
        let binary = Image {
            data: full
                .data
                .iter()
                .map(|&v| f32::from(u8::from(v > 0.5)))
                .collect(),
            ..full
        };
        masks::downsample_coverage(binary, k, scale, path)
    }

    /// The foreground mask file of a training image, when the data set has one.
    pub fn train_mask(&self, image: &Path) -> Option<&Path> {
        self.train_masks.get(image).map(PathBuf::as_path)
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
