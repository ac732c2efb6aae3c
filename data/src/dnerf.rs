//! The D-NeRF data format: `transforms_{train,val,test}.json` plus RGBA PNGs.
//!
//! Each json holds `camera_angle_x` (horizontal field of view, radians) and `frames[]`
//! with `file_path` (relative to the data folder, `.png` appended when it has no
//! extension), `time` (read as is, never derived from the frame index) and
//! `transform_matrix`, a 4x4 camera-to-world matrix listed row by row in OpenGL/Blender
//! axes (x right, y up, camera looks down -z). It is converted to OpenCV axes by
//! negating its y and z columns, `c2w[:3, 1:3] *= -1`. Intrinsics:
//! `f = W / (2 tan(camera_angle_x / 2))` for both axes, principal point `(W/2, H/2)`.
//!
//! maaf's generator adds optional keys that other loaders ignore: `scene_bounds`
//! (`[[min x, y, z], [max x, y, z]]`) at the top level, and `flow_path` per frame of the
//! `video` split (forward flow to the next frame, see [`super::flow`]).

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3, DVec4};
use maaf_splat::Camera;
use serde_json::Value;

use super::bounds::Aabb;
use super::error::DataError;
use super::image::image_size;

/// A split of a data set, stored in `transforms_<name>.json`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Split {
    /// Training views.
    Train,
    /// Validation views (optional).
    Val,
    /// Test views.
    Test,
    /// A fixed-camera video with forward flow (optional; written by `maaf generate`).
    Video,
}

impl Split {
    /// Every split, in file order.
    pub const ALL: [Split; 4] = [Split::Train, Split::Val, Split::Test, Split::Video];

    /// The split's name as used in file names: `train`, `val`, `test`, `video`.
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Val => "val",
            Split::Test => "test",
            Split::Video => "video",
        }
    }

    /// The json file name, `transforms_<name>.json`.
    pub fn json_name(self) -> String {
        format!("transforms_{}.json", self.name())
    }
}

impl std::fmt::Display for Split {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One view of a split, as described by its json entry.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Resolved image path.
    pub file: PathBuf,
    /// Time stamp, exactly as written in the json.
    pub time: f64,
    /// Camera at the source resolution, OpenCV axes.
    pub camera: Camera,
    /// Forward-flow file of the `video` split (`flow_path`), if any.
    pub flow: Option<PathBuf>,
}

/// A parsed split: intrinsics, frames and the optional scene bounds.
#[derive(Clone, Debug)]
pub struct SplitMeta {
    /// Which split.
    pub split: Split,
    /// Path of the json it was read from.
    pub json: PathBuf,
    /// Horizontal field of view in radians.
    pub camera_angle_x: f64,
    /// Source image width in pixels (all frames share it).
    pub width: u32,
    /// Source image height in pixels.
    pub height: u32,
    /// Focal length in pixels at the source resolution, `W / (2 tan(camera_angle_x / 2))`.
    pub focal: f64,
    /// The frames, in json order.
    pub frames: Vec<Frame>,
    /// `scene_bounds` if the json has it.
    pub scene_bounds: Option<Aabb>,
}

/// Converts a camera-to-world matrix from OpenGL axes (y up, looking down -z) to OpenCV
/// axes (y down, looking down +z): `c2w[:3, 1:3] *= -1` (negates the y and z columns).
pub fn opengl_to_opencv(c2w: DMat4) -> DMat4 {
    DMat4::from_cols(c2w.x_axis, -c2w.y_axis, -c2w.z_axis, c2w.w_axis)
}

/// Focal length in pixels from the horizontal field of view: `W / (2 tan(angle / 2))`.
pub fn focal_from_angle(width: u32, camera_angle_x: f64) -> f64 {
    0.5 * width as f64 / (0.5 * camera_angle_x).tan()
}

/// Reads and checks `root/transforms_<split>.json` and the header of every image it
/// names (sizes must agree). Images are not decoded here.
pub fn read_split(root: &Path, split: Split) -> Result<SplitMeta, DataError> {
    let json = root.join(split.json_name());
    let text =
        std::fs::read_to_string(&json).map_err(|e| DataError::io(&json, "cannot read", e))?;
    parse_split(&text, &json, root, split)
}

