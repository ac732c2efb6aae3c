//! The Plenoptic Video (Neural 3D Video, "N3DV") format: `poses_bounds.npy` plus one
//! folder of extracted frames per camera.
//!
//! # Layout
//! `root/poses_bounds.npy` and, per camera, `root/camXX/images/NNNN.png` (the layout
//! 4DGaussians' N3DV reader extracts to; `.jpg` frames are read too). Camera folders are
//! the sub-folders named `cam` followed by digits, sorted by name; row `i` of
//! `poses_bounds.npy` belongs to the `i`-th of them (4DGaussians pairs rows with the
//! sorted `cam*.mp4` the same way). The first, `cam00`, is held out for the `test` split
//! (4DGaussians' `eval_index = 0`); every other camera's frames form `train`, camera by
//! camera. Frames are the image files of `images/` sorted by name; every camera must
//! have the same number `F` of them, all of one size.
//!
//! # `poses_bounds.npy`
//! A float64 (or float32) array of shape `N x 17`. Row `i` is a `3 x 5` matrix flattened
//! row by row, then `near, far` (depth bounds, unused here). The matrix is `[R | c | hwf]`:
//! the columns of `R` are the camera's *down, right, back* axes in world coordinates
//! (LLFF's convention), `c` is the camera centre, and `hwf = [H, W, focal]` (pixels of
//! the original videos, 2028 x 2704 for N3DV). maaf cameras use OpenCV axes (x right,
//! y down, z forward; [`maaf_splat::Camera`]), so the camera-to-world matrix is
//! `[R[:, 1], R[:, 0], -R[:, 2], c]` ([`llff_to_opencv`]); 4DGaussians reaches the same
//! matrix in two steps (`[R1, -R0, R2]`, OpenGL axes, then negating y and z, as the
//! D-NeRF loader's [`super::dnerf::opengl_to_opencv`] does).
//!
//! # Intrinsics
//! Frames are usually extracted smaller than `W x H` (4DGaussians uses 1352 x 1014, half
//! size). With `s = frame width / W` the focal length is `fx = fy = focal s`, the
//! principal point the frame centre, and `H s` must match the frame height within 1%.
//!
//! # Time
//! Frame `i` of `F` has `t = i / F`, as 4DGaussians' reader (`idx / countss`, where
//! `countss = 300` is the length of every N3DV video), so `t` runs over
//! `[0, (F - 1) / F]` and never reaches 1.
//!
//! # maaf extras (ignored by other readers)
//! `maaf generate --rig multiview` also writes `maaf_scene.json` (`scene_bounds` as in
//! D-NeRF jsons, used for initialisation; without it bounds are estimated from the
//! cameras), `cam00/flow/NNNN.png` (exact forward flow from frame `NNNN` to the next,
//! KITTI format, [`super::flow`]; makes a `video` split of `cam00`'s frames) and
//! `cam00/masks/NNNN.png` (8-bit grey: the fraction of the pixel that sees a moving
//! object, `0` static, `255` moving, in between on silhouettes).
//!
//! # Extracting frames from the dataset's videos
//! In a scene folder (`cam00.mp4`, ..., `poses_bounds.npy`), at half size like
//! 4DGaussians, numbered from 0:
//! ```text
//! for v in cam*.mp4; do c=${v%.mp4}; mkdir -p $c/images;
//!   ffmpeg -i $v -vf scale=iw/2:ih/2 -start_number 0 $c/images/%04d.png; done
//! ```
//!
//! # Memory
//! A multi-view video has cameras x frames views, and `Dataset::train_views` decodes and
//! keeps all of them as `f32` RGB: `12 W H` bytes each. Real N3DV (20 cameras x 300
//! frames at 1352 x 1014) is 16.5 MB a view, 94 GB for the 5700 training views at full
//! size; note 1014 has no factor 4, so the half-size frames have exact box-downsampled
//! scales 1/2, 1/13 and 1/26 only. `Dataset::open_capped` keeps fewer time steps.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec4};
use maaf_splat::Camera;
use npyz::{Order, WriterBuilder};

use super::dnerf::{Frame, Split, SplitMeta, check_rigid, parse_bounds};
use super::error::DataError;
use super::image::image_size;

/// File name of the camera table.
pub const POSES_BOUNDS: &str = "poses_bounds.npy";
/// File name of maaf's optional scene description (`scene_bounds`).
pub const SCENE_JSON: &str = "maaf_scene.json";
/// Values per row of `poses_bounds.npy`: a `3 x 5` matrix and `near, far`.
pub const ROW_LEN: usize = 17;

