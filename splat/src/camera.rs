//! Pinhole camera in OpenCV axes and its JSON file format.

use std::path::Path;

use glam::{DMat3, DMat4, DVec3, DVec4};
use serde::{Deserialize, Serialize};

/// Errors raised while reading or validating a camera; each names the file and field.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// The file could not be read.
    #[error("{path}: cannot read camera file: {source}")]
    Io {
        /// File that failed.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The JSON is malformed or a field is missing or of the wrong type.
    #[error("{path}: invalid camera JSON: {message}")]
    Json {
        /// File that failed.
        path: String,
        /// serde_json's description, which names the field.
        message: String,
    },
    /// A field has a value the camera cannot use.
    #[error("{path}: field `{field}`: {message}")]
    Invalid {
        /// File (or `<memory>`) that failed.
        path: String,
        /// Offending field.
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
}

/// A pinhole camera: OpenCV axes (x right, y down, z forward), world-to-camera
/// rigid transform, intrinsics in pixels, pixel centres at `(x + 0.5, y + 0.5)`.
///
/// A world point `p` maps to camera space `c = R p + t` and to the pixel
/// `(fx c.x / c.z + cx, fy c.y / c.z + cy)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels (image centre is `width / 2`).
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Row-major 4x4 world-to-camera matrix (rotation + translation, last row 0 0 0 1).
    pub world_to_camera: [[f64; 4]; 4],
}

/// Largest width or height a camera file may ask for, pixels.
pub const MAX_SIDE: u32 = 16_384;
/// Largest image a camera file may ask for, pixels (64 megapixels: about 770 MB of
/// f32 RGB plus the renderer's per-pixel buffers).
pub const MAX_PIXELS: u64 = 64_000_000;
/// Widest field of view a pinhole camera may have, degrees, along either image axis
/// (`2 atan(W / 2 fx)`): at 180 the focal length is zero and every projection
/// degenerates; past 179 it is a tenth of a percent of the image width, which no
/// pinhole data set uses (wider lenses are fisheyes, another model).
pub const MAX_FOV_DEGREES: f64 = 179.0;
/// Largest camera translation (|t| of world-to-camera, the camera centre's distance
/// from the world origin), world units: scenes are normalised to units of about one
/// (D-NeRF's cameras sit 4 units out, N3DV's within a few), so 10^6 only refuses
/// poses that are broken (1e30), where f32 centres would lose every digit.
pub const MAX_TRANSLATION: f64 = 1e6;

impl CameraError {
    /// The offending field of an [`CameraError::Invalid`] (`fx`, `cx`,
    /// `world_to_camera`, `width/height`, ...), so a loader can name its own field.
    pub fn field(&self) -> Option<&'static str> {
        match self {
            CameraError::Invalid { field, .. } => Some(field),
            _ => None,
        }
    }

    /// What is wrong, without the file name: `field: message` for an invalid value.
    pub fn reason(&self) -> String {
        match self {
            CameraError::Invalid { field, message, .. } => format!("{field}: {message}"),
            other => other.to_string(),
        }
    }
}

/// Largest deviation of a pose's rotation block from a rotation (`|R^T R - I|`
/// entrywise) and of its last row from `[0, 0, 0, 1]` that a camera accepts: far
/// above the rounding of poses stored in `f32`, far below any scale or shear.
pub const RIGID_TOLERANCE: f64 = 1e-3;

/// Why the 4x4 pose `m` (world-to-camera or camera-to-world) is not a rigid
/// transform, or `None` when it is: last row `[0, 0, 0, 1]` and a rotation block
/// (`|R^T R - I| <` [`RIGID_TOLERANCE`] entrywise, `det R > 0`).
pub fn rigid_problem(m: &DMat4) -> Option<String> {
    let last = m.row(3);
    if (last - DVec4::new(0.0, 0.0, 0.0, 1.0)).abs().max_element() > RIGID_TOLERANCE {
        return Some(format!(
            "last row is [{}, {}, {}, {}], expected [0, 0, 0, 1]",
            last.x, last.y, last.z, last.w
        ));
    }
    let r = DMat3::from_mat4(*m);
    let rtr = r.transpose() * r;
    let err = (rtr.x_axis - DVec3::X)
        .abs()
        .max_element()
        .max((rtr.y_axis - DVec3::Y).abs().max_element())
        .max((rtr.z_axis - DVec3::Z).abs().max_element());
    if err > RIGID_TOLERANCE || r.determinant() <= 0.0 {
        return Some(format!(
            "rotation block is not a rotation (|R^T R - I| = {err:.2e}, det {:.3})",
            r.determinant()
        ));
    }
    None
}

impl Camera {
    /// Builds a camera from a world-to-camera matrix and intrinsics, validating it.
    pub fn new(
        width: u32,
        height: u32,
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        world_to_camera: [[f64; 4]; 4],
    ) -> Result<Self, CameraError> {
        let cam = Camera {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            world_to_camera,
        };
        cam.validate("<memory>")?;
        Ok(cam)
    }

