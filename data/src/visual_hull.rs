//! Initial points for a multi-view video that ships none: the visual hull of the
//! foreground masks at a set of time steps (points with times on the movers) plus
//! random static points in the box of the camera centres.
//!
//! # Carving (one time step)
//! A voxel grid covers the region (the box of the camera centres grown by `margin` of
//! its size on every side) with `resolution` cells along its longest side (cubic
//! cells). A cell's centre `X` is projected into every training camera of the step;
//! `S` are the cameras where it lands inside the image in front of the camera. The cell
//! is *occupied* when `|S| >= min_views` and the mask is background at the projection
//! in at most `floor(miss_fraction |S|)` of them (a robust hull: a mask that misses
//! part of a person in one camera does not carve it away). Occupied cells with an empty
//! face neighbour are the *surface*; each gives one point, jittered uniformly inside
//! its cell (seeded), coloured by the mean over `S` of the image colours at the
//! projections that the mask calls foreground, timed at the step's time.
//!
//! # The cloud ([`hull_cloud`])
//! `dynamic_fraction` of the budget goes to surface points drawn uniformly from all
//! steps' surfaces (fewer when the surfaces hold fewer); the rest are static points
//! uniform in the box spanned by the training camera centres and the hull's points (a
//! capture dome's walls lie on it, and the floor the movers stand on inside it) with
//! uniform random colours and uniform random times (what SaRO-GS draws for untimed
//! points), or with `shell` on the dome's wall and floor ([`crate::shell`]) with the
//! colours of the background pixels they are seen in.
//!
//! Occlusion is ignored (every camera votes), so two people close in one view do
//! not carve each other; the hull is a superset of the true shape, as any visual hull.

use std::path::PathBuf;

use glam::DVec3;
use maaf_splat::Camera;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::bounds::Aabb;
use super::error::DataError;
use super::median_mask::{Rgb8, decode_rgb8};
use super::shell::{Shell, shell_points};
use crate::PointCloud;

/// One training view of a time step: camera, image and its foreground mask.
#[derive(Clone, Debug)]
pub struct HullView {
    /// The camera at the image size.
    pub camera: Camera,
    /// The image file.
    pub image: PathBuf,
    /// The foreground mask file (non-zero = foreground).
    pub mask: PathBuf,
}

/// The views of one time step.
#[derive(Clone, Debug)]
pub struct HullStep {
    /// The step's time.
    pub time: f64,
    /// Its training views with masks.
    pub views: Vec<HullView>,
}

/// Settings of the carving and of the cloud.
#[derive(Clone, Debug, PartialEq)]
pub struct HullOptions {
    /// Training times carved, evenly spread (30: every fifth frame of a 150-frame
    /// Panoptic sequence).
    pub steps: usize,
    /// Cells along the longest side of the region.
    pub resolution: usize,
    /// Cameras that must see a cell for it to be kept.
    pub min_views: usize,
    /// Fraction of the seeing cameras whose mask may call the cell background.
    pub miss_fraction: f64,
    /// Share of the point budget that goes to the hull's surface points.
    pub dynamic_fraction: f64,
    /// The carved region is the box of the camera centres grown by this fraction of
    /// its size on every side (a dome's floor lies below its lowest camera).
    pub margin: f64,
    /// Put the static points on the capture dome's wall and floor
    /// ([`crate::shell`]) instead of uniformly in the box.
    pub shell: bool,
}

impl Default for HullOptions {
    /// 30 times, 192 cells along the longest side, at least 4 cameras, one miss in ten,
    /// half of the budget on the movers, the camera box grown by half its size on every
    /// side.
    fn default() -> Self {
        HullOptions {
            steps: 30,
            resolution: 192,
            min_views: 4,
            miss_fraction: 0.1,
            dynamic_fraction: 0.5,
            margin: 0.5,
            shell: false,
        }
    }
}

/// A decoded view: camera, 8-bit RGB image and foreground bits.
pub(crate) struct Decoded {
    pub(crate) camera: Camera,
    pub(crate) image: Rgb8,
    pub(crate) mask: Vec<bool>,
}

/// Decodes a view's image and mask, checking both against the camera's size.
pub(crate) fn decode(view: &HullView) -> Result<Decoded, DataError> {
    let image = decode_rgb8(&view.image)?;
    let mask = decode_rgb8(&view.mask)?;
    if (mask.width, mask.height) != (view.camera.width, view.camera.height)
        || (image.width, image.height) != (view.camera.width, view.camera.height)
    {
        return Err(DataError::Image {
            path: view.mask.display().to_string(),
            message: format!(
                "mask is {}x{} and image {}x{}, but the camera is {}x{}",
                mask.width,
                mask.height,
                image.width,
                image.height,
                view.camera.width,
                view.camera.height
            ),
        });
    }
    Ok(Decoded {
        camera: view.camera.clone(),
        image,
        mask: mask.data.chunks_exact(3).map(|p| p[0] > 127).collect(),
    })
}