/// Parses the text of a split json (`json` names it in errors; `root` resolves
/// `file_path`) and reads the image headers.
pub fn parse_split(
    text: &str,
    json: &Path,
    root: &Path,
    split: Split,
) -> Result<SplitMeta, DataError> {
    let value: Value = serde_json::from_str(text).map_err(|e| DataError::Json {
        path: json.display().to_string(),
        message: e.to_string(),
    })?;
    let top = value
        .as_object()
        .ok_or_else(|| DataError::field(json, "<root>", "expected a JSON object"))?;
    let camera_angle_x = number(json, "camera_angle_x", top.get("camera_angle_x"))?;
    let max_fov = maaf_splat::camera::MAX_FOV_DEGREES.to_radians();
    if !(camera_angle_x > 0.0 && camera_angle_x < max_fov) {
        return Err(DataError::field(
            json,
            "camera_angle_x",
            format!(
                "{camera_angle_x} is not a field of view in (0, {max_fov:.6}) radians (0 to {} degrees, the widest pinhole camera maaf accepts)",
                maaf_splat::camera::MAX_FOV_DEGREES
            ),
        ));
    }
    let scene_bounds = match top.get("scene_bounds") {
        None => None,
        Some(v) => Some(parse_bounds(json, v)?),
    };
    let frames_value = top
        .get("frames")
        .ok_or_else(|| DataError::field(json, "frames", "missing"))?;
    let list = frames_value.as_array().ok_or_else(|| {
        DataError::field(
            json,
            "frames",
            format!("expected an array, got {}", kind(frames_value)),
        )
    })?;
    if list.is_empty() {
        return Err(DataError::field(json, "frames", "is empty"));
    }

    let mut raw = Vec::with_capacity(list.len());
    for (i, f) in list.iter().enumerate() {
        let name = |k: &str| format!("frames[{i}].{k}");
        let obj = f
            .as_object()
            .ok_or_else(|| DataError::field(json, format!("frames[{i}]"), "expected an object"))?;
        let file_path = match obj.get("file_path") {
            None => return Err(DataError::field(json, name("file_path"), "missing")),
            Some(Value::String(s)) => s.clone(),
            Some(v) => {
                return Err(DataError::field(
                    json,
                    name("file_path"),
                    format!("expected a string, got {}", kind(v)),
                ));
            }
        };
        let time = number(json, &name("time"), obj.get("time"))?;
        // The filters and the lifespans are defined on normalised time.
        if !(0.0..=1.0).contains(&time) {
            return Err(DataError::field(
                json,
                name("time"),
                format!("{time} is outside [0, 1] (D-NeRF times are normalised)"),
            ));
        }
        let gl = matrix4(json, &name("transform_matrix"), obj.get("transform_matrix"))?;
        let flow = match obj.get("flow_path") {
            None | Some(Value::Null) => None,
            Some(Value::String(s)) => Some(root.join(s)),
            Some(v) => {
                return Err(DataError::field(
                    json,
                    name("flow_path"),
                    format!("expected a string, got {}", kind(v)),
                ));
            }
        };
        let mut file = root.join(&file_path);
        if file.extension().is_none() {
            file.set_extension("png");
        }
        raw.push((file, time, gl, flow));
    }

    // Image sizes from the headers; every frame of a split must match the first.
    let (width, height) = image_size(&raw[0].0)?;
    for (i, (file, ..)) in raw.iter().enumerate().skip(1) {
        let (w, h) = image_size(file)?;
        if (w, h) != (width, height) {
            return Err(DataError::field(
                json,
                format!("frames[{i}].file_path"),
                format!(
                    "{} is {w}x{h} but {} (frames[0]) is {width}x{height}: all images of a split must have one size",
                    file.display(),
                    raw[0].0.display()
                ),
            ));
        }
    }

    let focal = focal_from_angle(width, camera_angle_x);
    let mut frames = Vec::with_capacity(raw.len());
    for (i, (file, time, gl, flow)) in raw.into_iter().enumerate() {
        let field = format!("frames[{i}].transform_matrix");
        check_rigid(json, &field, &gl)?;
        let c2w = opengl_to_opencv(gl);
        let camera = Camera::from_camera_to_world(
            width,
            height,
            focal,
            focal,
            0.5 * width as f64,
            0.5 * height as f64,
            c2w,
        )
        .map_err(|e| DataError::field(json, field.clone(), e.to_string()))?;
        frames.push(Frame {
            file,
            time,
            camera,
            flow,
        });
    }
    Ok(SplitMeta {
        split,
        json: json.to_path_buf(),
        camera_angle_x,
        width,
        height,
        focal,
        frames,
        scene_bounds,
    })
}