    /// Builds a camera from a camera-to-world pose (OpenCV axes) and intrinsics.
    pub fn from_camera_to_world(
        width: u32,
        height: u32,
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        camera_to_world: DMat4,
    ) -> Result<Self, CameraError> {
        if camera_to_world.determinant().abs() < 1e-12 || !camera_to_world.is_finite() {
            return Err(CameraError::Invalid {
                path: "<memory>".into(),
                field: "camera_to_world",
                message: "matrix is singular or not finite".into(),
            });
        }
        let w2c = camera_to_world.inverse();
        Self::new(width, height, fx, fy, cx, cy, mat4_to_rows(w2c))
    }

    /// Reads the JSON camera format
    /// `{"width","height","fx","fy","cx","cy","world_to_camera":[[4]x4]}`.
    pub fn from_json_file(path: &Path) -> Result<Self, CameraError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| CameraError::Io {
            path: shown.clone(),
            source,
        })?;
        Self::from_json_str(&text, &shown)
    }

    /// Parses the JSON camera format; `origin` names the source in errors.
    pub fn from_json_str(text: &str, origin: &str) -> Result<Self, CameraError> {
        let cam: Camera = serde_json::from_str(text).map_err(|e| CameraError::Json {
            path: origin.into(),
            message: e.to_string(),
        })?;
        cam.validate(origin)?;
        Ok(cam)
    }

    /// Serialises to the JSON camera format.
    pub fn to_json_string(&self) -> String {
        // Serialising plain numbers and arrays cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Checks the camera (`origin` names it in errors): a non-empty size within
    /// [`MAX_SIDE`] and [`MAX_PIXELS`], finite positive focal lengths giving a field
    /// of view below [`MAX_FOV_DEGREES`], a finite principal point that keeps every
    /// pixel within half of it of the optical axis (an off-centre crop of a larger
    /// image is fine, a principal point at 10^12 px is not), and a finite, rigid pose
    /// ([`rigid_problem`]) with a translation within [`MAX_TRANSLATION`]. Every
    /// constructor runs it; data loaders that build a camera field by field call it.
    pub fn validate(&self, origin: &str) -> Result<(), CameraError> {
        let bad = |field: &'static str, message: String| CameraError::Invalid {
            path: origin.into(),
            field,
            message,
        };
        if self.width == 0 || self.height == 0 {
            return Err(bad(
                "width/height",
                format!("{}x{} is empty", self.width, self.height),
            ));
        }
        if self.width > MAX_SIDE
            || self.height > MAX_SIDE
            || u64::from(self.width) * u64::from(self.height) > MAX_PIXELS
        {
            return Err(bad(
                "width/height",
                format!(
                    "{}x{} is over the cap of {MAX_SIDE} px a side and {MAX_PIXELS} pixels",
                    self.width, self.height
                ),
            ));
        }
        for (field, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(field, format!("{v} must be finite and positive")));
            }
        }
        for (field, v, side) in [("fx", self.fx, self.width), ("fy", self.fy, self.height)] {
            let fov = 2.0 * (0.5 * f64::from(side) / v).atan().to_degrees();
            if fov >= MAX_FOV_DEGREES {
                return Err(bad(
                    field,
                    format!(
                        "{v} px gives a field of view of {fov:.3} degrees over {side} px; a pinhole camera needs less than {MAX_FOV_DEGREES}"
                    ),
                ));
            }
        }
        let limit = (0.5 * MAX_FOV_DEGREES).to_radians().tan();
        for (field, v, side, f) in [
            ("cx", self.cx, self.width, self.fx),
            ("cy", self.cy, self.height, self.fy),
        ] {
            if !v.is_finite() {
                return Err(bad(field, format!("{v} is not finite")));
            }
            // The pixel farthest from the principal point, as an angle off the axis.
            let reach = v.abs().max((f64::from(side) - v).abs());
            if reach > f * limit {
                return Err(bad(
                    field,
                    format!(
                        "{v} px puts pixels {:.3} degrees off the optical axis (focal length {f} px, {side} px image); a pinhole camera sees less than {} degrees either side",
                        (reach / f).atan().to_degrees(),
                        0.5 * MAX_FOV_DEGREES
                    ),
                ));
            }
        }
        let m = self.world_to_camera_mat();
        if !m.is_finite() {
            return Err(bad("world_to_camera", "contains a non-finite value".into()));
        }
        let t = m.w_axis.truncate().length();
        if t > MAX_TRANSLATION {
            return Err(bad(
                "world_to_camera",
                format!(
                    "translation of length {t:.3e} is beyond {MAX_TRANSLATION:e} world units: a broken pose"
                ),
            ));
        }
        if m.determinant().abs() < 1e-12 {
            return Err(bad("world_to_camera", "matrix is singular".into()));
        }
        if let Some(problem) = rigid_problem(&m) {
            return Err(bad("world_to_camera", problem));
        }
        Ok(())
    }

    /// The world-to-camera matrix as a glam matrix.
    pub fn world_to_camera_mat(&self) -> DMat4 {
        let r = &self.world_to_camera;
        DMat4::from_cols(
            DVec4::new(r[0][0], r[1][0], r[2][0], r[3][0]),
            DVec4::new(r[0][1], r[1][1], r[2][1], r[3][1]),
            DVec4::new(r[0][2], r[1][2], r[2][2], r[3][2]),
            DVec4::new(r[0][3], r[1][3], r[2][3], r[3][3]),
        )
    }

    /// Rotation part `R` of the world-to-camera transform.
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_mat4(self.world_to_camera_mat())
    }

    /// Translation part `t` of the world-to-camera transform.
    pub fn translation(&self) -> DVec3 {
        let r = &self.world_to_camera;
        DVec3::new(r[0][3], r[1][3], r[2][3])
    }

    /// Camera centre in world coordinates, `-R^T t`.
    pub fn center(&self) -> DVec3 {
        self.world_to_camera_mat()
            .inverse()
            .transform_point3(DVec3::ZERO)
    }

    /// World point to camera space, `R p + t`.
    pub fn to_camera(&self, p: DVec3) -> DVec3 {
        self.world_to_camera_mat().transform_point3(p)
    }

    /// Projects a world point to pixel coordinates and camera depth z, or `None` when
    /// the point is not in front of the camera (z <= 0).
    pub fn project(&self, p: DVec3) -> Option<(f64, f64, f64)> {
        let c = self.to_camera(p);
        (c.z > 0.0).then(|| {
            (
                self.fx * c.x / c.z + self.cx,
                self.fy * c.y / c.z + self.cy,
                c.z,
            )
        })
    }

    /// `tan(fov_x / 2)` measured from the principal point to the image border,
    /// `width / (2 fx)` (3DGS convention).
    pub fn tan_half_fov_x(&self) -> f64 {
        self.width as f64 / (2.0 * self.fx)
    }

    /// `tan(fov_y / 2)`, `height / (2 fy)`.
    pub fn tan_half_fov_y(&self) -> f64 {
        self.height as f64 / (2.0 * self.fy)
    }

    /// The same camera rendering at scale `s`: width, height, fx, fy, cx, cy are all
    /// multiplied by `s` (width and height rounded to the nearest pixel).
    pub fn scaled(&self, s: f64) -> Camera {
        Camera {
            width: ((self.width as f64 * s).round() as u32).max(1),
            height: ((self.height as f64 * s).round() as u32).max(1),
            fx: self.fx * s,
            fy: self.fy * s,
            cx: self.cx * s,
            cy: self.cy * s,
            world_to_camera: self.world_to_camera,
        }
    }
}

