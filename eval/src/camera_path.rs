//! Camera paths for videos of a trained scene: an orbit around the point the
//! training cameras look at, and a spiral around their mean pose (the forward-facing
//! path of LLFF-style multi-view video). Both keep the intrinsics of a given camera
//! and look at the same target in every frame.

use glam::{DMat4, DVec3, DVec4};
use maaf_splat::Camera;

use crate::Error;

/// Where the training cameras are and what they look at, the frame of every path.
#[derive(Clone, Debug, PartialEq)]
pub struct Rig {
    /// The point nearest (least squares) to every camera's optical axis; the mean
    /// of the centres plus the mean forward direction when the axes are parallel.
    pub target: DVec3,
    /// The mean of the cameras' up directions (OpenCV axes: `-y`), unit length.
    pub up: DVec3,
    /// The cameras' centres.
    pub centres: Vec<DVec3>,
}

impl Rig {
    /// The rig of `cameras` (at least one).
    pub fn of(cameras: &[Camera]) -> Result<Rig, Error> {
        if cameras.is_empty() {
            return Err(Error::Input("a camera path needs training cameras".into()));
        }
        let poses: Vec<DMat4> = cameras
            .iter()
            .map(|c| c.world_to_camera_mat().inverse())
            .collect();
        let centres: Vec<DVec3> = poses.iter().map(|p| p.w_axis.truncate()).collect();
        let forwards: Vec<DVec3> = poses
            .iter()
            .map(|p| p.z_axis.truncate().normalize())
            .collect();
        let up = poses
            .iter()
            .map(|p| -p.y_axis.truncate())
            .sum::<DVec3>()
            .normalize_or(DVec3::Y);
        // Least squares: sum (I - d d^T) p = sum (I - d d^T) c.
        let mut a = glam::DMat3::ZERO;
        let mut b = DVec3::ZERO;
        for (c, d) in centres.iter().zip(&forwards) {
            let m = glam::DMat3::IDENTITY - glam::DMat3::from_cols(*d * d.x, *d * d.y, *d * d.z);
            a += m;
            b += m * *c;
        }
        let mean = centres.iter().sum::<DVec3>() / centres.len() as f64;
        let target = if a.determinant().abs() > 1e-9 * cameras.len().pow(3) as f64 {
            a.inverse() * b
        } else {
            let spread = centres
                .iter()
                .map(|c| c.distance(mean))
                .fold(0.0, f64::max)
                .max(1.0);
            mean + forwards.iter().sum::<DVec3>().normalize_or(DVec3::Z) * spread
        };
        Ok(Rig {
            target,
            up,
            centres,
        })
    }

    /// `frames` cameras on a circle around `target` about `up`, at the training
    /// cameras' mean horizontal distance and height, starting at `start`'s bearing, one
    /// full turn; each with `start`'s intrinsics.
    pub fn orbit(&self, start: &Camera, frames: usize) -> Result<Vec<Camera>, Error> {
        let (e1, e2) = plane_axes(self.up);
        let rel: Vec<DVec3> = self.centres.iter().map(|c| *c - self.target).collect();
        let height = rel.iter().map(|r| r.dot(self.up)).sum::<f64>() / rel.len() as f64;
        let radius = rel
            .iter()
            .map(|r| (*r - self.up * r.dot(self.up)).length())
            .sum::<f64>()
            / rel.len() as f64;
        let s = start.center() - self.target;
        let phase = s.dot(e2).atan2(s.dot(e1));
        (0..frames)
            .map(|i| {
                let a = phase + std::f64::consts::TAU * i as f64 / frames as f64;
                let pos = self.target
                    + self.up * height
                    + (e1 * a.cos() + e2 * a.sin()) * radius.max(1e-6);
                look_at(start, pos, self.target, self.up)
            })
            .collect()
    }

    /// `frames` cameras on a spiral around `start`'s position in its image plane (two
    /// turns, radius half the training cameras' spread across the view or 5 % of the
    /// distance to the target, whichever is larger; the depth swings by a quarter of
    /// the radius), each looking at `target` with `start`'s intrinsics.
    pub fn spiral(&self, start: &Camera, frames: usize) -> Result<Vec<Camera>, Error> {
        let centre = start.center();
        let forward = (self.target - centre).normalize_or(DVec3::Z);
        let right = forward.cross(self.up).normalize_or(DVec3::X);
        let up = right.cross(forward);
        let spread = self
            .centres
            .iter()
            .map(|c| {
                let r = *c - centre;
                r.dot(right).abs().max(r.dot(up).abs())
            })
            .fold(0.0, f64::max);
        let radius = (0.5 * spread).max(0.05 * centre.distance(self.target));
        (0..frames)
            .map(|i| {
                let a = 2.0 * std::f64::consts::TAU * i as f64 / frames as f64;
                let pos = centre
                    + (right * a.cos() + up * a.sin()) * radius
                    + forward * (0.25 * radius * (0.5 * a).sin());
                look_at(start, pos, self.target, self.up)
            })
            .collect()
    }
}

