//! `maaf generate --rig multiview`: a multi-view video of a built-in scene in the
//! Plenoptic Video layout that [`crate::n3dv`] reads, written atomically.
//!
//! Output: `poses_bounds.npy` (one row per camera, OpenCV cameras converted to LLFF's
//! down-right-back columns, `[H, W, focal]` of the frames themselves, near/far from the
//! scene bounds), `camXX/images/NNNN.png` (straight RGBA, 8 bit, the same supersampled
//! renderer as the D-NeRF generator, [`super::render`]), and for the test camera `cam00`
//! `cam00/flow/NNNN.png` (exact forward flow to frame `NNNN + 1`, KITTI) and
//! `cam00/masks/NNNN.png` (moving-object coverage, 8-bit grey), plus `maaf_scene.json`
//! (`scene_bounds` and the generator settings). Frame `j` of `F` is at time `j / F`.
//! Everything is written into a temporary sibling of the target and swapped in by
//! `maaf_io::replace_dir`, so a failure leaves nothing half-written.
//!
//! Defaults: the `approach` scene, 16 cameras (`cam00` + 15 training) x 150 frames at
//! 448 x 336, 4 x 4 samples per pixel. 448 x 336 is 4:3 like N3DV's frames and a multiple
//! of 16, so training at 1/4 (112 x 84) can be evaluated at 4x, 2x, 1x, 1/2x and 1/4x of
//! the training size, all exact box downsamples of the source. The 2250 training views
//! take 254 MB as `f32` RGB at 1/4 scale (`12 W H` bytes a view).

use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use maaf_splat::Camera;
use serde_json::json;

use super::render::{forward_flow, render_layers, render_rgba};
use super::rig::{arc_positions, camera_wh};
use super::write::{
    GenerateSummary, MAX_CAMERAS, MAX_FRAMES, check_image_memory, image_salt, in_range,
    write_folder, write_points,
};
use super::{build_scene, scene::Scene, scene_bounds};
use crate::bounds::Aabb;
use crate::error::DataError;
use crate::flow::write_flow;
use crate::image::{Image, encode_rgba_png, write_quantised_png};
use crate::n3dv::{POSES_BOUNDS, PoseRow, SCENE_JSON, encode_poses_bounds};
use maaf_splat::camera::MAX_SIDE;

/// What [`generate_multiview`] writes (see the module doc for the defaults).
#[derive(Clone, Debug)]
pub struct MultiviewOptions {
    /// Built-in scene name.
    pub scene: String,
    /// Frame width in pixels (a multiple of 16).
    pub width: u32,
    /// Frame height in pixels (a multiple of 16).
    pub height: u32,
    /// Cameras, `cam00` (test) included; 2 to 100.
    pub cameras: usize,
    /// Frames per camera; 2 to 10000.
    pub frames: usize,
    /// Jittered samples per pixel along each axis (`n x n` per pixel).
    pub samples: u32,
    /// Seed of the sample jitter.
    pub seed: u64,
    /// Replace an existing output folder.
    pub force: bool,
}

impl Default for MultiviewOptions {
    fn default() -> Self {
        MultiviewOptions {
            scene: "approach".into(),
            width: 448,
            height: 336,
            cameras: 16,
            frames: 150,
            samples: 4,
            seed: 0,
            force: false,
        }
    }
}