/// One camera of `poses_bounds.npy`, converted.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseRow {
    /// Camera-to-world matrix in OpenCV axes.
    pub camera_to_world: DMat4,
    /// Image height of the original video, pixels.
    pub height: f64,
    /// Image width of the original video, pixels.
    pub width: f64,
    /// Focal length at `width x height`, pixels.
    pub focal: f64,
    /// Near depth bound.
    pub near: f64,
    /// Far depth bound.
    pub far: f64,
}

/// Camera-to-world in OpenCV axes from LLFF's `3 x 4` `[down, right, back | centre]`
/// (rows of the matrix): `[R[:, 1], R[:, 0], -R[:, 2], c]`.
pub fn llff_to_opencv(m: [[f64; 4]; 3]) -> DMat4 {
    let col = |c: usize, sign: f64| DVec4::new(sign * m[0][c], sign * m[1][c], sign * m[2][c], 0.0);
    DMat4::from_cols(
        col(1, 1.0),
        col(0, 1.0),
        col(2, -1.0),
        DVec4::new(m[0][3], m[1][3], m[2][3], 1.0),
    )
}

/// The inverse of [`llff_to_opencv`]: LLFF's `3 x 4` rows `[down, right, back | centre]`
/// of an OpenCV camera-to-world matrix.
pub fn opencv_to_llff(c2w: DMat4) -> [[f64; 4]; 3] {
    let (x, y, z, t) = (c2w.x_axis, c2w.y_axis, c2w.z_axis, c2w.w_axis);
    std::array::from_fn(|r| [y[r], x[r], -z[r], t[r]])
}

/// Encodes rows as `poses_bounds.npy` bytes (float64, C order, `N x 17`).
pub fn encode_poses_bounds(rows: &[PoseRow]) -> std::io::Result<Vec<u8>> {
    let mut values = Vec::with_capacity(rows.len() * ROW_LEN);
    for row in rows {
        let m = opencv_to_llff(row.camera_to_world);
        let hwf = [row.height, row.width, row.focal];
        for r in 0..3 {
            values.extend_from_slice(&m[r]);
            values.push(hwf[r]);
        }
        values.extend_from_slice(&[row.near, row.far]);
    }
    let mut out = Vec::new();
    let mut writer = npyz::WriteOptions::<f64>::new()
        .default_dtype()
        .shape(&[rows.len() as u64, ROW_LEN as u64])
        .writer(&mut out)
        .begin_nd()?;
    writer.extend(values)?;
    writer.finish()?;
    Ok(out)
}

/// Parses `poses_bounds.npy` bytes (`path` names the file in errors): shape `N x 17`,
/// float64 or float32, C or Fortran order; every matrix rigid, `hwf` positive.
pub fn parse_poses_bounds(bytes: &[u8], path: &Path) -> Result<Vec<PoseRow>, DataError> {
    let bad_npy = |m: String| DataError::Image {
        path: path.display().to_string(),
        message: format!("not a readable .npy array: {m}"),
    };
    let npy = npyz::NpyFile::new(bytes).map_err(|e| bad_npy(e.to_string()))?;
    let shape = npy.shape().to_vec();
    if shape.len() != 2 || shape[1] != ROW_LEN as u64 || shape[0] == 0 {
        return Err(DataError::field(
            path,
            "shape",
            format!("expected (N, 17) with N >= 1, got {shape:?}"),
        ));
    }
    let order = npy.order();
    let dtype = npy.dtype().descr();
    let values: Vec<f64> = match npy.try_data::<f64>() {
        Ok(reader) => reader.collect::<Result<_, _>>(),
        Err(npy) => match npy.try_data::<f32>() {
            Ok(reader) => reader.map(|v| v.map(f64::from)).collect(),
            Err(_) => {
                return Err(DataError::field(
                    path,
                    "dtype",
                    format!("expected float64 or float32, got {dtype}"),
                ));
            }
        },
    }
    .map_err(|e| bad_npy(e.to_string()))?;
    let n = shape[0] as usize;
    let at = |r: usize, c: usize| match order {
        Order::C => values[r * ROW_LEN + c],
        Order::Fortran => values[c * n + r],
    };
    let mut rows = Vec::with_capacity(n);
    for i in 0..n {
        if let Some(c) = (0..ROW_LEN).find(|&c| !at(i, c).is_finite()) {
            return Err(DataError::field(
                path,
                format!("rows[{i}][{c}]"),
                format!("{} is not finite", at(i, c)),
            ));
        }
        let m: [[f64; 4]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| at(i, r * 5 + c)));
        let [height, width, focal] = [at(i, 4), at(i, 9), at(i, 14)];
        if !(height > 0.0 && width > 0.0 && focal > 0.0) {
            return Err(DataError::field(
                path,
                format!("rows[{i}].hwf"),
                format!("[H, W, focal] = [{height}, {width}, {focal}] must all be positive"),
            ));
        }
        let camera_to_world = llff_to_opencv(m);
        check_rigid(path, &format!("rows[{i}].c2w"), &camera_to_world)?;
        rows.push(PoseRow {
            camera_to_world,
            height,
            width,
            focal,
            near: at(i, 15),
            far: at(i, 16),
        });
    }
    Ok(rows)
}

