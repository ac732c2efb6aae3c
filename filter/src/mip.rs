//! Mip-Splatting's static 3D filter (paper Eq. 2, Sec. 3.3).
//!
//! `nu_k = max_n 1_n(p_k) f_n / d_n` over the training cameras `n`, where the
//! visibility indicator `1_n` is Mip-Splatting's `compute_3D_filter` rule: camera
//! depth `z > near` (0.2) and the projection inside the image with a 15% margin.
//! Gaussians no camera sees get the smallest nu seen. The variance added by the
//! renderer's `apply_3d_filter` is `s3d / nu^2` (s3d = 0.2).
//!
//! Choices (documented differences from the reference code):
//! * `d_n` is the camera-space depth z (as the code; not the Euclidean distance).
//! * `f_n = max(fx, fy)` of camera `n`: the finest of the two pixel pitches bounds
//!   the highest frequency this camera can resolve, so the isotropic filter must
//!   not remove it. For square pixels (D-NeRF, Blender, most video rigs) it is the
//!   code's `focal_x`.
//! * The max is taken per camera over `f_n / z_n` (the paper's Eq. 2). The code uses
//!   one global focal (max over cameras) with the per-Gaussian minimum depth; the
//!   two agree when every training camera has the same focal length.

use maaf_splat::Camera;
use rayon::prelude::*;

use crate::config::{FilterConfig, FilterError};

/// A camera reduced to what the visibility test needs, in f64 (as `Camera`).
#[derive(Clone, Copy, Debug)]
pub struct Viewer {
    rows: [[f64; 4]; 3],
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    width: f64,
    height: f64,
    near: f64,
    margin: f64,
    /// Focal length used in `f / d`: `max(fx, fy)` (see the module docs).
    pub focal: f64,
}

impl Viewer {
    /// Prepares `camera` with the near plane and margin of `cfg`.
    pub fn new(camera: &Camera, cfg: &FilterConfig) -> Viewer {
        let m = &camera.world_to_camera;
        Viewer {
            rows: [m[0], m[1], m[2]],
            fx: camera.fx,
            fy: camera.fy,
            cx: camera.cx,
            cy: camera.cy,
            width: camera.width as f64,
            height: camera.height as f64,
            near: cfg.near as f64,
            margin: cfg.margin as f64,
            focal: camera.fx.max(camera.fy),
        }
    }

    /// Camera depth `z` of world point `p` when it is visible under Mip-Splatting's
    /// rule (`z > near`, pixel inside `[-m W, (1+m) W] x [-m H, (1+m) H]`), else `None`.
    #[inline]
    pub fn visible_depth(&self, p: [f32; 3]) -> Option<f64> {
        let [x, y, z] = [p[0] as f64, p[1] as f64, p[2] as f64];
        let r = &self.rows;
        let cz = r[2][0] * x + r[2][1] * y + r[2][2] * z + r[2][3];
        // Written so that a NaN depth is also rejected.
        if cz.is_nan() || cz <= self.near {
            return None;
        }
        let cx = r[0][0] * x + r[0][1] * y + r[0][2] * z + r[0][3];
        let cy = r[1][0] * x + r[1][1] * y + r[1][2] * z + r[1][3];
        let u = self.fx * cx / cz + self.cx;
        let v = self.fy * cy / cz + self.cy;
        let (mw, mh) = (self.margin * self.width, self.margin * self.height);
        let inside = u >= -mw && u <= self.width + mw && v >= -mh && v <= self.height + mh;
        inside.then_some(cz)
    }

    /// Sampling rate `f / z` of `p` in this camera (pixels per world unit), or `None`
    /// when not visible (paper Eq. 2 summand).
    #[inline]
    pub fn sampling_rate(&self, p: [f32; 3]) -> Option<f32> {
        self.visible_depth(p).map(|z| (self.focal / z) as f32)
    }
}