/// Two unit vectors orthogonal to `up` and to each other.
fn plane_axes(up: DVec3) -> (DVec3, DVec3) {
    let e1 = up.any_orthonormal_vector();
    (e1, up.cross(e1))
}

/// A camera at `pos` looking at `target` with `up` pointing up in the image (OpenCV
/// axes: x right, y down, z forward), with `like`'s size and intrinsics.
fn look_at(like: &Camera, pos: DVec3, target: DVec3, up: DVec3) -> Result<Camera, Error> {
    let z = (target - pos).normalize();
    let x = z.cross(up).normalize_or(z.any_orthonormal_vector());
    let y = z.cross(x);
    let c2w = DMat4::from_cols(
        x.extend(0.0),
        y.extend(0.0),
        z.extend(0.0),
        DVec4::new(pos.x, pos.y, pos.z, 1.0),
    );
    Camera::from_camera_to_world(
        like.width,
        like.height,
        like.fx,
        like.fy,
        like.cx,
        like.cy,
        c2w,
    )
    .map_err(|e| Error::Input(format!("camera path: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera at `pos` looking at the origin with +Y up, 64x48.
    fn cam(pos: DVec3) -> Camera {
        let like = Camera::new(
            64,
            48,
            50.0,
            50.0,
            32.0,
            24.0,
            DMat4::IDENTITY.to_cols_array_2d(),
        )
        .expect("camera");
        look_at(&like, pos, DVec3::ZERO, DVec3::Y).expect("look at")
    }

    /// The image position of `p` in `c`.
    fn pixel(c: &Camera, p: DVec3) -> (f64, f64) {
        let (u, v, _) = c.project(p).expect("in front");
        (u, v)
    }

    #[test]
    fn look_at_puts_the_target_at_the_principal_point_and_up_at_the_top() {
        let c = cam(DVec3::new(3.0, 1.0, 4.0));
        let (u, v) = pixel(&c, DVec3::ZERO);
        assert!(
            (u - 32.0).abs() < 1e-9 && (v - 24.0).abs() < 1e-9,
            "{u} {v}"
        );
        let (_, v_up) = pixel(&c, DVec3::new(0.0, 0.1, 0.0));
        assert!(
            v_up < 24.0,
            "a point above the target is above the centre: {v_up}"
        );
    }

    #[test]
    fn a_ring_of_cameras_orbits_its_target() {
        // Evenly spaced, so the cameras' mean up direction is the ring's axis.
        let ring: Vec<Camera> = (0..6)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 6.0 + 0.3;
                cam(DVec3::new(4.0 * a.cos(), 1.0, 4.0 * a.sin()))
            })
            .collect();
        let rig = Rig::of(&ring).expect("rig");
        assert!(rig.target.length() < 1e-6, "{:?}", rig.target);
        let path = rig.orbit(&ring[0], 8).expect("orbit");
        assert_eq!(path.len(), 8);
        assert!(path[0].center().distance(ring[0].center()) < 1e-6);
        for c in &path {
            let p = c.center();
            assert!((p.y - 1.0).abs() < 1e-6, "{p:?}");
            assert!(
                (DVec3::new(p.x, 0.0, p.z).length() - 4.0).abs() < 1e-6,
                "{p:?}"
            );
            let (u, v) = pixel(c, rig.target);
            assert!((u - 32.0).abs() < 1e-6 && (v - 24.0).abs() < 1e-6);
        }
    }

    #[test]
    fn a_spiral_circles_the_start_and_looks_at_the_target() {
        let arc: Vec<Camera> = (-2..=2)
            .map(|i| cam(DVec3::new(0.5 * i as f64, 0.0, 5.0)))
            .collect();
        let rig = Rig::of(&arc).expect("rig");
        let path = rig.spiral(&arc[2], 12).expect("spiral");
        let start = arc[2].center();
        for c in &path {
            let d = c.center().distance(start);
            assert!(d > 0.4 && d < 1.5, "{d}");
            let (u, v) = pixel(c, rig.target);
            assert!((u - 32.0).abs() < 1e-6 && (v - 24.0).abs() < 1e-6);
        }
    }
}
