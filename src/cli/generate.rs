//! `maaf generate`: write a built-in synthetic dynamic scene, in D-NeRF format
//! (monocular or ring rig) or, for the multiview rig, in the Plenoptic Video or the
//! Dynamic 3D Gaussians layout.

use std::io::Write;
use std::path::PathBuf;

use maaf_train::data::synthetic::{self, GenerateOptions, MultiviewOptions, Rig};

/// Camera rig: the D-NeRF-format rigs of [`Rig`] or the Plenoptic Video one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RigArg {
    /// One camera per time at a random position on the cap (D-NeRF format).
    Monocular,
    /// Fixed cameras on the cap rendering every time (D-NeRF format).
    Ring,
    /// 15-20 fixed cameras on an arc, cam00 held out, with flow and moving masks for
    /// cam00 (Plenoptic Video format: poses_bounds.npy + camXX/images/NNNN.png).
    Multiview,
}

/// File layout of the multiview rig.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LayoutArg {
    /// Plenoptic Video: poses_bounds.npy + camXX/images/NNNN.png.
    Plenoptic,
    /// Dynamic 3D Gaussians (CMU Panoptic): train_meta.json, test_meta.json,
    /// ims/<cam>/<frame>.png, seg/<cam>/<frame>.png; per-camera focal lengths and
    /// off-centre principal points.
    Dynamic3dgs,
}

/// Arguments of `maaf generate`.
#[derive(clap::Args, Debug)]
pub struct GenerateArgs {
    /// Built-in scene name [default: dolly; approach for the multiview rig].
    #[arg(long)]
    pub scene: Option<String>,
    /// Output folder (must not exist unless --force; written atomically).
    #[arg(long)]
    pub out: PathBuf,
    /// Image width in pixels, a multiple of 4 (16 for multiview) [default: 800; 448
    /// for multiview].
    #[arg(long)]
    pub size: Option<u32>,
    /// Image height for the multiview rig, a multiple of 16 [default: 3/4 of the width,
    /// rounded to 16]; the other rigs are square.
    #[arg(long)]
    pub height: Option<u32>,
    /// Training time steps (frames per camera for multiview) [default: 100 for
    /// monocular, 30 for ring, 150 for multiview].
    #[arg(long)]
    pub frames: Option<usize>,
    /// Camera rig of the training split.
    #[arg(long, value_enum, default_value_t = RigArg::Monocular)]
    pub rig: RigArg,
    /// File layout of the multiview rig.
    #[arg(long, value_enum, default_value_t = LayoutArg::Plenoptic)]
    pub layout: LayoutArg,
    /// Seed of the camera positions, test times and sample jitter.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Jittered samples per pixel along each axis (n x n per pixel).
    #[arg(long, default_value_t = 4)]
    pub samples: u32,
    /// Number of test views (monocular and ring).
    #[arg(long, default_value_t = 20)]
    pub test_frames: usize,
    /// Number of validation views (monocular and ring).
    #[arg(long, default_value_t = 10)]
    pub val_frames: usize,
    /// Frames of the fixed-camera video (monocular and ring; forward flow between
    /// consecutive frames).
    #[arg(long, default_value_t = 30)]
    pub video_frames: usize,
    /// Cameras of the ring rig [default: 6] or of the multiview rig, cam00 included
    /// [default: 16].
    #[arg(long, alias = "ring-cameras")]
    pub cameras: Option<usize>,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
}

/// Runs `maaf generate`.
pub fn run(args: &GenerateArgs) -> anyhow::Result<()> {
    let mut err = std::io::stderr();
    let mut progress = |done: usize, total: usize| {
        let _ = write!(err, "\rgenerate: {done}/{total} images");
        let _ = err.flush();
    };
    let rig = match args.rig {
        RigArg::Monocular => Rig::Monocular,
        RigArg::Ring => Rig::Ring,
        RigArg::Multiview => return run_multiview(args, &mut progress),
    };
    if args.height.is_some() {
        anyhow::bail!("--height: only the multiview rig has non-square images");
    }
    if args.layout != LayoutArg::Plenoptic {
        anyhow::bail!("--layout: only the multiview rig has other layouts");
    }
    let defaults = GenerateOptions::default();
    let opts = GenerateOptions {
        scene: args.scene.clone().unwrap_or(defaults.scene),
        size: args.size.unwrap_or(defaults.size),
        frames: args.frames,
        rig,
        seed: args.seed,
        samples: args.samples,
        test_frames: args.test_frames,
        val_frames: args.val_frames,
        video_frames: args.video_frames,
        ring_cameras: args.cameras.unwrap_or(defaults.ring_cameras),
        force: args.force,
    };
    let summary = synthetic::generate(&args.out, &opts, &mut progress)?;
    eprintln!();
    let [train, val, test, video] = summary.counts;
    println!(
        "wrote {} ({rig} rig, {s}x{s}): {train} train, {val} val, {test} test, {video} video frames with flow, in {:.1} s",
        summary.out.display(),
        summary.seconds,
        s = opts.size,
    );
    Ok(())
}

fn run_multiview(
    args: &GenerateArgs,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<()> {
    let defaults = MultiviewOptions::default();
    let width = args.size.unwrap_or(defaults.width);
    let opts = MultiviewOptions {
        scene: args.scene.clone().unwrap_or(defaults.scene),
        width,
        height: args.height.unwrap_or(
            (width.saturating_mul(3) / 4)
                .div_ceil(16)
                .saturating_mul(16),
        ),
        cameras: args.cameras.unwrap_or(defaults.cameras),
        frames: args.frames.unwrap_or(defaults.frames),
        samples: args.samples,
        seed: args.seed,
        force: args.force,
    };
    let (summary, layout, test_note) = match args.layout {
        LayoutArg::Plenoptic => (
            synthetic::generate_multiview(&args.out, &opts, progress)?,
            "Plenoptic Video layout",
            "cam00, with flow and moving masks",
        ),
        LayoutArg::Dynamic3dgs => (
            synthetic::generate_dynamic3dgs(&args.out, &opts, progress)?,
            "Dynamic 3D Gaussians layout",
            "camera 0; every camera has foreground masks",
        ),
    };
    eprintln!();
    let [train, _, test, _] = summary.counts;
    println!(
        "wrote {} (multiview rig, {layout}, {} cameras x {} frames, {}x{}): {train} train views, {test} test views ({test_note}), in {:.1} s",
        summary.out.display(),
        opts.cameras,
        opts.frames,
        opts.width,
        opts.height,
        summary.seconds
    );
    Ok(())
}