/// Static Mip-Splatting sampling rate per Gaussian (paper Eq. 2):
/// `nu_k = max_n 1_n(p_k) f_n / z_n`, unseen Gaussians get the smallest nu seen.
///
/// `centres` are the Gaussians' *canonical* (static) centres for the
/// "SaRO-GS + 3D filter" baseline; `cameras` are the training cameras only.
/// Errors with the config error if `cfg` is invalid, and with
/// [`FilterError::NothingVisible`] when no camera sees any Gaussian (and `centres`
/// is not empty). Parallel over Gaussians.
pub fn static_nu(
    centres: &[[f32; 3]],
    cameras: &[Camera],
    cfg: &FilterConfig,
) -> Result<Vec<f32>, FilterError> {
    cfg.validate()?;
    let viewers: Vec<Viewer> = cameras.iter().map(|c| Viewer::new(c, cfg)).collect();
    let mut nu: Vec<f32> = centres
        .par_iter()
        .map(|&p| {
            viewers
                .iter()
                .filter_map(|v| v.sampling_rate(p))
                .fold(0.0f32, f32::max)
        })
        .collect();
    fill_unseen(&mut nu)?;
    Ok(nu)
}

/// Replaces zeros (unseen) by the smallest positive value (Mip-Splatting's rule).
pub(crate) fn fill_unseen(nu: &mut [f32]) -> Result<(), FilterError> {
    if nu.is_empty() {
        return Ok(());
    }
    let min_seen = nu
        .iter()
        .copied()
        .filter(|&v| v > 0.0)
        .fold(f32::INFINITY, f32::min);
    if !min_seen.is_finite() {
        return Err(FilterError::NothingVisible);
    }
    for v in nu.iter_mut().filter(|v| **v <= 0.0) {
        *v = min_seen;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera at (0, 0, -dist) looking down +z, 100x100 pixels, f = 100.
    pub(crate) fn cam_at(dist: f64, f: f64) -> Camera {
        let mut w2c = [[0.0; 4]; 4];
        for (i, row) in w2c.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        w2c[2][3] = dist;
        Camera::new(100, 100, f, f, 50.0, 50.0, w2c).expect("camera")
    }

    #[test]
    fn near_plane_and_margin_follow_mip_splatting() {
        let cfg = FilterConfig::default();
        let v = Viewer::new(&cam_at(1.0, 100.0), &cfg);
        // Centre: z = 1, f/z = 100.
        assert_eq!(v.sampling_rate([0.0, 0.0, 0.0]), Some(100.0));
        // Behind the near plane (z = 0.2 exactly is culled: the test is z > 0.2).
        assert_eq!(v.visible_depth([0.0, 0.0, -0.8]), None);
        assert!(v.visible_depth([0.0, 0.0, -0.79]).is_some());
        // u = 100 x + 50 at z = 1: margin 15% of W = 100 allows u in [-15, 115].
        assert!(v.visible_depth([0.65, 0.0, 0.0]).is_some()); // u = 115
        assert!(v.visible_depth([0.66, 0.0, 0.0]).is_none()); // u = 116
        assert!(v.visible_depth([0.0, -0.65, 0.0]).is_some()); // v = -15
        assert!(v.visible_depth([0.0, -0.66, 0.0]).is_none());
    }

    #[test]
    fn static_nu_is_the_max_over_cameras_and_unseen_get_the_min() {
        let cfg = FilterConfig::default();
        let cams = [cam_at(2.0, 100.0), cam_at(4.0, 300.0)];
        let centres = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [50.0, 0.0, 0.0]];
        let nu = static_nu(&centres, &cams, &cfg).expect("visible");
        // Gaussian 0: max(100/2, 300/4) = 75; Gaussian 1: max(100/3, 300/5) = 60;
        // Gaussian 2 is off-screen everywhere: smallest seen = 60.
        assert_eq!(nu, vec![75.0, 60.0, 60.0]);
        let var = crate::FilterState::Mip3d {
            s3d: cfg.s3d,
            nu: nu.clone(),
        }
        .variance_at(0.0);
        assert!((var[0] - 0.2 / 5625.0).abs() < 1e-12);
        let err = static_nu(&[[50.0, 0.0, 0.0]], &cams, &cfg).expect_err("unseen");
        assert!(matches!(err, FilterError::NothingVisible));
        assert!(static_nu(&[], &cams, &cfg).expect("empty").is_empty());
    }

    #[test]
    fn focal_is_the_larger_of_fx_and_fy() {
        let cfg = FilterConfig::default();
        let mut cam = cam_at(2.0, 100.0);
        cam.fy = 150.0;
        assert_eq!(Viewer::new(&cam, &cfg).sampling_rate([0.0; 3]), Some(75.0));
    }
}