/// The splits of a Plenoptic Video folder, as the D-NeRF loader's [`SplitMeta`]s.
#[derive(Clone, Debug)]
pub struct Plenoptic {
    /// `train`, `test` and, when `cam00/flow` exists, `video` (cam00 with flow).
    pub splits: BTreeMap<Split, SplitMeta>,
    /// Moving-coverage mask file of each `test` frame, when `cam00/masks` exists.
    pub masks: Vec<Option<PathBuf>>,
    /// The camera table, one row per camera folder.
    pub rows: Vec<PoseRow>,
}

/// Reads `root/poses_bounds.npy`, the camera folders and every frame header (see the
/// module doc); no image is decoded.
pub fn read_plenoptic(root: &Path) -> Result<Plenoptic, DataError> {
    let npy = root.join(POSES_BOUNDS);
    let bytes = std::fs::read(&npy).map_err(|e| DataError::io(&npy, "cannot read", e))?;
    let rows = parse_poses_bounds(&bytes, &npy)?;
    let cams = camera_folders(root)?;
    if cams.len() != rows.len() {
        return Err(DataError::field(
            &npy,
            "shape",
            format!(
                "{} rows but {} has {} camera folders (cam00, cam01, ...): one row per camera",
                rows.len(),
                root.display(),
                cams.len()
            ),
        ));
    }
    let frames: Vec<Vec<PathBuf>> = cams
        .iter()
        .map(|c| frame_files(&c.join("images")))
        .collect::<Result<_, _>>()?;
    let count = frames[0].len();
    for (cam, list) in cams.iter().zip(&frames) {
        if list.len() != count {
            return Err(DataError::request(
                &cam.join("images"),
                format!(
                    "has {} frames but {} has {count}: every camera needs the same frames",
                    list.len(),
                    cams[0].join("images").display()
                ),
            ));
        }
    }
    let (width, height) = image_size(&frames[0][0])?;
    for file in frames.iter().flatten() {
        let size = image_size(file)?;
        if size != (width, height) {
            return Err(DataError::Image {
                path: file.display().to_string(),
                message: format!(
                    "is {}x{} but {} is {width}x{height}: all frames must have one size",
                    size.0,
                    size.1,
                    frames[0][0].display()
                ),
            });
        }
    }
    let mut cameras = Vec::with_capacity(rows.len());
    for (i, row) in rows.iter().enumerate() {
        cameras.push(frame_camera(&npy, i, row, width, height)?);
    }
    let time = |j: usize| j as f64 / count as f64;
    let meta = |split: Split, frames: Vec<Frame>| SplitMeta {
        split,
        json: npy.clone(),
        camera_angle_x: 2.0 * (0.5 * width as f64 / cameras[0].fx).atan(),
        width,
        height,
        focal: cameras[0].fx,
        frames,
        scene_bounds: None,
    };
    let frame = |c: usize, j: usize, flow: Option<PathBuf>| Frame {
        file: frames[c][j].clone(),
        time: time(j),
        camera: cameras[c].clone(),
        flow,
    };
    let train: Vec<Frame> = (1..cams.len())
        .flat_map(|c| (0..count).map(move |j| (c, j)))
        .map(|(c, j)| frame(c, j, None))
        .collect();
    if train.is_empty() {
        return Err(DataError::field(
            &npy,
            "shape",
            "only one camera: cam00 is the test camera, training needs at least one more",
        ));
    }
    let mut splits = BTreeMap::new();
    let mut train_meta = meta(Split::Train, train);
    let scene_json = root.join(SCENE_JSON);
    if scene_json.exists() {
        train_meta.scene_bounds = Some(read_scene_bounds(&scene_json)?);
    }
    splits.insert(Split::Train, train_meta);
    splits.insert(
        Split::Test,
        meta(Split::Test, (0..count).map(|j| frame(0, j, None)).collect()),
    );
    let flows = extras(&cams[0].join("flow"), &frames[0], count - 1)?;
    if !flows.is_empty() {
        let video = (0..count)
            .map(|j| frame(0, j, flows.get(j).cloned()))
            .collect();
        splits.insert(Split::Video, meta(Split::Video, video));
    }
    let masks = extras(&cams[0].join("masks"), &frames[0], count)?
        .into_iter()
        .map(Some)
        .collect();
    Ok(Plenoptic {
        splits,
        masks,
        rows,
    })
}

