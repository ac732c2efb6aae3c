//! `maaf render` (one image of a trained run at a time and camera) and
//! `maaf render-video` (a fixed-camera video over time: PNG frames + animated GIF).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_eval::camera_path::Rig;
use maaf_eval::images::{save_png, to_rgb8};
use maaf_eval::render::render_video;
use maaf_eval::{check_frame_count, frame_times, run_camera};
use maaf_scene::TrainedScene;
use maaf_splat::Camera;
use maaf_train::data::{Dataset, Split};

use super::Background;
use super::cameras::read_camera_file;
use super::eval::{load_scene, open_run_data, read_lock};
use maaf_train::Plugins;

/// The run, its camera's size and the background (shared by `render` and
/// `render-video`; each says where its camera comes from).
#[derive(clap::Args, Debug)]
pub struct CameraArgs {
    /// Run directory written by `maaf train`.
    #[arg(long)]
    pub run: PathBuf,
    /// Camera JSON: {"width","height","fx","fy","cx","cy","world_to_camera":[[4]x4]}
    /// and optionally "time", as `maaf cameras` writes them [default: none].
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Scale of a data-set view's camera relative to the training scale (2 = zoom-in
    /// 2x).
    #[arg(long, default_value_t = 1.0, conflicts_with = "size")]
    pub scale: f64,
    /// Image size WxH in pixels instead of --scale, of the camera's aspect ratio (the
    /// camera's intrinsics are scaled to it; another aspect is refused) [default: the
    /// camera's own size].
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Background: white, black, or r,g,b in [0, 1] [default: the one the run was
    /// trained on].
    #[arg(long, value_parser = Background::parse)]
    pub background: Option<Background>,
}

/// Arguments of `maaf render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    camera: CameraArgs,
    /// A data-set view as SPLIT:INDEX, e.g. test:0 or video:0, whose camera is
    /// rendered [default: none: give this or --camera].
    #[arg(long, conflicts_with = "camera")]
    pub view: Option<String>,
    /// Data folder the run was trained on, read only for --view [default: the one in
    /// RUN/data.json].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Time to render [default: the view's time with --view, the camera file's "time"
    /// with --camera, else 0].
    #[arg(long)]
    pub time: Option<f64>,
    /// Output PNG (8-bit).
    #[arg(long)]
    pub out: PathBuf,
}

/// `render-video --path` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathArg {
    /// One camera (--view or --camera) over the data set's time range.
    Fixed,
    /// One turn around the point the training cameras look at, at their mean distance
    /// and height, starting at --view / --camera, over the time range.
    Orbit,
    /// Two turns of a spiral around --view / --camera in its image plane, looking at
    /// the same point, over the time range (forward-facing multi-view video).
    Spiral,
    /// The data set's test views in order, each at its own time.
    Test,
}

/// Arguments of `maaf render-video`.
#[derive(clap::Args, Debug)]
pub struct RenderVideoArgs {
    #[command(flatten)]
    camera: CameraArgs,
    /// A data-set view as SPLIT:INDEX, e.g. test:0 or video:0, whose camera is the
    /// fixed camera or the start of an orbit or spiral (this or --camera) [default:
    /// test:0 for an orbit or spiral].
    #[arg(long, conflicts_with = "camera")]
    pub view: Option<String>,
    /// Data folder the run was trained on, read only for --view, --path test and the
    /// default start of an orbit or spiral [default: the one in RUN/data.json].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Camera path.
    #[arg(long, value_enum, default_value_t = PathArg::Fixed)]
    pub path: PathArg,
    /// Number of frames, evenly spaced over the data set's time range (all test views
    /// with --path test); at most 10000.
    #[arg(long, default_value_t = 30)]
    pub frames: usize,
    /// Output folder (frame_NNNN.png and video.gif); a video file name (.mp4, .gif,
    /// ...) is refused.
    #[arg(long)]
    pub out: PathBuf,
}

/// Extensions of video files, which `render-video --out` (a folder) refuses.
const VIDEO_EXTENSIONS: [&str; 7] = ["mp4", "m4v", "mov", "mkv", "webm", "avi", "gif"];

/// Parses `--size WxH`.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, e.g. 800x600, got `{s}`"))?;
    let side = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=maaf_splat::camera::MAX_SIDE).contains(n))
            .ok_or_else(|| {
                format!(
                    "`{v}` in `{s}` is not a size in 1..={}",
                    maaf_splat::camera::MAX_SIDE
                )
            })
    };
    Ok((side(w)?, side(h)?))
}