fn kind(v: &Value) -> String {
    match v {
        Value::Null => "null".into(),
        Value::Bool(b) => format!("boolean {b}"),
        Value::Number(n) => format!("number {n}"),
        Value::String(s) => format!("string {s:?}"),
        Value::Array(_) => "an array".into(),
        Value::Object(_) => "an object".into(),
    }
}

fn number(json: &Path, field: &str, v: Option<&Value>) -> Result<f64, DataError> {
    let v = v.ok_or_else(|| DataError::field(json, field, "missing"))?;
    let x = v.as_f64().ok_or_else(|| {
        DataError::field(json, field, format!("expected a number, got {}", kind(v)))
    })?;
    if !x.is_finite() {
        return Err(DataError::field(json, field, format!("{x} is not finite")));
    }
    Ok(x)
}

/// A 4x4 matrix listed row by row (`m[row][col]`, numpy's `np.array(rows)`).
fn matrix4(json: &Path, field: &str, v: Option<&Value>) -> Result<DMat4, DataError> {
    let v = v.ok_or_else(|| DataError::field(json, field, "missing"))?;
    let rows = v.as_array().filter(|r| r.len() == 4).ok_or_else(|| {
        DataError::field(
            json,
            field,
            format!("expected 4 rows of 4 numbers, got {}", kind(v)),
        )
    })?;
    let mut m = [[0.0; 4]; 4];
    for (r, row) in rows.iter().enumerate() {
        let cols = row.as_array().filter(|c| c.len() == 4).ok_or_else(|| {
            DataError::field(json, format!("{field}[{r}]"), "expected a row of 4 numbers")
        })?;
        for (c, x) in cols.iter().enumerate() {
            m[r][c] = number(json, &format!("{field}[{r}][{c}]"), Some(x))?;
        }
    }
    Ok(DMat4::from_cols(
        DVec4::new(m[0][0], m[1][0], m[2][0], m[3][0]),
        DVec4::new(m[0][1], m[1][1], m[2][1], m[3][1]),
        DVec4::new(m[0][2], m[1][2], m[2][2], m[3][2]),
        DVec4::new(m[0][3], m[1][3], m[2][3], m[3][3]),
    ))
}

/// A camera-to-world matrix must be invertible and rigid
/// ([`maaf_splat::camera::rigid_problem`]: last row `0 0 0 1` and a rotation block).
pub(crate) fn check_rigid(json: &Path, field: &str, m: &DMat4) -> Result<(), DataError> {
    let det = m.determinant();
    if det.abs() < 1e-9 {
        return Err(DataError::field(
            json,
            field,
            format!("matrix is not invertible (determinant {det:.3e})"),
        ));
    }
    match maaf_splat::camera::rigid_problem(m) {
        Some(problem) => Err(DataError::field(json, field, problem)),
        None => Ok(()),
    }
}

pub(crate) fn parse_bounds(json: &Path, v: &Value) -> Result<Aabb, DataError> {
    let field = "scene_bounds";
    let pair = v
        .as_array()
        .filter(|a| a.len() == 2)
        .ok_or_else(|| DataError::field(json, field, "expected [[min x, y, z], [max x, y, z]]"))?;
    let mut corners = [DVec3::ZERO; 2];
    for (k, corner) in pair.iter().enumerate() {
        let xyz = corner
            .as_array()
            .filter(|a| a.len() == 3)
            .ok_or_else(|| DataError::field(json, format!("{field}[{k}]"), "expected 3 numbers"))?;
        for (j, x) in xyz.iter().enumerate() {
            corners[k][j] = number(json, &format!("{field}[{k}][{j}]"), Some(x))?;
        }
    }
    if !corners[0].cmplt(corners[1]).all() {
        return Err(DataError::field(
            json,
            field,
            "min must be below max on every axis",
        ));
    }
    Ok(Aabb {
        min: corners[0],
        max: corners[1],
    })
}