/// The camera of row `i` for frames of `width x height`: `fx = fy = focal width / W`,
/// principal point at the frame centre; the frame's aspect must match `W x H` (1%).
fn frame_camera(
    npy: &Path,
    i: usize,
    row: &PoseRow,
    width: u32,
    height: u32,
) -> Result<Camera, DataError> {
    let s = width as f64 / row.width;
    let expected_h = row.height * s;
    if (expected_h - height as f64).abs() > 0.01 * height as f64 {
        return Err(DataError::field(
            npy,
            format!("rows[{i}].hwf"),
            format!(
                "H x W = {} x {} does not have the aspect of the {width}x{height} frames",
                row.height, row.width
            ),
        ));
    }
    let f = row.focal * s;
    let (cx, cy) = (0.5 * width as f64, 0.5 * height as f64);
    Camera::from_camera_to_world(width, height, f, f, cx, cy, row.camera_to_world)
        .map_err(|e| DataError::field(npy, format!("rows[{i}].c2w"), e.to_string()))
}

/// Sub-folders of `root` named `cam` + digits, sorted by name.
fn camera_folders(root: &Path) -> Result<Vec<PathBuf>, DataError> {
    let entries = std::fs::read_dir(root).map_err(|e| DataError::io(root, "cannot list", e))?;
    let mut cams: Vec<PathBuf> = entries
        .flatten()
        .filter(|e| e.path().is_dir())
        .filter(|e| {
            let name = e.file_name().to_string_lossy().to_string();
            name.strip_prefix("cam")
                .is_some_and(|d| !d.is_empty() && d.chars().all(|c| c.is_ascii_digit()))
        })
        .map(|e| e.path())
        .collect();
    cams.sort();
    if cams.is_empty() {
        return Err(DataError::request(
            root,
            "no camera folders (cam00/images/0000.png, ...): extract the frames of the cam*.mp4 videos first",
        ));
    }
    Ok(cams)
}

/// Image files (`.png`, `.jpg`, `.jpeg`) of a folder, sorted by name; at least one.
fn frame_files(dir: &Path) -> Result<Vec<PathBuf>, DataError> {
    let entries =
        std::fs::read_dir(dir).map_err(|e| DataError::io(dir, "cannot list frames", e))?;
    let mut files: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase())
                .is_some_and(|e| matches!(e.as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(DataError::request(dir, "has no .png or .jpg frames"));
    }
    Ok(files)
}

/// The per-frame extra files of `dir` (`dir/<frame stem>.png` for the first `n`
/// frames), or nothing when `dir` does not exist; every one of them must exist.
fn extras(dir: &Path, frames: &[PathBuf], n: usize) -> Result<Vec<PathBuf>, DataError> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    frames[..n]
        .iter()
        .map(|f| {
            let stem = f.file_stem().map(|s| s.to_string_lossy().to_string());
            let path = dir.join(format!("{}.png", stem.unwrap_or_default()));
            if path.is_file() {
                Ok(path)
            } else {
                Err(DataError::request(
                    &path,
                    format!("missing: {} needs one file per frame", dir.display()),
                ))
            }
        })
        .collect()
}

/// `scene_bounds` of `maaf_scene.json`.
fn read_scene_bounds(path: &Path) -> Result<super::bounds::Aabb, DataError> {
    let text = std::fs::read_to_string(path).map_err(|e| DataError::io(path, "cannot read", e))?;
    let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| DataError::Json {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    let bounds = value
        .get("scene_bounds")
        .ok_or_else(|| DataError::field(path, "scene_bounds", "missing"))?;
    parse_bounds(path, bounds)
}