/// `camera` at `width` x `height` pixels (focal lengths and principal point scaled),
/// refused with both sizes named when its aspect ratio differs from the camera's by
/// more than a pixel's rounding.
fn resized(camera: &Camera, (width, height): (u32, u32)) -> anyhow::Result<Camera> {
    let (cw, ch) = (f64::from(camera.width), f64::from(camera.height));
    let same_aspect = (f64::from(width) * ch / cw - f64::from(height)).abs() < 1.0
        || (f64::from(height) * cw / ch - f64::from(width)).abs() < 1.0;
    if !same_aspect {
        bail!(
            "--size {width}x{height}: the camera is {}x{}, another aspect ratio, which would stretch the image; give {width}x{} or {}x{height}, or --scale",
            camera.width,
            camera.height,
            (f64::from(width) * ch / cw).round(),
            (f64::from(height) * cw / ch).round()
        );
    }
    let sx = f64::from(width) / f64::from(camera.width);
    let sy = f64::from(height) / f64::from(camera.height);
    Ok(Camera::new(
        width,
        height,
        camera.fx * sx,
        camera.fy * sy,
        camera.cx * sx,
        camera.cy * sy,
        camera.world_to_camera,
    )?)
}

fn parse_view(s: &str) -> anyhow::Result<(Split, usize)> {
    let Some((split, index)) = s.split_once(':') else {
        bail!("--view {s}: expected SPLIT:INDEX, e.g. test:0");
    };
    let split = match split {
        "train" => Split::Train,
        "val" => Split::Val,
        "test" => Split::Test,
        "video" => Split::Video,
        other => bail!("--view {s}: unknown split `{other}` (train, val, test or video)"),
    };
    let index = index
        .parse::<usize>()
        .with_context(|| format!("--view {s}: `{index}` is not a view index"))?;
    Ok((split, index))
}

/// A loaded run, the data set when it was needed, and the camera of --view or
/// --camera (at --scale or --size) with the view's time.
struct Setup {
    scene: TrainedScene,
    data: Option<Dataset>,
    camera: Option<Camera>,
    time: Option<f64>,
}

/// Loads the run's scene (on --background when given) and resolves the camera of
/// `view` or --camera, if any, with its time. The data set (`data_dir`, else the
/// run's) is opened only for `view` or when `need_data` (and for a run saved before
/// checkpoints recorded their cameras).
fn setup(
    args: &CameraArgs,
    view: Option<&str>,
    data_dir: Option<&Path>,
    need_data: bool,
    plugins: &Plugins,
) -> anyhow::Result<Setup> {
    // Check the cheap arguments before loading the model.
    let view = view.map(parse_view).transpose()?;
    let file_camera = args.camera.as_deref().map(read_camera_file).transpose()?;
    let data = if view.is_some() || need_data {
        Some(open_run_data(
            &args.run,
            data_dir,
            args.background,
            &plugins.formats,
        )?)
    } else {
        None
    };
    let mut scene = load_scene(&args.run, data_dir, args.background, data.as_ref(), plugins)?;
    if let Some(b) = args.background {
        scene.record.background = b.rgb();
    }
    let (camera, time) = match (view, file_camera, &data) {
        (Some((split, index)), _, Some(data)) => {
            let cam = run_camera(&scene, data, split, index, args.scale)?;
            let time = data.times(split).get(index).copied();
            (Some(cam), time)
        }
        (None, Some((cam, time)), _) => (Some(cam), time),
        _ => (None, None),
    };
    let camera = match (camera, args.size) {
        (Some(c), Some(size)) => Some(resized(&c, size)?),
        (c, _) => c,
    };
    Ok(Setup {
        scene,
        data,
        camera,
        time,
    })
}

/// Bytes one render needs per pixel, about: the float image, alpha and depth, the
/// rasteriser's per-pixel state and the 8-bit copy written out.
const RENDER_BYTES_PER_PIXEL: u64 = 64;

/// Refuses a render of `camera` larger than the memory available
/// ([`maaf_io::memory::check`]), naming its size.
fn check_render_memory(camera: &Camera) -> anyhow::Result<()> {
    let pixels = u64::from(camera.width) * u64::from(camera.height);
    maaf_io::memory::check(
        pixels * RENDER_BYTES_PER_PIXEL,
        &format!(
            "a {}x{} render (--size, --scale or the camera file)",
            camera.width, camera.height
        ),
    )
    .map_err(anyhow::Error::msg)
}

