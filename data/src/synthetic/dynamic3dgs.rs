//! `maaf generate --rig multiview --layout dynamic3dgs`: the multi-view video of
//! [`super::multiview`] written in the Dynamic 3D Gaussians layout that
//! [`crate::dynamic3dgs`] reads (CMU Panoptic's), so its loader, the visual-hull
//! initialisation and the median masks are tested without downloaded data.
//!
//! Output: `ims/<c>/<j:06>.png` (straight RGBA, 8 bit), `seg/<c>/<j:06>.png` (8-bit grey
//! foreground masks: 255 where at least half of the pixel's samples see a moving object,
//! else 0; for every camera, test camera included, unlike the real data),
//! `train_meta.json` (cameras `1..n`) and `test_meta.json` (camera `0`) with the layout's
//! keys. Frame `j` of `F` is rendered at `t = j / (F - 1)`, the loader's time. No point
//! cloud is written: training carves one from the masks.
//!
//! Each camera keeps one supersampling pattern over all its frames (a sensor's pixel
//! footprint does not move), so a static pixel has the same value in every frame.
//!
//! The cameras are the arc of [`super::rig::arc_positions`] with per-camera intrinsics
//! as a real rig has them: camera `c` has focal length `f (1 + 0.1 ((c mod 3) - 1))`
//! and its principal point moved from the centre by `(0.04 W, -0.03 H) ((c mod 3) - 1)`
//! (the Panoptic cameras' principal points sit up to 15 px of 640 off centre).

use std::path::Path;
use std::time::Instant;

use maaf_splat::Camera;
use serde_json::json;

use super::multiview::MultiviewOptions;
use super::render::render_layers;
use super::rig::{arc_positions, camera_wh};
use super::write::{GenerateSummary, image_salt, write_folder};
use super::{build_scene, scene::Scene};
use crate::dynamic3dgs::{IMAGES_DIR, MASKS_DIR, TEST_META, TRAIN_META};
use crate::error::DataError;
use crate::image::{Image, encode_rgba_png, write_quantised_png};

/// The rig's `n` cameras at `width x height` (module doc: focal and principal point
/// vary with the index mod 3).
pub fn rig_cameras(n: usize, width: u32, height: u32) -> Result<Vec<Camera>, DataError> {
    arc_positions(n)
        .into_iter()
        .enumerate()
        .map(|(c, eye)| rig_camera(c, eye, width, height))
        .collect()
}

/// Camera `c` of the rig at `eye`.
fn rig_camera(c: usize, eye: glam::DVec3, width: u32, height: u32) -> Result<Camera, DataError> {
    let centred = camera_wh(eye, width, height)?;
    let s = (c % 3) as f64 - 1.0;
    let f = centred.fx * (1.0 + 0.1 * s);
    let cx = centred.cx + 0.04 * width as f64 * s;
    let cy = centred.cy - 0.03 * height as f64 * s;
    Camera::new(width, height, f, f, cx, cy, centred.world_to_camera).map_err(|e| {
        DataError::Request {
            path: "<generator>".into(),
            message: format!("camera {c}: {e}"),
        }
    })
}

/// Renders the scene from every camera at every frame and writes the data set to `out`
/// in the Dynamic 3D Gaussians layout (module doc), atomically. Options as
/// [`super::generate_multiview`] checks them.
pub fn generate_dynamic3dgs(
    out: &Path,
    opts: &MultiviewOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<GenerateSummary, DataError> {
    let start = Instant::now();
    let scene = build_scene(&opts.scene)?;
    super::multiview::check_options(out, opts)?;
    let cams = rig_cameras(opts.cameras, opts.width, opts.height)?;
    write_folder(out, opts.force, |tmp| {
        write_all(tmp, &scene, &cams, opts, progress)
    })?;
    let f = opts.frames;
    Ok(GenerateSummary {
        out: out.to_path_buf(),
        counts: [(opts.cameras - 1) * f, 0, f, 0],
        seconds: start.elapsed().as_secs_f64(),
    })
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
    let total = cams.len() * f;
    let mut done = 0;
    for (c, cam) in cams.iter().enumerate() {
        mkdir(&dir.join(IMAGES_DIR).join(c.to_string()))?;
        mkdir(&dir.join(MASKS_DIR).join(c.to_string()))?;
        for j in 0..f {
            let t = j as f64 / (f - 1) as f64;
            // One sample pattern per camera: a real sensor integrates the same pixel
            // footprint in every frame, so static pixels repeat exactly over time.
            let salt = image_salt(opts.seed, c, 0);
            let (img, coverage) = render_layers(scene, cam, t, opts.samples, salt);
            let name = format!("{c}/{j:06}.png");
            encode_rgba_png(&img, &dir.join(IMAGES_DIR).join(&name))?;
            let seg = Image {
                data: coverage
                    .data
                    .iter()
                    .map(|&v| if v >= 0.5 { 1.0 } else { 0.0 })
                    .collect(),
                ..coverage
            };
            write_quantised_png(
                &seg,
                &dir.join(MASKS_DIR).join(&name),
                image::ExtendedColorType::L8,
                "mask PNG",
            )?;
            done += 1;
            progress(done, total);
        }
    }
    write_meta(dir, TRAIN_META, &cams[1..], 1, opts)?;
    write_meta(dir, TEST_META, &cams[..1], 0, opts)
}

/// Writes one `*_meta.json` for `cams`, numbered from `first`.
fn write_meta(
    dir: &Path,
    name: &str,
    cams: &[Camera],
    first: usize,
    opts: &MultiviewOptions,
) -> Result<(), DataError> {
    let per_frame = |j: usize| {
        let ids: Vec<usize> = (first..first + cams.len()).collect();
        let k: Vec<[[f64; 3]; 3]> = cams
            .iter()
            .map(|c| [[c.fx, 0.0, c.cx], [0.0, c.fy, c.cy], [0.0, 0.0, 1.0]])
            .collect();
        let w2c: Vec<[[f64; 4]; 4]> = cams.iter().map(|c| c.world_to_camera).collect();
        let files: Vec<String> = ids.iter().map(|c| format!("{c}/{j:06}.png")).collect();
        (k, w2c, files, ids)
    };
    let frames: Vec<_> = (0..opts.frames).map(per_frame).collect();
    let doc = json!({
        "w": opts.width,
        "h": opts.height,
        "k": frames.iter().map(|f| &f.0).collect::<Vec<_>>(),
        "w2c": frames.iter().map(|f| &f.1).collect::<Vec<_>>(),
        "fn": frames.iter().map(|f| &f.2).collect::<Vec<_>>(),
        "cam_id": frames.iter().map(|f| &f.3).collect::<Vec<_>>(),
    });
    let path = dir.join(name);
    let text = serde_json::to_string(&doc).map_err(|e| DataError::Json {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    maaf_io::write_atomic(&path, text.as_bytes())
        .map_err(|e| DataError::io(&path, "cannot write", e))
}