/// The pixel `(x, y)` a point projects to in `cam`, when in front and inside.
fn pixel(cam: &Camera, p: DVec3) -> Option<(usize, usize)> {
    let (u, v, z) = cam.project(p)?;
    if z <= 1e-6 || !(u >= 0.0 && v >= 0.0) {
        return None;
    }
    let (x, y) = (u.floor() as usize, v.floor() as usize);
    (x < cam.width as usize && y < cam.height as usize).then_some((x, y))
}

/// The surface points of one step's visual hull (module doc), jittered with `seed`.
pub fn carve_step(
    step: &HullStep,
    region: &Aabb,
    options: &HullOptions,
    seed: u64,
) -> Result<PointCloud, DataError> {
    let views: Vec<Decoded> = step
        .views
        .par_iter()
        .map(decode)
        .collect::<Result<_, _>>()?;
    let size = region.size();
    let cell = size.max_element() / options.resolution.max(1) as f64;
    let dims = (size / cell).ceil().max(DVec3::ONE).as_uvec3();
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let centre = |i: usize, j: usize, k: usize| {
        region.min + cell * DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5)
    };
    let max_miss = (options.miss_fraction * views.len() as f64).floor() as usize;
    let occupied: Vec<bool> = (0..nx * ny * nz)
        .into_par_iter()
        .map(|c| {
            let (i, j, k) = (c % nx, (c / nx) % ny, c / (nx * ny));
            let x = centre(i, j, k);
            let (mut seen, mut miss) = (0usize, 0usize);
            for v in &views {
                if let Some((px, py)) = pixel(&v.camera, x) {
                    seen += 1;
                    if !v.mask[py * v.camera.width as usize + px] {
                        miss += 1;
                        if miss > max_miss {
                            return false;
                        }
                    }
                }
            }
            seen >= options.min_views
                && miss <= (options.miss_fraction * seen as f64).floor() as usize
        })
        .collect();
    let at = |i: isize, j: isize, k: isize| {
        i >= 0
            && j >= 0
            && k >= 0
            && (i as usize) < nx
            && (j as usize) < ny
            && (k as usize) < nz
            && occupied[i as usize + nx * (j as usize + ny * k as usize)]
    };
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut cloud = PointCloud {
        points: Vec::new(),
        colours: Vec::new(),
        times: Some(Vec::new()),
    };
    for c in (0..occupied.len()).filter(|&c| occupied[c]) {
        let (i, j, k) = (
            (c % nx) as isize,
            ((c / nx) % ny) as isize,
            (c / (nx * ny)) as isize,
        );
        let inner = at(i - 1, j, k)
            && at(i + 1, j, k)
            && at(i, j - 1, k)
            && at(i, j + 1, k)
            && at(i, j, k - 1)
            && at(i, j, k + 1);
        if inner {
            continue;
        }
        let jitter = DVec3::new(
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
        );
        let p = centre(i as usize, j as usize, k as usize) + cell * jitter;
        let (mut sum, mut n) = ([0.0f64; 3], 0usize);
        for v in &views {
            if let Some((px, py)) = pixel(&v.camera, p) {
                let idx = py * v.camera.width as usize + px;
                if v.mask[idx] {
                    for (s, &b) in sum.iter_mut().zip(&v.image.data[3 * idx..3 * idx + 3]) {
                        *s += f64::from(b) / 255.0;
                    }
                    n += 1;
                }
            }
        }
        let colour = if n > 0 {
            sum.map(|s| s / n as f64)
        } else {
            [0.5; 3]
        };
        cloud.points.push(p.to_array());
        cloud.colours.push(colour);
        if let Some(t) = cloud.times.as_mut() {
            t.push(step.time);
        }
    }
    Ok(cloud)
}

/// Time steps whose background pixels colour the shell's points.
const SHELL_STEPS: usize = 4;

/// The folder of the masks of `steps` (the first view's), for messages.
fn masks_folder(steps: &[HullStep]) -> PathBuf {
    steps
        .iter()
        .flat_map(|s| &s.views)
        .next()
        .map_or_else(PathBuf::new, |v| maaf_io::parent_of(&v.mask).to_path_buf())
}

