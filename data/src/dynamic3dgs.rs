//! The Dynamic 3D Gaussians layout (Luiten et al., "Dynamic 3D Gaussians: Tracking by
//! Persistent Dynamic View Synthesis", 3DV 2024) of multi-view videos such as the CMU
//! Panoptic sports sequences.
//!
//! # Layout
//! `root/train_meta.json` and `root/test_meta.json`, each an object with
//! - `w`, `h`: the image size in pixels (every image of the file has it);
//! - `k[frame][i]`: the 3x3 intrinsics in pixels of entry `i` of frame `frame`
//!   (`[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`; principal points off centre are kept);
//! - `w2c[frame][i]`: the 4x4 world-to-camera matrix, OpenCV axes (x right, y down,
//!   z forward), the convention maaf cameras use ([`maaf_splat::Camera`]);
//! - `fn[frame][i]`: the image path relative to `root/ims/` (`<cam>/<frame:06>.jpg`);
//! - `cam_id[frame][i]`: the camera number.
//!
//! Foreground masks, when present, are `root/seg/<fn with .png>` (the real data has them
//! for the training cameras only). The reference reader's `init_pt_cld.npz` is not read:
//! without it, training starts from [`super::visual_hull`]'s points.
//!
//! # Splits and time
//! `train_meta.json` gives the `train` split, `test_meta.json` the `test` split and an
//! optional `val_meta.json` (not part of the reference layout) a `val` split, e.g. a
//! training camera held out to choose settings on without touching the test cameras.
//! All are ordered camera by camera (cameras in order of first appearance, each camera's
//! frames in order), so a frame stride picks the same frames of every test camera.
//! Frame `j` of the `F` training frames has `t = j / (F - 1)` (`0` when `F = 1`), so
//! time spans `[0, 1]`. The test views are mapped by frame number: frame `j` of
//! `test_meta.json` is frame `j` of the training sequence, at the same time, also when
//! the test file lists fewer frames; one listing more frames than the training file
//! (frames with no training time) is refused.
//!
//! # Moving pixels of the test views
//! When every test image has a mask (the generator writes exact ones) those are the
//! moving-pixel masks; otherwise each test camera's movers are found by background
//! subtraction against its temporal median ([`super::median_mask`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DMat4;
use maaf_splat::Camera;
use rayon::prelude::*;
use serde::Deserialize;

use super::dnerf::{Frame, Split, SplitMeta, check_rigid};
use super::error::DataError;
use super::image::image_size;

/// File name of the training cameras' table.
pub const TRAIN_META: &str = "train_meta.json";
/// File name of the test cameras' table.
pub const TEST_META: &str = "test_meta.json";
/// File name of the optional validation cameras' table (same format).
pub const VAL_META: &str = "val_meta.json";
/// Folder of the images, `ims/<cam>/<frame:06>.jpg`.
pub const IMAGES_DIR: &str = "ims";
/// Folder of the foreground masks, `seg/<cam>/<frame:06>.png`.
pub const MASKS_DIR: &str = "seg";

/// One `*_meta.json` file as stored.
#[derive(Clone, Debug, Deserialize)]
pub struct MetaFile {
    /// Image width, pixels.
    pub w: u32,
    /// Image height, pixels.
    pub h: u32,
    /// Intrinsics per frame and entry.
    pub k: Vec<Vec<[[f64; 3]; 3]>>,
    /// World-to-camera matrices per frame and entry (OpenCV axes).
    pub w2c: Vec<Vec<[[f64; 4]; 4]>>,
    /// Image paths relative to `ims/`, per frame and entry.
    #[serde(rename = "fn")]
    pub files: Vec<Vec<String>>,
    /// Camera numbers per frame and entry.
    pub cam_id: Vec<Vec<i64>>,
}

/// One view of a meta file: which camera, which frame, where its files are.
#[derive(Clone, Debug)]
pub struct MetaView {
    /// Camera number (`cam_id`).
    pub cam_id: i64,
    /// Frame index `j` (time `j / (F - 1)`).
    pub frame: usize,
    /// The image.
    pub image: PathBuf,
    /// Its foreground mask (`seg/`), when the file exists.
    pub mask: Option<PathBuf>,
    /// The camera at the image size.
    pub camera: Camera,
}

/// A parsed meta file: its views in camera-major order and the frame count.
#[derive(Clone, Debug)]
pub struct Meta {
    /// The json file.
    pub json: PathBuf,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Frames `F` (the outer length of every table).
    pub frames: usize,
    /// Views ordered camera by camera, each camera's frames in order.
    pub views: Vec<MetaView>,
}

