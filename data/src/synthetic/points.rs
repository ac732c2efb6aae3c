//! The initial point cloud a generated data set ships (`points3d.ply`,
//! [`crate::points`]): what structure from motion over the training views
//! would give with perfect matching. Surface points seen by a training camera at its
//! time, coloured as shaded there, each with that time (the merged per-frame clouds
//! SpacetimeGS prepares for multi-view video; D-NeRF scenes ship none, and loaders
//! then start from random points).

use maaf_splat::Camera;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::render::pixel_ray;
use super::scene::Scene;
use crate::PointCloud;

/// Points a generated data set ships: enough for the default `init_points` (10 000)
/// to be a subsample.
pub const GENERATED_POINTS: usize = 20_000;

/// About `total` surface points seen by `views` (camera, time): the same number of
/// rays per view through uniformly random positions of its image, the first surface
/// each ray hits (rays that hit nothing are dropped), its shaded colour and the
/// view's time. Seeded; views are visited in order.
pub fn visible_points(
    scene: &Scene,
    views: &[(Camera, f64)],
    total: usize,
    seed: u64,
) -> PointCloud {
    let per_view = total.div_ceil(views.len().max(1));
    let mut rng = Pcg64::seed_from_u64(seed ^ 0x5EED_0F90_1A75);
    let mut cloud = PointCloud {
        points: Vec::with_capacity(total),
        colours: Vec::with_capacity(total),
        times: Some(Vec::with_capacity(total)),
    };
    for (cam, t) in views {
        let posed = scene.at(*t);
        for _ in 0..per_view {
            let px = rng.random_range(0.0..cam.width as f64);
            let py = rng.random_range(0.0..cam.height as f64);
            let (o, d) = pixel_ray(cam, px, py);
            let Some(hit) = posed.trace_all(o, d) else {
                continue;
            };
            cloud.points.push((o + hit.dist * d).to_array());
            cloud.colours.push(posed.shade(&hit));
            if let Some(times) = cloud.times.as_mut() {
                times.push(*t);
            }
        }
    }
    cloud
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{build_scene, rig};

    #[test]
    fn points_lie_on_the_surfaces_their_camera_saw_at_their_time() {
        let scene = build_scene("dolly").expect("scene");
        let views: Vec<(Camera, f64)> = [0.0, 0.5, 1.0]
            .iter()
            .map(|&t| (rig::camera_at(rig::video_position(), 64).expect("cam"), t))
            .collect();
        let cloud = visible_points(&scene, &views, 300, 1);
        assert!(cloud.len() > 150 && cloud.len() <= 300, "{}", cloud.len());
        let times = cloud.times.as_ref().expect("times");
        for (i, p) in cloud.points.iter().enumerate() {
            let (cam, t) = views
                .iter()
                .find(|v| v.1 == times[i])
                .expect("a view's time");
            // The ray from the camera to the point hits the scene at the point.
            let o = cam.center();
            let to = glam::DVec3::from_array(*p) - o;
            let hit = scene.at(*t).trace_all(o, to.normalize()).expect("hit");
            assert!(
                (hit.dist - to.length()).abs() < 1e-9,
                "point {i} is not the first surface"
            );
            assert!(cloud.colours[i].iter().all(|c| (0.0..=1.0).contains(c)));
        }
        // The flyer is seen at t = 0.5 by this camera: some points lie on it then.
        let flyer = scene
            .objects
            .iter()
            .position(|o| o.name == "flyer")
            .expect("flyer");
        let (centre, r) = scene.at(0.5).bounding_sphere(flyer);
        let on_flyer = cloud
            .points
            .iter()
            .zip(times)
            .filter(|(p, t)| {
                **t == 0.5 && (glam::DVec3::from_array(**p) - centre).length() < r + 1e-9
            })
            .count();
        assert!(on_flyer > 0, "no point on the flyer");
    }
}