/// Renders the scene from every camera at every frame and writes the data set to `out`
/// (module doc). `progress` gets `(done, total)` after each image. Fails, writing
/// nothing, on a bad option or when `out` exists (unless `force`).
pub fn generate_multiview(
    out: &Path,
    opts: &MultiviewOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<GenerateSummary, DataError> {
    let start = Instant::now();
    let scene = build_scene(&opts.scene)?;
    check_options(out, opts)?;
    let cams = arc_positions(opts.cameras)
        .into_iter()
        .map(|p| camera_wh(p, opts.width, opts.height))
        .collect::<Result<Vec<_>, _>>()?;
    write_folder(out, opts.force, |tmp| {
        write_all(tmp, &scene, &cams, opts, progress)
    })?;
    let f = opts.frames;
    Ok(GenerateSummary {
        out: out.to_path_buf(),
        counts: [(opts.cameras - 1) * f, 0, f, f],
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Checks the options of a multi-view generation (either layout; `out` names the
/// folder in errors, which [`write_folder`] checks): sizes multiples of 16 up to
/// [`maaf_splat::camera::MAX_SIDE`], 1..=16 samples, 2..=100 cameras, 2..=10000
/// frames, and the memory one image's rendering needs ([`check_image_memory`]).
pub(crate) fn check_options(out: &Path, opts: &MultiviewOptions) -> Result<(), DataError> {
    let bad = |m: String| DataError::request(out, m);
    for (name, v) in [("--size", opts.width), ("--height", opts.height)] {
        if v < 16 || !v.is_multiple_of(16) || v > MAX_SIDE {
            return Err(bad(format!(
                "{name} {v} must be a multiple of 16 (exact 1/4-of-1/4 scales) in 16..={MAX_SIDE}"
            )));
        }
    }
    check_image_memory(out, opts.width, opts.height)?;
    if !(1..=16).contains(&opts.samples) {
        return Err(bad(format!("--samples {} must be in 1..=16", opts.samples)));
    }
    in_range(out, "--cameras", opts.cameras, 2, MAX_CAMERAS)?;
    in_range(out, "--frames", opts.frames, 2, MAX_FRAMES)?;
    Ok(())
}

fn write_all(
    dir: &Path,
    scene: &Scene,
    cams: &[Camera],
    opts: &MultiviewOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(), DataError> {
    let mkdir =
        |p: &Path| std::fs::create_dir_all(p).map_err(|e| DataError::io(p, "cannot create", e));
    let f = opts.frames;
    let total = cams.len() * f + f - 1;
    let mut done = 0;
    for (c, cam) in cams.iter().enumerate() {
        let folder = dir.join(format!("cam{c:02}"));
        let images = folder.join("images");
        mkdir(&images)?;
        if c == 0 {
            mkdir(&folder.join("flow"))?;
            mkdir(&folder.join("masks"))?;
        }
        for j in 0..f {
            let t = j as f64 / f as f64;
            let salt = image_salt(opts.seed, c, j);
            let name = format!("{j:04}.png");
            let img = if c == 0 {
                let (img, mask) = render_layers(scene, cam, t, opts.samples, salt);
                write_mask(&mask, &folder.join("masks").join(&name))?;
                if j + 1 < f {
                    let flow = forward_flow(scene, cam, t, (j + 1) as f64 / f as f64);
                    write_flow(&flow, &folder.join("flow").join(&name))?;
                    done += 1;
                }
                img
            } else {
                render_rgba(scene, cam, t, opts.samples, salt)
            };
            encode_rgba_png(&img, &images.join(&name))?;
            done += 1;
            progress(done, total);
        }
    }
    let train: Vec<(Camera, f64)> = cams[1..]
        .iter()
        .flat_map(|cam| (0..f).map(move |j| (cam.clone(), j as f64 / f as f64)))
        .collect();
    write_points(dir, scene, &train, opts.seed)?;
    let bounds = scene_bounds(scene);
    let rows: Vec<PoseRow> = cams.iter().map(|cam| pose_row(cam, &bounds)).collect();
    let npy = dir.join(POSES_BOUNDS);
    let bytes = encode_poses_bounds(&rows).map_err(|e| DataError::io(&npy, "cannot encode", e))?;
    maaf_io::write_atomic(&npy, &bytes).map_err(|e| DataError::io(&npy, "cannot write", e))?;
    let doc = json!({
        "scene_bounds": [bounds.min.to_array(), bounds.max.to_array()],
        "generator": {
            "scene": opts.scene,
            "rig": "multiview",
            "seed": opts.seed,
            "width": opts.width,
            "height": opts.height,
            "samples_per_pixel": opts.samples * opts.samples,
            "cameras": cams.len(),
            "frames": f,
            "time": "frame / frames",
            "test_camera": "cam00",
            "moving_objects": scene.moving(),
        },
    });
    let path = dir.join(SCENE_JSON);
    let text = serde_json::to_string_pretty(&doc).map_err(|e| DataError::Json {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    maaf_io::write_atomic(&path, text.as_bytes())
        .map_err(|e| DataError::io(&path, "cannot write", e))
}

/// The `poses_bounds.npy` row of a generated camera: its pose, `[H, W, focal]` of the
/// frames, and near/far the depth range of the scene-bounds corners (near at least 0.05).
fn pose_row(cam: &Camera, bounds: &Aabb) -> PoseRow {
    let depths = (0..8).map(|k| {
        let pick = |bit: usize, lo: f64, hi: f64| if k & bit == 0 { lo } else { hi };
        let corner = DVec3::new(
            pick(1, bounds.min.x, bounds.max.x),
            pick(2, bounds.min.y, bounds.max.y),
            pick(4, bounds.min.z, bounds.max.z),
        );
        cam.to_camera(corner).z
    });
    let (near, far) = depths.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), z| {
        (lo.min(z), hi.max(z))
    });
    PoseRow {
        camera_to_world: cam.world_to_camera_mat().inverse(),
        height: cam.height as f64,
        width: cam.width as f64,
        focal: cam.fx,
        near: near.max(0.05),
        far,
    }
}

/// Writes a `[H, W, 1]` coverage in `[0, 1]` as an 8-bit grey PNG, `round(255 v)`.
fn write_mask(mask: &Image, path: &Path) -> Result<(), DataError> {
    write_quantised_png(mask, path, image::ExtendedColorType::L8, "mask PNG")
}
