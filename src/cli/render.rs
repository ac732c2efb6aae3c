//! `maaf render` (one image of a trained run at a time and camera) and
//! `maaf render-video` (a fixed-camera video over time: PNG frames + animated GIF).

use std::path::PathBuf;

use anyhow::{Context, bail};
use maaf_splat::Camera;
use maaf_train::data::{Dataset, Split};
use maaf_train::eval::images::{save_png, to_rgb8};
use maaf_train::eval::render::render_video;
use maaf_train::eval::{load_run, render_image, run_camera};
use maaf_train::trainer::Trainer;

use super::BackgroundArg;
use super::eval::{open_run_data, read_lock};

/// Where the camera comes from (shared by `render` and `render-video`).
#[derive(clap::Args, Debug)]
pub struct CameraArgs {
    /// Run directory written by `maaf train`.
    #[arg(long)]
    pub run: PathBuf,
    /// Data folder the run was trained on (default: the one in RUN/data.json).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// A data-set view as SPLIT:INDEX, e.g. test:0 or video:0.
    #[arg(long, conflicts_with = "camera", required_unless_present = "camera")]
    pub view: Option<String>,
    /// Camera JSON: {"width","height","fx","fy","cx","cy","world_to_camera":[[4]x4]}.
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Scale relative to the training scale for --view (2 = zoom-in 2x).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Background (default: RUN/data.json's, else white).
    #[arg(long, value_enum)]
    pub background: Option<BackgroundArg>,
}

/// Arguments of `maaf render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    camera: CameraArgs,
    /// Time to render (default: the view's time with --view, else 0).
    #[arg(long)]
    pub time: Option<f64>,
    /// Output PNG (8-bit).
    #[arg(long)]
    pub out: PathBuf,
}

/// Arguments of `maaf render-video`.
#[derive(clap::Args, Debug)]
pub struct RenderVideoArgs {
    #[command(flatten)]
    camera: CameraArgs,
    /// Number of frames, evenly spaced over the data set's time range.
    #[arg(long, default_value_t = 30)]
    pub frames: usize,
    /// Output folder (frame_NNNN.png and video.gif).
    #[arg(long)]
    pub out: PathBuf,
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

/// Loads the run and resolves the camera; also returns the view's time if any.
fn setup(args: &CameraArgs) -> anyhow::Result<(Dataset, Trainer, Camera, Option<f64>)> {
    let data = open_run_data(&args.run, args.data.as_deref(), args.background)?;
    // Check the cheap arguments before loading the model.
    let view = args.view.as_deref().map(parse_view).transpose()?;
    let file_camera = args
        .camera
        .as_ref()
        .map(|p| Camera::from_json_file(p))
        .transpose()?;
    let trainer = load_run(&args.run, &data)?;
    let (camera, time) = match (view, file_camera) {
        (Some((split, index)), _) => {
            let cam = run_camera(&trainer, &data, split, index, args.scale)?;
            let time = data.times(split).get(index).copied();
            (cam, time)
        }
        (None, Some(cam)) => (cam, None),
        (None, None) => bail!("give --view SPLIT:INDEX or --camera CAM.json"),
    };
    Ok((data, trainer, camera, time))
}

/// Runs `maaf render`.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
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
    let (data, trainer, camera, view_time) = setup(&args.camera)?;
    let time = args.time.or(view_time).unwrap_or(0.0);
    let (t0, t1) = data.time_range();
    if !(t0..=t1).contains(&time) {
        eprintln!(
            "maaf: warning: --time {time} is outside the data's time range [{t0}, {t1}]: the model extrapolates"
        );
    }
    let settings = trainer.render_settings(trainer.iteration);
    let image = render_image(&trainer, &camera, time, &settings);
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
pub fn run_video(args: &RenderVideoArgs) -> anyhow::Result<()> {
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    let _lock = read_lock(&args.camera.run)?;
    let (data, trainer, camera, _) = setup(&args.camera)?;
    let range = data.time_range();
    let paths = render_video(&trainer, &camera, range, args.frames, &args.out)?;
    println!(
        "rendered {} frames ({}x{}, t = {}..{}) to {} (frame_NNNN.png, video.gif)",
        paths.len(),
        camera.width,
        camera.height,
        range.0,
        range.1,
        args.out.display()
    );
    Ok(())
}