fn mat4_to_rows(m: DMat4) -> [[f64; 4]; 4] {
    let mut rows = [[0.0; 4]; 4];
    for (i, row) in rows.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = m.col(j)[i];
        }
    }
    rows
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn identity_cam() -> Camera {
        let mut w2c = [[0.0; 4]; 4];
        for (i, row) in w2c.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        w2c[2][3] = 4.0;
        Camera::new(100, 80, 50.0, 50.0, 50.0, 40.0, w2c).expect("valid camera")
    }

    #[test]
    fn principal_axis_projects_to_principal_point() {
        let cam = identity_cam();
        let (u, v, z) = cam.project(DVec3::ZERO).expect("in front");
        assert_eq!((u, v, z), (50.0, 40.0, 4.0));
        assert!((cam.center() - DVec3::new(0.0, 0.0, -4.0)).length() < 1e-12);
    }

    #[test]
    fn scaled_multiplies_intrinsics() {
        let cam = identity_cam().scaled(0.5);
        assert_eq!((cam.width, cam.height), (50, 40));
        assert_eq!((cam.fx, cam.cx, cam.cy), (25.0, 25.0, 20.0));
    }

    #[test]
    fn json_round_trip_and_errors_name_the_field() {
        let cam = identity_cam();
        let back = Camera::from_json_str(&cam.to_json_string(), "cam.json").expect("parses");
        assert_eq!(cam, back);
        let missing = r#"{"width":4,"height":4,"fx":1,"fy":1,"cx":2,"world_to_camera":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#;
        let err = Camera::from_json_str(missing, "cam.json")
            .unwrap_err()
            .to_string();
        assert!(err.contains("cam.json") && err.contains("cy"), "{err}");
        let singular = r#"{"width":4,"height":4,"fx":1,"fy":1,"cx":2,"cy":2,"world_to_camera":[[0,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#;
        let err = Camera::from_json_str(singular, "cam.json")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("world_to_camera") && err.contains("singular"),
            "{err}"
        );
    }
}
