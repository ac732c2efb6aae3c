//! Loading a trained scene on a data set (checked against the run's
//! [`maaf_scene::run_data`] fingerprint), test-view cameras at any scale, and a video
//! over time (PNG frames + GIF) of a [`TrainedScene`].

use std::path::{Path, PathBuf};

use maaf_data::{Dataset, Split};
use maaf_scene::run_data::{DataFingerprint, recorded_data};
use maaf_scene::{ModelRegistry, TrainedScene, model_dir};
use maaf_splat::Camera;

use super::images;
use super::sequence::{check_frame_count, check_own_folder};
use crate::Error;

/// Loads the trained scene of `run` for evaluation on `data`: refuses a data set
/// other than the one `RUN/data.json` records ([`DataFingerprint::check_frames`]: its
/// background may differ, [`crate::EvalReport::name`]), then
/// loads `RUN/model` through `registry`, taking from `data` only what a run saved
/// before the scene record lacks ([`TrainedScene::load_with`]).
pub fn load_scene_on(
    run: &Path,
    data: &Dataset,
    registry: &ModelRegistry,
) -> Result<TrainedScene, Error> {
    let dir = model_dir(run)?;
    if let Some(rec) = recorded_data(run)? {
        rec.check_frames(&DataFingerprint::of(data)?, run)?;
    }
    TrainedScene::from_checkpoint(&dir, registry, Some(data))
}

/// Camera of view `index` of `split` at `scale` relative to the run's training scale
/// (no ground truth is needed, so zoom-in beyond the source images is allowed).
pub fn run_camera(
    scene: &TrainedScene,
    data: &Dataset,
    split: Split,
    index: usize,
    scale: f64,
) -> Result<Camera, Error> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::Input(format!(
            "scale {scale}: must be a positive number"
        )));
    }
    let source = data
        .camera(split, index, 1.0)
        .map_err(|e| Error::Input(e.to_string()))?;
    let s = scene.config.train_scale * scale;
    let cam = source.scaled(s);
    if cam.width as u64 * cam.height as u64 > 64_000_000 {
        return Err(Error::Input(format!(
            "scale {scale}: {}x{} is too large to render",
            cam.width, cam.height
        )));
    }
    Ok(cam)
}

/// Renders one frame per `(camera, time)` of `frames` (a fixed camera over time, a
/// camera path, or a data set's views) into `out` as `frame_NNNN.png` plus an
/// animated `video.gif` (10 frames per second). Returns the PNG paths. Frames are
/// rendered and written one at a time (the GIF streamed, [`images::GifWriter`]), so
/// a video needs the memory of one frame. The frames are built in a fresh temporary
/// folder swapped in for `out` ([`maaf_io::write_dir`]), so no frame of an earlier,
/// longer video stays beside the new ones; an `out` holding anything but such frames
/// is refused.
pub fn render_video(
    scene: &TrainedScene,
    frames: &[(Camera, f64)],
    out: &Path,
) -> Result<Vec<PathBuf>, Error> {
    if frames.is_empty() {
        return Err(Error::Input("a video needs at least one frame".into()));
    }
    check_frame_count(frames.len())?;
    check_own_folder(out, "video", |name| {
        name == "video.gif" || (name.starts_with("frame_") && name.ends_with(".png"))
    })?;
    let settings = scene.render_settings();
    let names: Vec<String> = (0..frames.len())
        .map(|i| format!("frame_{i:04}.png"))
        .collect();
    maaf_io::write_dir(out, Error::io, |tmp| {
        let mut gif = images::GifWriter::create(&tmp.join("video.gif"), 100)?;
        for (name, (camera, t)) in names.iter().zip(frames) {
            let img = images::to_rgb8(&scene.render_with(camera, *t, &settings))?;
            images::save_png(&img, &tmp.join(name))?;
            gif.push(&img)?;
        }
        gif.finish()
    })?;
    Ok(names.iter().map(|name| out.join(name)).collect())
}