impl Meta {
    /// The time of frame `j` of a sequence of `frames`: `j / (frames - 1)`, or `0`
    /// for a single frame.
    pub fn time(j: usize, frames: usize) -> f64 {
        if frames <= 1 {
            0.0
        } else {
            j as f64 / (frames - 1) as f64
        }
    }

    /// The camera numbers in order of first appearance.
    pub fn cameras(&self) -> Vec<i64> {
        camera_order(&self.views)
    }

    /// The split's [`SplitMeta`] (frames in the order of [`Meta::views`]), frame `j`
    /// at the time of frame `j` of a sequence of `timeline` frames (the training
    /// file's: test frames are mapped by frame number).
    pub fn split_meta(&self, split: Split, timeline: usize) -> SplitMeta {
        let focal = self.views.first().map_or(1.0, |v| v.camera.fx);
        SplitMeta {
            split,
            json: self.json.clone(),
            camera_angle_x: 2.0 * (0.5 * self.width as f64 / focal).atan(),
            width: self.width,
            height: self.height,
            focal,
            frames: self
                .views
                .iter()
                .map(|v| Frame {
                    file: v.image.clone(),
                    time: Self::time(v.frame, timeline),
                    camera: v.camera.clone(),
                    flow: None,
                })
                .collect(),
            scene_bounds: None,
        }
    }
}

/// The splits of a Dynamic 3D Gaussians folder.
#[derive(Clone, Debug)]
pub struct Dynamic3dgs {
    /// `train_meta.json`, parsed.
    pub train: Meta,
    /// `test_meta.json`, parsed.
    pub test: Meta,
    /// `val_meta.json`, parsed, when the folder has one.
    pub val: Option<Meta>,
}

impl Dynamic3dgs {
    /// The `train`, `test` and (when present) `val` [`SplitMeta`]s.
    pub fn splits(&self) -> BTreeMap<Split, SplitMeta> {
        let frames = self.train.frames;
        let mut splits = BTreeMap::from([
            (Split::Train, self.train.split_meta(Split::Train, frames)),
            (Split::Test, self.test.split_meta(Split::Test, frames)),
        ]);
        if let Some(val) = &self.val {
            splits.insert(Split::Val, val.split_meta(Split::Val, frames));
        }
        splits
    }
}

/// Reads the meta files of `root` and every image header (module doc); no image is
/// decoded. Errors name the file and the entry at fault.
pub fn read_dynamic3dgs(root: &Path) -> Result<Dynamic3dgs, DataError> {
    let train = read_meta(root, &root.join(TRAIN_META))?;
    let test = read_meta(root, &root.join(TEST_META))?;
    let val_json = root.join(VAL_META);
    let val = val_json
        .is_file()
        .then(|| read_meta(root, &val_json))
        .transpose()?;
    for (meta, name) in
        std::iter::once((&test, TEST_META)).chain(val.as_ref().map(|v| (v, VAL_META)))
    {
        if meta.frames > train.frames {
            return Err(DataError::field(
                &meta.json,
                "fn",
                format!(
                    "has {} frames but {TRAIN_META} has {}: frame j of {name} is training frame j (its time), so its views may not outlast the training sequence",
                    meta.frames, train.frames
                ),
            ));
        }
    }
    Ok(Dynamic3dgs { train, test, val })
}

/// Parses one meta file (see the module doc) and checks its image headers.
pub fn read_meta(root: &Path, json: &Path) -> Result<Meta, DataError> {
    let text = std::fs::read_to_string(json).map_err(|e| DataError::io(json, "cannot read", e))?;
    let file: MetaFile = serde_json::from_str(&text).map_err(|e| DataError::Json {
        path: json.display().to_string(),
        message: e.to_string(),
    })?;
    parse_meta(root, json, &file)
}