/// Refuses cameras that all face away from `centre` (the middle of the carved
/// region): `centre` is behind every camera of `steps` by more than a tenth of its
/// distance. A capture that surrounds its subject sees the middle of its cameras;
/// carving with cameras turned around would find nothing and say nothing.
fn refuse_facing_away(steps: &[HullStep], centre: DVec3) -> Result<(), DataError> {
    let views: Vec<&HullView> = steps.iter().flat_map(|s| &s.views).collect();
    let behind = |v: &&HullView| {
        let c = v.camera.to_camera(centre);
        c.z < -0.1 * c.length()
    };
    if !views.is_empty() && views.iter().all(behind) {
        return Err(DataError::request(
            &masks_folder(steps),
            format!(
                "the camera of every one of the {} training views carved faces away from the middle of the cameras (the region the visual hull is carved in): check the poses (w2c) or ship points3d.ply",
                views.len()
            ),
        ));
    }
    Ok(())
}

/// Refuses masks of `steps` that are all background (no pixel above 127): they mark
/// nothing to start the movers from, and training would start from random points
/// and report nothing wrong.
fn refuse_empty_masks(steps: &[HullStep]) -> Result<(), DataError> {
    let views: Vec<&HullView> = steps.iter().flat_map(|s| &s.views).collect();
    let any_foreground = views
        .par_iter()
        .any(|v| decode(v).is_ok_and(|d| d.mask.contains(&true)));
    if !any_foreground {
        return Err(DataError::request(
            &masks_folder(steps),
            format!(
                "every foreground mask of the {} training views carved is all background: the masks mark nothing for the visual hull; fix the masks or ship points3d.ply",
                views.len()
            ),
        ));
    }
    Ok(())
}

/// The initial cloud of at most `budget` points (module doc) and how many of them are
/// hull surface points (the first ones): hull surface points of every step in `steps`
/// plus static points in the box of `camera_centres` and the hull. Seeded;
/// steps are carved one after the other (each in parallel), so memory holds one
/// step's images. Refused: cameras that all face away from the middle of their
/// centres, and an empty hull whose masks are all background.
pub fn hull_cloud(
    steps: &[HullStep],
    camera_centres: &[DVec3],
    budget: usize,
    options: &HullOptions,
    seed: u64,
) -> Result<(PointCloud, usize), DataError> {
    let (lo, hi) = camera_centres.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &c| (lo.min(c), hi.max(c)),
    );
    let margin = options.margin * (hi - lo);
    let region = Aabb {
        min: lo - margin,
        max: hi + margin,
    };
    refuse_facing_away(steps, 0.5 * (lo + hi))?;
    let mut hull = PointCloud {
        points: Vec::new(),
        colours: Vec::new(),
        times: Some(Vec::new()),
    };
    for (s, step) in steps.iter().enumerate() {
        let part = carve_step(step, &region, options, seed ^ (s as u64 + 1))?;
        hull.points.extend(part.points);
        hull.colours.extend(part.colours);
        if let (Some(t), Some(p)) = (hull.times.as_mut(), part.times) {
            t.extend(p);
        }
    }
    if hull.is_empty() {
        refuse_empty_masks(steps)?;
    }
    // The static box reaches the floor the movers stand on, below the lowest camera.
    let (lo, hi) = hull.points.iter().fold((lo, hi), |(lo, hi), p| {
        let p = DVec3::from_array(*p);
        (lo.min(p), hi.max(p))
    });
    let dynamic = ((options.dynamic_fraction * budget as f64).round() as usize).min(hull.len());
    let mut cloud = hull.subsample(dynamic, seed);
    let mut rng = Pcg64::seed_from_u64(seed.wrapping_add(0x5eed));
    if options.shell {
        let views: Vec<HullView> = steps.iter().flat_map(|s| s.views.clone()).collect();
        let cameras: Vec<Camera> = views.iter().map(|v| v.camera.clone()).collect();
        if let Some(shell) = Shell::fit(&cameras, &hull.points) {
            // A few evenly spread steps' views are enough to colour the shell.
            let picked: Vec<HullView> = (0..SHELL_STEPS.min(steps.len()))
                .flat_map(|k| {
                    steps[k * steps.len() / SHELL_STEPS.min(steps.len())]
                        .views
                        .clone()
                })
                .collect();
            let on_shell = shell_points(&shell, &picked, budget - cloud.len(), seed)?;
            cloud.points.extend(on_shell.points.iter().copied());
            cloud.colours.extend(on_shell.colours.iter().copied());
            if let Some(t) = cloud.times.as_mut() {
                t.extend((0..on_shell.len()).map(|_| rng.random_range(0.0..1.0)));
            }
        }
    }
    for _ in cloud.len()..budget {
        cloud
            .points
            .push(std::array::from_fn(|a| rng.random_range(lo[a]..=hi[a])));
        cloud
            .colours
            .push(std::array::from_fn(|_| rng.random_range(0.0..1.0)));
        if let Some(t) = cloud.times.as_mut() {
            t.push(rng.random_range(0.0..1.0));
        }
    }
    Ok((cloud, dynamic))
}