/// Runs `maaf render`.
pub fn run(args: &RenderArgs, plugins: &Plugins) -> anyhow::Result<()> {
    if let Some(t) = args.time
        && !t.is_finite()
    {
        bail!("--time {t}: must be a finite number");
    }
    let is_png = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        bail!(
            "--out {}: maaf render writes PNG; give a file name ending in .png",
            args.out.display()
        );
    }
    let _lock = read_lock(&args.camera.run)?;
    let Setup {
        scene,
        camera,
        time: view_time,
        ..
    } = setup(
        &args.camera,
        args.view.as_deref(),
        args.data.as_deref(),
        false,
        plugins,
    )?;
    let Some(camera) = camera else {
        bail!("give --view SPLIT:INDEX or --camera CAM.json");
    };
    check_render_memory(&camera)?;
    let time = args.time.or(view_time).unwrap_or(0.0);
    let (t0, t1) = scene.record.time_range;
    if !(t0..=t1).contains(&time) {
        eprintln!(
            "maaf: warning: --time {time} is outside the data's time range [{t0}, {t1}]: the model extrapolates"
        );
    }
    let image = scene.render(&camera, time);
    save_png(&to_rgb8(&image)?, &args.out)?;
    println!(
        "rendered {}x{} at t = {time} to {}",
        camera.width,
        camera.height,
        args.out.display()
    );
    Ok(())
}

/// Runs `maaf render-video`.
pub fn run_video(args: &RenderVideoArgs, plugins: &Plugins) -> anyhow::Result<()> {
    check_frame_count(args.frames)?;
    if let Some(ext) = args
        .out
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        && VIDEO_EXTENSIONS.contains(&ext.as_str())
    {
        bail!(
            "--out {}: render-video writes a folder of PNG frames and video.gif, not a .{ext} file; give a folder (--out {}) and encode its frames with a video tool if needed (ffmpeg -i {}/frame_%04d.png v.mp4)",
            args.out.display(),
            args.out.with_extension("").display(),
            args.out.with_extension("").display()
        );
    }
    let _lock = read_lock(&args.camera.run)?;
    // The test views' cameras come from the data set: the path of them, and the
    // default start of an orbit or spiral.
    let need_data =
        args.path == PathArg::Test || (args.view.is_none() && args.camera.camera.is_none());
    let Setup {
        scene,
        data,
        camera,
        ..
    } = setup(
        &args.camera,
        args.view.as_deref(),
        args.data.as_deref(),
        need_data,
        plugins,
    )?;
    let range = scene.record.time_range;
    let test_camera = |i: usize| -> anyhow::Result<Camera> {
        let Some(data) = &data else {
            bail!("the test views' cameras need the data set");
        };
        Ok(run_camera(&scene, data, Split::Test, i, args.camera.scale)?)
    };
    let start = || -> anyhow::Result<Camera> {
        match &camera {
            Some(c) => Ok(c.clone()),
            None => {
                let c = test_camera(0)?;
                Ok(match args.camera.size {
                    Some(size) => resized(&c, size)?,
                    None => c,
                })
            }
        }
    };
    let along = |cameras: Vec<Camera>| -> anyhow::Result<Vec<(Camera, f64)>> {
        let times = frame_times(range, cameras.len())?;
        Ok(cameras.into_iter().zip(times).collect())
    };
    let frames: Vec<(Camera, f64)> = match args.path {
        PathArg::Fixed => {
            let Some(c) = camera.clone() else {
                bail!("--path fixed: give --view SPLIT:INDEX or --camera CAM.json");
            };
            along(vec![c; args.frames])?
        }
        PathArg::Orbit | PathArg::Spiral => {
            let rig = Rig::of(scene.cameras())?;
            let start = start()?;
            along(if args.path == PathArg::Orbit {
                rig.orbit(&start, args.frames)?
            } else {
                rig.spiral(&start, args.frames)?
            })?
        }
        PathArg::Test => {
            if camera.is_some() {
                bail!("--path test renders the test views' own cameras; drop --view / --camera");
            }
            let times = data
                .as_ref()
                .map_or_else(Vec::new, |d| d.times(Split::Test));
            if times.is_empty() {
                bail!("--path test: the data set has no test views");
            }
            let mut frames = Vec::with_capacity(times.len());
            for (i, t) in times.into_iter().enumerate() {
                let c = test_camera(i)?;
                let c = match args.camera.size {
                    Some(size) => resized(&c, size)?,
                    None => c,
                };
                frames.push((c, t));
            }
            frames
        }
    };
    if let Some((camera, _)) = frames.first() {
        check_render_memory(camera)?;
    }
    let paths = render_video(&scene, &frames, &args.out)?;
    let (first, last) = (&frames[0], &frames[frames.len() - 1]);
    println!(
        "rendered {} frames ({}x{}, t = {}..{}) to {} (frame_NNNN.png, video.gif)",
        paths.len(),
        first.0.width,
        first.0.height,
        first.1,
        last.1,
        args.out.display()
    );
    Ok(())
}