/// Checks a parsed meta file and builds its views (camera-major); `json` names the
/// file in errors.
pub fn parse_meta(root: &Path, json: &Path, file: &MetaFile) -> Result<Meta, DataError> {
    let bad = |field: String, message: String| DataError::field(json, field, message);
    if file.w == 0 || file.h == 0 {
        return Err(bad(
            "w, h".into(),
            format!("image size {}x{} must be positive", file.w, file.h),
        ));
    }
    let frames = file.files.len();
    if frames == 0 {
        return Err(bad("fn".into(), "has no frames".into()));
    }
    for (name, len) in [
        ("k", file.k.len()),
        ("w2c", file.w2c.len()),
        ("cam_id", file.cam_id.len()),
    ] {
        if len != frames {
            return Err(bad(
                name.into(),
                format!("has {len} frames but fn has {frames}"),
            ));
        }
    }
    let mut views = Vec::new();
    for j in 0..frames {
        let n = file.files[j].len();
        if n == 0 {
            return Err(bad(format!("fn[{j}]"), "lists no camera".into()));
        }
        for (name, len) in [
            ("k", file.k[j].len()),
            ("w2c", file.w2c[j].len()),
            ("cam_id", file.cam_id[j].len()),
        ] {
            if len != n {
                return Err(bad(
                    format!("{name}[{j}]"),
                    format!("has {len} entries but fn[{j}] has {n}"),
                ));
            }
        }
        for i in 0..n {
            let camera = entry_camera(json, j, i, file)?;
            let rel = &file.files[j][i];
            let image = root.join(IMAGES_DIR).join(rel);
            let mask = root
                .join(MASKS_DIR)
                .join(Path::new(rel).with_extension("png"));
            views.push(MetaView {
                cam_id: file.cam_id[j][i],
                frame: j,
                image,
                mask: mask.is_file().then_some(mask),
                camera,
            });
        }
    }
    let order = camera_order(&views);
    views.sort_by_key(|v| {
        let rank = order.iter().position(|&c| c == v.cam_id).unwrap_or(0);
        (rank, v.frame)
    });
    for pair in views.windows(2) {
        if pair[0].cam_id == pair[1].cam_id && pair[0].frame == pair[1].frame {
            return Err(bad(
                format!("cam_id[{}]", pair[0].frame),
                format!("lists camera {} twice", pair[0].cam_id),
            ));
        }
    }
    views
        .par_iter()
        .map(|v| check_image(json, v, file.w, file.h))
        .collect::<Result<Vec<()>, _>>()?;
    Ok(Meta {
        json: json.to_path_buf(),
        width: file.w,
        height: file.h,
        frames,
        views,
    })
}

/// The camera numbers of `views` in order of first appearance.
fn camera_order(views: &[MetaView]) -> Vec<i64> {
    let mut ids: Vec<i64> = Vec::new();
    for v in views {
        if !ids.contains(&v.cam_id) {
            ids.push(v.cam_id);
        }
    }
    ids
}

/// The camera of entry `i` of frame `j`: `k` must be `[[fx, 0, cx], [0, fy, cy], [0, 0,
/// 1]]` with finite positive focal lengths and finite principal point, `w2c` rigid.
fn entry_camera(json: &Path, j: usize, i: usize, file: &MetaFile) -> Result<Camera, DataError> {
    let k = file.k[j][i];
    let field = format!("k[{j}][{i}]");
    if k.iter().flatten().any(|v| !v.is_finite()) {
        return Err(DataError::field(
            json,
            field,
            format!("{k:?} is not finite"),
        ));
    }
    let (fx, fy, cx, cy) = (k[0][0], k[1][1], k[0][2], k[1][2]);
    if !(fx > 0.0 && fy > 0.0) {
        return Err(DataError::field(
            json,
            field,
            format!("focal lengths fx = {fx}, fy = {fy} must be positive"),
        ));
    }
    let off = [k[0][1], k[1][0], k[2][0], k[2][1], k[2][2] - 1.0];
    if off.iter().any(|v| v.abs() > 1e-9 * fx.max(1.0)) {
        return Err(DataError::field(
            json,
            field,
            format!("{k:?}: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)"),
        ));
    }
    let rows = file.w2c[j][i];
    let field = format!("w2c[{j}][{i}]");
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(DataError::field(json, field, "is not finite"));
    }
    let w2c = DMat4::from_cols_array_2d(&rows).transpose();
    check_rigid(json, &field, &w2c)?;
    Camera::new(file.w, file.h, fx, fy, cx, cy, rows).map_err(|e| {
        // Name the table the camera's bad value came from.
        let field = match e.field() {
            Some("fx" | "fy" | "cx" | "cy") => format!("k[{j}][{i}]"),
            Some("width/height") => "w, h".to_string(),
            _ => field,
        };
        DataError::field(json, field, e.reason())
    })
}

/// The image of `v` must exist and be `w x h`.
fn check_image(json: &Path, v: &MetaView, w: u32, h: u32) -> Result<(), DataError> {
    let size = image_size(&v.image)?;
    if size != (w, h) {
        return Err(DataError::Image {
            path: v.image.display().to_string(),
            message: format!(
                "is {}x{} but {} says w x h = {w}x{h}",
                size.0,
                size.1,
                json.display()
            ),
        });
    }
    Ok(())
}
