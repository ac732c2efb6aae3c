//! Camera rigs of the generated data sets: cameras on a spherical cap around the scene
//! looking at a common target (like D-NeRF's cameras on a sphere), in OpenCV axes.

use glam::{DMat4, DVec3, DVec4};
use maaf_splat::Camera;
use rand::{RngExt, SeedableRng};

use crate::dnerf::focal_from_angle;
use crate::error::DataError;

/// Point every camera looks at (world; z up).
pub const TARGET: DVec3 = DVec3::new(0.0, 0.0, 0.6);
/// Distance of every camera from [`TARGET`].
pub const RADIUS: f64 = 4.0;
/// Horizontal field of view, radians (50 degrees).
pub const CAMERA_ANGLE_X: f64 = 50.0 * std::f64::consts::PI / 180.0;
/// Azimuth range of the cap, degrees either side of the front (-y) direction.
pub const AZIMUTH_DEG: f64 = 60.0;
/// Elevation range of the cap, degrees above the horizon.
pub const ELEVATION_DEG: (f64, f64) = (12.0, 50.0);

/// Camera-to-world (OpenCV axes: x right, y down, z forward) of a camera at `eye`
/// looking at `target` with world z up.
pub fn look_at(eye: DVec3, target: DVec3) -> DMat4 {
    let fwd = (target - eye).normalize();
    let right = fwd.cross(DVec3::Z).normalize();
    let down = fwd.cross(right);
    DMat4::from_cols(
        right.extend(0.0),
        down.extend(0.0),
        fwd.extend(0.0),
        DVec4::new(eye.x, eye.y, eye.z, 1.0),
    )
}

/// Position on the cap: `TARGET + RADIUS (cos e sin a, -cos e cos a, sin e)`, azimuth `a`
/// measured from the front (-y) towards +x, elevation `e`, both in degrees.
pub fn cap_position(azimuth_deg: f64, elevation_deg: f64) -> DVec3 {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    TARGET + RADIUS * DVec3::new(e.cos() * a.sin(), -e.cos() * a.cos(), e.sin())
}

/// A pinhole camera of `size x size` pixels at `eye` looking at [`TARGET`], with
/// `f = size / (2 tan(CAMERA_ANGLE_X / 2))` and the principal point at the centre.
pub fn camera_at(eye: DVec3, size: u32) -> Result<Camera, DataError> {
    camera_wh(eye, size, size)
}

/// A pinhole camera of `width x height` pixels at `eye` looking at [`TARGET`], with
/// square pixels, `f = width / (2 tan(CAMERA_ANGLE_X / 2))` and the principal point at
/// the centre `(width / 2, height / 2)`.
pub fn camera_wh(eye: DVec3, width: u32, height: u32) -> Result<Camera, DataError> {
    let f = focal_from_angle(width, CAMERA_ANGLE_X);
    let (cx, cy) = (0.5 * width as f64, 0.5 * height as f64);
    Camera::from_camera_to_world(width, height, f, f, cx, cy, look_at(eye, TARGET)).map_err(|e| {
        DataError::Request {
            path: "<generator>".into(),
            message: format!("camera at {eye:?}: {e}"),
        }
    })
}

/// Azimuth half-range of the multi-view arc, degrees either side of the front.
pub const ARC_AZIMUTH_DEG: f64 = 45.0;

/// The `n` fixed cameras of the multi-view rig, like the Plenoptic Video rig (a row of
/// cameras facing the scene): index 0 is the held-out test camera `cam00` at the centre
/// of the arc (azimuth 0, elevation 17 degrees); cameras `1..n` are evenly spread over
/// azimuth `[-ARC_AZIMUTH_DEG, ARC_AZIMUTH_DEG]`, elevation alternating 12 and 22
/// degrees, so none coincides with `cam00` (the nearest is 5 degrees, 0.35 units, away).
pub fn arc_positions(n: usize) -> Vec<DVec3> {
    let train = n.saturating_sub(1);
    let mut out = vec![cap_position(0.0, 17.0)];
    out.extend((0..train).map(|i| {
        let s = if train > 1 {
            i as f64 / (train - 1) as f64
        } else {
            0.5
        };
        let e = if i % 2 == 0 { 12.0 } else { 22.0 };
        cap_position(-ARC_AZIMUTH_DEG + 2.0 * ARC_AZIMUTH_DEG * s, e)
    }));
    out.truncate(n);
    out
}

/// `n` random cap positions (uniform in azimuth and in `sin(elevation)`, i.e. uniform in
/// area on the cap), from a PCG stream seeded by `(seed, stream)`.
pub fn random_positions(n: usize, seed: u64, stream: u64) -> Vec<DVec3> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let (lo, hi) = (
        ELEVATION_DEG.0.to_radians().sin(),
        ELEVATION_DEG.1.to_radians().sin(),
    );
    (0..n)
        .map(|_| {
            let a = rng.random_range(-AZIMUTH_DEG..AZIMUTH_DEG);
            let e = rng.random_range(lo..hi).asin().to_degrees();
            cap_position(a, e)
        })
        .collect()
}

/// `n` fixed ring positions evenly spread over the cap's azimuth range, elevation
/// alternating between 18 and 34 degrees.
pub fn ring_positions(n: usize) -> Vec<DVec3> {
    (0..n)
        .map(|i| {
            let s = if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.5
            };
            let a = -AZIMUTH_DEG + 2.0 * AZIMUTH_DEG * s;
            let e = if i % 2 == 0 { 18.0 } else { 34.0 };
            cap_position(a, e)
        })
        .collect()
}

/// The fixed camera of the test video: azimuth -10 degrees, elevation 18 degrees.
pub fn video_position() -> DVec3 {
    cap_position(-10.0, 18.0)
}

/// `n` evenly spaced times `i / (n - 1)` in `[0, 1]` (`[0]` for `n = 1`).
pub fn even_times(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.0
            }
        })
        .collect()
}
