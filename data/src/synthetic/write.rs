//! `maaf generate`: renders a built-in scene and writes it in D-NeRF format, atomically.
//!
//! Layout of the output folder:
//! `transforms_{train,val,test,video}.json`, `{train,val,test,video}/r_NNN.png`
//! (straight RGBA, 8 bit) and `video/flow_NNN.png` (forward flow from video frame `NNN`
//! to `NNN + 1`, KITTI 16-bit PNG, see [`crate::flow`]). Everything is written into a
//! temporary sibling of the target and swapped in by `maaf_io::replace_dir`
//! (`write_folder`), so a failure leaves nothing half-written.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;
use maaf_splat::Camera;
use maaf_splat::camera::MAX_SIDE;
use serde_json::json;

use super::points::{GENERATED_POINTS, visible_points};
use super::render::{forward_flow, render_rgba};
use super::rig::{self, CAMERA_ANGLE_X};
use super::{build_scene, scene::Scene, scene_bounds};
use crate::dnerf::opengl_to_opencv;
use crate::error::DataError;
use crate::flow::write_flow;
use crate::image::encode_rgba_png;
use crate::points::{POINTS_FILE, encode_points};

/// Camera arrangement of the training split.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rig {
    /// One camera per time, at a random position on the cap (like D-NeRF).
    Monocular,
    /// Several fixed cameras on the cap, all rendering every time (multi-view video).
    Ring,
}

impl std::str::FromStr for Rig {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "monocular" => Ok(Rig::Monocular),
            "ring" => Ok(Rig::Ring),
            _ => Err(format!("unknown rig {s:?}; expected monocular or ring")),
        }
    }
}

impl std::fmt::Display for Rig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Rig::Monocular => "monocular",
            Rig::Ring => "ring",
        })
    }
}

/// What to generate. [`Default`] is the demo data set: scene `dolly`, 800x800, monocular,
/// 100 training times, 10 val, 20 test, a 30-frame fixed-camera video, 4x4 samples.
#[derive(Clone, Debug)]
pub struct GenerateOptions {
    /// Built-in scene name.
    pub scene: String,
    /// Image width and height in pixels (a multiple of 4, at least 8).
    pub size: u32,
    /// Training time steps; `None` means 100 for the monocular rig and 30 for the ring.
    pub frames: Option<usize>,
    /// Camera rig of the training split.
    pub rig: Rig,
    /// Seed of the camera positions, test times and sample jitter.
    pub seed: u64,
    /// Jittered samples per pixel along each axis (`n x n` per pixel).
    pub samples: u32,
    /// Number of test views.
    pub test_frames: usize,
    /// Number of validation views.
    pub val_frames: usize,
    /// Frames of the fixed-camera video (with forward flow between consecutive frames).
    pub video_frames: usize,
    /// Cameras of the ring rig.
    pub ring_cameras: usize,
    /// Replace an existing output folder.
    pub force: bool,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        GenerateOptions {
            scene: super::DEFAULT_SCENE.into(),
            size: 800,
            frames: None,
            rig: Rig::Monocular,
            seed: 0,
            samples: 4,
            test_frames: 20,
            val_frames: 10,
            video_frames: 30,
            ring_cameras: 6,
            force: false,
        }
    }
}

impl GenerateOptions {
    /// A small scene for tests and quick checks: `size` x `size` images, `frames`
    /// training times, one sample per pixel, 2 test views, 1 validation view and a
    /// 2-frame video; the rest as [`Default`].
    pub fn small(size: u32, frames: usize) -> Self {
        GenerateOptions {
            size,
            frames: Some(frames),
            samples: 1,
            test_frames: 2,
            val_frames: 1,
            video_frames: 2,
            ..GenerateOptions::default()
        }
    }
}

/// Most training times, test, validation or video views of a generated split
/// (four-digit frame numbers; a count sizes the plan of every view before any is
/// rendered).
pub const MAX_FRAMES: usize = 10_000;

