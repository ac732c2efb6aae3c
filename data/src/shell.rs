//! Initial static points on a capture dome's shell: for a rig of cameras hung on the
//! walls of a room and looking in (the CMU Panoptic dome), the static background is
//! the wall the cameras hang on and the floor the actors stand on. Random points in
//! the room instead leave Gaussians floating inside it, which the training cameras,
//! seeing that wall from across the room, cannot tell from the wall but which a new
//! camera hung there sees right in front of its lens.
//!
//! # The shell
//! - the **wall**: the sphere fitted to the camera centres by least squares,
//!   `|c_i - o|^2 = r^2` (linear in `o` and `r^2 - |o|^2`);
//! - the **floor**: the plane `p . up = h` under the movers, with `up` the mean of the
//!   cameras' up axes (minus their image-y axis in world space) and `h` the lowest
//!   `p . up` of the visual hull's points (their feet), when there is a hull.
//!
//! # The points ([`shell_points`])
//! Background pixels (mask off) are drawn uniformly from the given views (seeded);
//! each pixel's ray from its camera centre through the pixel's centre ends where it
//! first meets the floor in front of the camera, else where it leaves the sphere; the
//! point takes the pixel's colour. Rays that leave the sphere within a tenth of its
//! radius (grazing the wall beside their own camera) are drawn again.

use glam::{DMat4, DVec3, DVec4};
use maaf_splat::Camera;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::error::DataError;
use super::visual_hull::{HullView, decode};
use crate::PointCloud;

/// The wall sphere and the optional floor plane of a rig.
#[derive(Clone, Debug, PartialEq)]
pub struct Shell {
    /// The sphere's centre.
    pub centre: DVec3,
    /// Its radius.
    pub radius: f64,
    /// `(up, h)`: the floor is `p . up = h`, `up` a unit vector.
    pub floor: Option<(DVec3, f64)>,
}

impl Shell {
    /// The shell of the cameras `cameras` (their centres' sphere, module doc) with the
    /// floor under `movers` (the visual hull's points; none: no floor). `None` for
    /// fewer than four cameras or centres in a plane (no sphere through them).
    pub fn fit(cameras: &[Camera], movers: &[[f64; 3]]) -> Option<Shell> {
        let centres: Vec<DVec3> = cameras.iter().map(Camera::center).collect();
        let (centre, radius) = fit_sphere(&centres)?;
        let up = cameras
            .iter()
            .map(|c| {
                let r = c.world_to_camera;
                -DVec3::new(r[1][0], r[1][1], r[1][2])
            })
            .sum::<DVec3>()
            .try_normalize();
        let floor = up.and_then(|up| {
            movers
                .iter()
                .map(|p| DVec3::from_array(*p).dot(up))
                .reduce(f64::min)
                .map(|h| (up, h))
        });
        Some(Shell {
            centre,
            radius,
            floor,
        })
    }

    /// Where the ray `origin + t dir` (`dir` unit, `origin` inside the sphere) ends:
    /// the floor when it meets it first in front of `origin`, else its exit from the
    /// sphere; `None` when that exit is within a tenth of the radius.
    pub fn hit(&self, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let oc = origin - self.centre;
        let b = dir.dot(oc);
        let c = oc.length_squared() - self.radius * self.radius;
        let exit = -b + (b * b - c).max(0.0).sqrt();
        let floor = self.floor.and_then(|(up, h)| {
            let down = dir.dot(up);
            let t = (h - origin.dot(up)) / down;
            (down < 0.0 && t > 0.0).then_some(t)
        });
        let t = match floor {
            Some(t) if t < exit => t,
            _ if exit < 0.1 * self.radius => return None,
            _ => exit,
        };
        Some(origin + t * dir)
    }
}

/// The sphere through `points` by linear least squares: `2 p . o + k = |p|^2` with
/// `k = r^2 - |o|^2`; `None` when the normal equations are singular.
pub fn fit_sphere(points: &[DVec3]) -> Option<(DVec3, f64)> {
    if points.len() < 4 {
        return None;
    }
    // Normal equations of the rows [2x, 2y, 2z, 1] . [o, k] = |p|^2.
    let mut a = DMat4::ZERO;
    let mut rhs = DVec4::ZERO;
    for p in points {
        let row = DVec4::new(2.0 * p.x, 2.0 * p.y, 2.0 * p.z, 1.0);
        a += DMat4::from_cols(row * row.x, row * row.y, row * row.z, row * row.w);
        rhs += row * p.length_squared();
    }
    // Singular (numerically) when the determinant is negligible against the entries'.
    let scale = a.to_cols_array().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if a.determinant().abs() <= 1e-12 * scale.powi(4) {
        return None;
    }
    let x = a.inverse() * rhs;
    let centre = DVec3::new(x[0], x[1], x[2]);
    let r2 = x[3] + centre.length_squared();
    (r2 > 0.0).then(|| (centre, r2.sqrt()))
}

