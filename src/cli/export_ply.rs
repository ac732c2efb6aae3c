//! `maaf export-ply`: the deformed, filtered Gaussians of a trained run at a time as a
//! standard 3DGS PLY (`--time T --out F.ply`), or a sequence of `N` frames over the
//! data set's time range (`--frames N --out DIR`: only `frame_NNNN.ply`, each with its
//! time in its header, as brush and SuperSplat play them; `--out X.zip`: the same
//! files as one zip archive). Gaussians invisible at a frame's time are left out.

use std::path::PathBuf;

use anyhow::bail;
use maaf_eval::check_frame_count;
use maaf_eval::export::{
    check_sequence_target, export_frame, export_sequence, export_sequence_zip, is_zip_path,
};

use maaf_train::Plugins;

use super::Background;
use super::eval::{load_scene, read_lock};

/// Arguments of `maaf export-ply`.
#[derive(clap::Args, Debug)]
pub struct ExportPlyArgs {
    /// Run directory written by `maaf train`.
    #[arg(long)]
    pub run: PathBuf,
    /// Data folder the run was trained on, read only for a run saved before
    /// checkpoints recorded their cameras [default: the one in RUN/data.json].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Time of the single frame to export (writes the PLY file --out).
    #[arg(long, conflicts_with = "frames", required_unless_present = "frames")]
    pub time: Option<f64>,
    /// Export N frames (at most 10000) evenly spaced over the data set's time range
    /// into the folder --out, or into one zip archive when --out ends in .zip.
    #[arg(long)]
    pub frames: Option<usize>,
    /// Output PLY file (--time), or folder or .zip file (--frames).
    #[arg(long)]
    pub out: PathBuf,
    /// Background of the run's data (only used to open the data set of a run saved
    /// before checkpoints recorded their cameras): white, black, or r,g,b in [0, 1]
    /// [default: the run's]. The PLY header records the run's own background.
    #[arg(long, value_parser = Background::parse)]
    pub background: Option<Background>,
}

/// Runs `maaf export-ply`.
pub fn run(args: &ExportPlyArgs, plugins: &Plugins) -> anyhow::Result<()> {
    if let Some(n) = args.frames {
        check_frame_count(n)?;
        check_sequence_target(&args.out)?;
    }
    let _lock = read_lock(&args.run)?;
    let scene = load_scene(
        &args.run,
        args.data.as_deref(),
        args.background,
        None,
        plugins,
    )?;
    let range = scene.record.time_range;
    match (args.time, args.frames) {
        (Some(t), _) => {
            if !t.is_finite() {
                bail!("--time {t}: must be a finite number");
            }
            if is_zip_path(&args.out) {
                bail!(
                    "{}: --time writes one PLY file; use --frames N for a .zip sequence",
                    args.out.display()
                );
            }
            let (t0, t1) = range;
            if !(t0..=t1).contains(&t) {
                eprintln!(
                    "maaf: warning: --time {t} is outside the data's time range [{t0}, {t1}]: the model extrapolates"
                );
            }
            let kept = export_frame(&scene, t, &args.out)?;
            let bytes = std::fs::metadata(&args.out).map_or(0, |m| m.len());
            println!(
                "wrote {} ({kept} of {} Gaussians, those drawn at t = {t}; {:.2} MB)",
                args.out.display(),
                scene.num_gaussians(),
                bytes as f64 / 1e6
            );
        }
        (None, Some(n)) if is_zip_path(&args.out) => {
            let bytes = export_sequence_zip(&scene, range, n, &args.out)?;
            println!(
                "wrote {n} frames to {} ({:.2} MB zip)",
                args.out.display(),
                bytes as f64 / 1e6
            );
        }
        (None, Some(n)) => {
            let paths = export_sequence(&scene, range, n, &args.out)?;
            let bytes: u64 = paths
                .iter()
                .filter_map(|p| std::fs::metadata(p).ok())
                .map(|m| m.len())
                .sum();
            println!(
                "wrote {} frames to {} ({:.2} MB in all)",
                paths.len(),
                args.out.display(),
                bytes as f64 / 1e6
            );
        }
        (None, None) => bail!("give --time T or --frames N"),
    }
    Ok(())
}