/// Most cameras of a generated rig.
pub const MAX_CAMERAS: usize = 100;

/// Bytes the generator needs per pixel of one image, about: the supersampled RGBA
/// and coverage layers in `f32`, the flow and the encoded copy.
const GENERATE_BYTES_PER_PIXEL: u64 = 48;

/// Refuses a count option `flag` outside `min..=max`, naming it and the range.
pub(crate) fn in_range(
    out: &Path,
    flag: &str,
    value: usize,
    min: usize,
    max: usize,
) -> Result<(), DataError> {
    if !(min..=max).contains(&value) {
        return Err(DataError::request(
            out,
            format!("{flag} {value}: must be in {min}..={max}"),
        ));
    }
    Ok(())
}

/// Refuses images of `width` x `height` whose rendering needs more memory than the
/// machine has available ([`maaf_io::memory::check`]).
pub(crate) fn check_image_memory(out: &Path, width: u32, height: u32) -> Result<(), DataError> {
    let bytes = u64::from(width) * u64::from(height) * GENERATE_BYTES_PER_PIXEL;
    maaf_io::memory::check(
        bytes,
        &format!("a {width}x{height} image (--size, --height)"),
    )
    .map_err(|m| DataError::request(out, m))
}

/// What [`generate`] wrote.
#[derive(Clone, Debug)]
pub struct GenerateSummary {
    /// The output folder.
    pub out: PathBuf,
    /// Views per split: train, val, test, video.
    pub counts: [usize; 4],
    /// Wall-clock seconds spent.
    pub seconds: f64,
}

struct PlannedView {
    position: DVec3,
    time: f64,
}

