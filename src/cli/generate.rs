//! `maaf generate`: write a built-in synthetic dynamic scene in D-NeRF format.

use std::io::Write;
use std::path::PathBuf;

use maaf_train::data::synthetic::{self, GenerateOptions, Rig};

/// Arguments of `maaf generate`.
#[derive(clap::Args, Debug)]
pub struct GenerateArgs {
    /// Built-in scene name.
    #[arg(long, default_value = synthetic::DEFAULT_SCENE)]
    pub scene: String,
    /// Output folder (must not exist unless --force; written atomically).
    #[arg(long)]
    pub out: PathBuf,
    /// Image width and height in pixels (a multiple of 4).
    #[arg(long, default_value_t = 800)]
    pub size: u32,
    /// Training time steps [default: 100 for monocular, 30 for ring].
    #[arg(long)]
    pub frames: Option<usize>,
    /// Camera rig of the training split: monocular (one camera per time) or ring
    /// (fixed cameras, every time).
    #[arg(long, default_value = "monocular")]
    pub rig: Rig,
    /// Seed of the camera positions, test times and sample jitter.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Jittered samples per pixel along each axis (n x n per pixel).
    #[arg(long, default_value_t = 4)]
    pub samples: u32,
    /// Number of test views.
    #[arg(long, default_value_t = 20)]
    pub test_frames: usize,
    /// Number of validation views.
    #[arg(long, default_value_t = 10)]
    pub val_frames: usize,
    /// Frames of the fixed-camera video (forward flow between consecutive frames).
    #[arg(long, default_value_t = 30)]
    pub video_frames: usize,
    /// Cameras of the ring rig.
    #[arg(long, default_value_t = 6)]
    pub ring_cameras: usize,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
}

/// Runs `maaf generate`.
pub fn run(args: &GenerateArgs) -> anyhow::Result<()> {
    let opts = GenerateOptions {
        scene: args.scene.clone(),
        size: args.size,
        frames: args.frames,
        rig: args.rig,
        seed: args.seed,
        samples: args.samples,
        test_frames: args.test_frames,
        val_frames: args.val_frames,
        video_frames: args.video_frames,
        ring_cameras: args.ring_cameras,
        force: args.force,
    };
    let mut err = std::io::stderr();
    let summary = synthetic::generate(&args.out, &opts, &mut |done, total| {
        let _ = write!(err, "\rgenerate: {done}/{total} images");
        let _ = err.flush();
    })?;
    eprintln!();
    let [train, val, test, video] = summary.counts;
    println!(
        "wrote {} ({} rig, {}x{}): {train} train, {val} val, {test} test, {video} video frames with flow, in {:.1} s",
        summary.out.display(),
        args.rig,
        args.size,
        args.size,
        summary.seconds
    );
    Ok(())
}