/// `count` points on `shell` from the background pixels of `views` (module doc),
/// untimed; fewer when the views hold too few background pixels whose rays reach the
/// shell. Seeded.
pub fn shell_points(
    shell: &Shell,
    views: &[HullView],
    count: usize,
    seed: u64,
) -> Result<PointCloud, DataError> {
    let mut cloud = PointCloud {
        points: Vec::with_capacity(count),
        colours: Vec::with_capacity(count),
        times: None,
    };
    if views.is_empty() || count == 0 {
        return Ok(cloud);
    }
    let decoded: Vec<_> = views.par_iter().map(decode).collect::<Result<_, _>>()?;
    let mut rng = Pcg64::seed_from_u64(seed ^ 0x5e11);
    // Each draw picks a view, then a pixel; at most 20 tries per point.
    for _ in 0..20 * count {
        if cloud.len() == count {
            break;
        }
        let v = &decoded[rng.random_range(0..decoded.len())];
        let (w, h) = (v.camera.width as usize, v.camera.height as usize);
        let (x, y) = (rng.random_range(0..w), rng.random_range(0..h));
        if v.mask[y * w + x] {
            continue;
        }
        let cam = &v.camera;
        let local = DVec3::new(
            (x as f64 + 0.5 - cam.cx) / cam.fx,
            (y as f64 + 0.5 - cam.cy) / cam.fy,
            1.0,
        );
        let r = cam.world_to_camera;
        let rows = [0, 1, 2].map(|i| DVec3::new(r[i][0], r[i][1], r[i][2]));
        let dir = (rows[0] * local.x + rows[1] * local.y + rows[2] * local.z).normalize();
        let Some(p) = shell.hit(cam.center(), dir) else {
            continue;
        };
        let c = &v.image.data[3 * (y * w + x)..3 * (y * w + x) + 3];
        cloud.points.push(p.to_array());
        cloud
            .colours
            .push([c[0], c[1], c[2]].map(|u| f64::from(u) / 255.0));
    }
    Ok(cloud)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_fit_recovers_a_sphere_from_points_on_it() {
        let (o, r) = (DVec3::new(0.3, -1.2, 2.0), 2.5);
        let mut rng = Pcg64::seed_from_u64(1);
        let pts: Vec<DVec3> = (0..30)
            .map(|_| {
                let d = DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..0.2),
                    rng.random_range(-1.0..1.0),
                )
                .normalize();
                o + r * d
            })
            .collect();
        let (c, rr) = fit_sphere(&pts).expect("fits");
        assert!((c - o).length() < 1e-9 && (rr - r).abs() < 1e-9, "{c} {rr}");
        let flat: Vec<DVec3> = (0..8).map(|i| DVec3::new(i as f64, 0.0, 1.0)).collect();
        assert_eq!(fit_sphere(&flat), None);
    }

    #[test]
    fn rays_end_on_the_floor_or_leave_the_sphere() {
        let shell = Shell {
            centre: DVec3::ZERO,
            radius: 2.0,
            floor: Some((DVec3::new(0.0, -1.0, 0.0), -1.0)),
        };
        // From the centre straight down (+y is down): the floor at y = 1.
        let down = shell.hit(DVec3::ZERO, DVec3::Y).expect("hits");
        assert!((down - DVec3::new(0.0, 1.0, 0.0)).length() < 1e-12);
        // Sideways: the sphere.
        let side = shell.hit(DVec3::ZERO, DVec3::X).expect("hits");
        assert!((side - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-12);
        // From the wall outward: grazing, refused.
        assert_eq!(shell.hit(DVec3::new(1.999, 0.0, 0.0), DVec3::X), None);
        // Upward from a point on the wall: across the room.
        let up = shell
            .hit(DVec3::new(0.0, 0.0, 2.0), -DVec3::Z)
            .expect("hits");
        assert!((up - DVec3::new(0.0, 0.0, -2.0)).length() < 1e-9);
    }
}