/// Renders the scene and writes the data set to `out` (see the module doc). `progress`
/// is called with `(done, total)` after each image. Fails, writing nothing, on a bad
/// option or when `out` exists (unless `force`).
pub fn generate(
    out: &Path,
    opts: &GenerateOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<GenerateSummary, DataError> {
    let start = Instant::now();
    let scene = build_scene(&opts.scene)?;
    let bad = |m: String| DataError::request(out, m);
    if opts.size < 8 || !opts.size.is_multiple_of(4) || opts.size > MAX_SIDE {
        return Err(bad(format!(
            "--size {} must be a multiple of 4 in 8..={MAX_SIDE}",
            opts.size
        )));
    }
    if !(1..=16).contains(&opts.samples) {
        return Err(bad(format!("--samples {} must be in 1..=16", opts.samples)));
    }
    let frames = opts.frames.unwrap_or(match opts.rig {
        Rig::Monocular => 100,
        Rig::Ring => 30,
    });
    in_range(out, "--frames", frames, 2, MAX_FRAMES)?;
    in_range(out, "--test-frames", opts.test_frames, 1, MAX_FRAMES)?;
    in_range(out, "--val-frames", opts.val_frames, 0, MAX_FRAMES)?;
    in_range(out, "--video-frames", opts.video_frames, 2, MAX_FRAMES)?;
    if opts.rig == Rig::Ring {
        in_range(out, "--cameras", opts.ring_cameras, 2, MAX_CAMERAS)?;
    }
    check_image_memory(out, opts.size, opts.size)?;

    // Plan every split before rendering anything.
    let times = rig::even_times(frames);
    let train: Vec<PlannedView> = match opts.rig {
        Rig::Monocular => rig::random_positions(frames, opts.seed, 1)
            .into_iter()
            .zip(&times)
            .map(|(position, &time)| PlannedView { position, time })
            .collect(),
        Rig::Ring => {
            let ring = rig::ring_positions(opts.ring_cameras);
            times
                .iter()
                .flat_map(|&time| {
                    ring.iter()
                        .map(move |&position| PlannedView { position, time })
                })
                .collect()
        }
    };
    let random_times = |n: usize, stream: u64| -> Vec<f64> {
        use rand::{RngExt, SeedableRng};
        let mut rng =
            rand_pcg::Pcg64::seed_from_u64(opts.seed ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
        let mut t: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..1.0)).collect();
        t.sort_by(f64::total_cmp);
        t
    };
    let test: Vec<PlannedView> = match opts.rig {
        Rig::Monocular => rig::random_positions(opts.test_frames, opts.seed, 2)
            .into_iter()
            .zip(random_times(opts.test_frames, 2))
            .map(|(position, time)| PlannedView { position, time })
            .collect(),
        // A held-out camera between the ring cameras, at evenly spaced times.
        Rig::Ring => rig::even_times(opts.test_frames)
            .into_iter()
            .map(|time| PlannedView {
                position: rig::cap_position(0.0, 26.0),
                time,
            })
            .collect(),
    };
    let val: Vec<PlannedView> = rig::random_positions(opts.val_frames, opts.seed, 3)
        .into_iter()
        .zip(random_times(opts.val_frames, 3))
        .map(|(position, time)| PlannedView { position, time })
        .collect();
    let video: Vec<PlannedView> = rig::even_times(opts.video_frames)
        .into_iter()
        .map(|time| PlannedView {
            position: rig::video_position(),
            time,
        })
        .collect();

    write_folder(out, opts.force, |tmp| {
        write_all(
            tmp,
            &scene,
            opts,
            frames,
            [&train, &val, &test, &video],
            progress,
        )
    })?;
    Ok(GenerateSummary {
        out: out.to_path_buf(),
        counts: [train.len(), val.len(), test.len(), video.len()],
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Writes the generated data set `out` crash-safely ([`maaf_io::write_dir`]): `write`
/// fills a temporary sibling of `out` that then replaces `out` whole; on any failure
/// `out` is left as it was. `out` must name a folder in an existing one. The
/// generation holds `out`'s lock throughout ([`maaf_io::RunLock`], as a trainer holds
/// its run's: a second generation into the same folder fails at once, naming the
/// first), and an `out` holding anything (an earlier data set) is refused unless
/// `force`.
pub(crate) fn write_folder(
    out: &Path,
    force: bool,
    write: impl FnOnce(&Path) -> Result<(), DataError>,
) -> Result<(), DataError> {
    if out.file_name().is_none() {
        return Err(DataError::request(out, "--out must name a folder"));
    }
    let parent = maaf_io::parent_of(out);
    if !parent.is_dir() {
        return Err(DataError::request(
            parent,
            "parent folder of --out does not exist",
        ));
    }
    // Refused before the lock too, which would otherwise put its file into the data.
    refuse_data(out, force)?;
    let doing = format!("generated (maaf generate, pid {})", std::process::id());
    let _lock = maaf_io::RunLock::exclusive(out, &doing)?;
    refuse_data(out, force)?;
    maaf_io::write_dir(out, |p, e| DataError::io(p, "cannot write", e), write)
}

/// Refuses an `out` holding anything but a lock file (an earlier data set) unless
/// `force`.
fn refuse_data(out: &Path, force: bool) -> Result<(), DataError> {
    let Ok(entries) = std::fs::read_dir(out) else {
        return Ok(());
    };
    let holds_data = entries
        .flatten()
        .any(|e| e.file_name() != std::ffi::OsStr::new(maaf_io::lock::LOCK_FILE));
    if holds_data && !force {
        return Err(DataError::request(
            out,
            "already exists; choose another --out or pass --force",
        ));
    }
    Ok(())
}

fn write_all(
    dir: &Path,
    scene: &Scene,
    opts: &GenerateOptions,
    frames: usize,
    splits: [&Vec<PlannedView>; 4],
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(), DataError> {
    let names = ["train", "val", "test", "video"];
    let total: usize =
        splits.iter().map(|s| s.len()).sum::<usize>() + splits[3].len().saturating_sub(1);
    let mut done = 0;
    let bounds = scene_bounds(scene);
    for (split_index, (name, views)) in names.iter().zip(splits).enumerate() {
        if views.is_empty() {
            continue;
        }
        let sub = dir.join(name);
        std::fs::create_dir_all(&sub).map_err(|e| DataError::io(&sub, "cannot create", e))?;
        let mut cams = Vec::with_capacity(views.len());
        let mut entries = Vec::with_capacity(views.len());
        for (i, v) in views.iter().enumerate() {
            let cam = rig::camera_at(v.position, opts.size)?;
            let salt = image_salt(opts.seed, split_index, i);
            let img = render_rgba(scene, &cam, v.time, opts.samples, salt);
            let file = sub.join(format!("r_{i:03}.png"));
            encode_rgba_png(&img, &file)?;
            let mut entry = json!({
                "file_path": format!("./{name}/r_{i:03}"),
                "time": v.time,
                "rotation": 0.0,
                "transform_matrix": gl_rows(&cam),
            });
            if *name == "video" && i + 1 < views.len() {
                let flow = forward_flow(scene, &cam, v.time, views[i + 1].time);
                let path = sub.join(format!("flow_{i:03}.png"));
                write_flow(&flow, &path)?;
                entry["flow_path"] = json!(format!("./{name}/flow_{i:03}.png"));
                done += 1;
            }
            entries.push(entry);
            cams.push(cam);
            done += 1;
            progress(done, total);
        }
        let doc = json!({
            "camera_angle_x": CAMERA_ANGLE_X,
            "scene_bounds": [bounds.min.to_array(), bounds.max.to_array()],
            "generator": {
                "scene": opts.scene,
                "rig": opts.rig.to_string(),
                "seed": opts.seed,
                "size": opts.size,
                "samples_per_pixel": opts.samples * opts.samples,
                "train_times": frames,
                "moving_objects": scene.moving(),
            },
            "frames": entries,
        });
        let path = dir.join(format!("transforms_{name}.json"));
        let text = serde_json::to_string_pretty(&doc).map_err(|e| DataError::Json {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        maaf_io::write_atomic(&path, text.as_bytes())
            .map_err(|e| DataError::io(&path, "cannot write", e))?;
    }
    let train = splits[0]
        .iter()
        .map(|v| Ok((rig::camera_at(v.position, opts.size)?, v.time)))
        .collect::<Result<Vec<_>, DataError>>()?;
    write_points(dir, scene, &train, opts.seed)
}

/// Writes the generated data set's `points3d.ply`: [`visible_points`] of the
/// training views.
pub(crate) fn write_points(
    dir: &Path,
    scene: &Scene,
    train: &[(Camera, f64)],
    seed: u64,
) -> Result<(), DataError> {
    let cloud = visible_points(scene, train, GENERATED_POINTS, seed);
    let path = dir.join(POINTS_FILE);
    maaf_io::write_atomic(&path, &encode_points(&cloud))
        .map_err(|e| DataError::io(&path, "cannot write", e))
}

/// The jitter seed of image `index` of split number `split` (0 train, 1 val, 2 test,
/// 3 video), so every image has its own sample pattern:
/// `seed * 1000003 XOR (split * 7919 + index * 104729)`.
pub fn image_salt(seed: u64, split: usize, index: usize) -> u64 {
    seed.wrapping_mul(1_000_003) ^ (split as u64 * 7919 + index as u64 * 104_729)
}

/// The camera-to-world matrix in OpenGL axes (what D-NeRF stores), row by row.
fn gl_rows(cam: &Camera) -> Vec<[f64; 4]> {
    let c2w_cv = cam.world_to_camera_mat().inverse();
    let gl = opengl_to_opencv(c2w_cv); // the axis flip is its own inverse
    (0..4).map(|r| gl.row(r).to_array()).collect()
}
