//! The command line: every subcommand and its dispatch (docs/cli.md).

use clap::{Parser, Subcommand};
use maaf_eval::MetricRegistry;
use maaf_train::Plugins;

use crate::cli;

/// Alias-free 4D Gaussian splatting of dynamic scenes (motion-aware smoothing filter).
#[derive(Parser)]
#[command(name = "maaf", version, about, long_about = None)]
pub(super) struct Cli {
    /// Print only warnings and errors on stderr (no progress lines or bars).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub(super) quiet: bool,
    /// Also print debug messages on stderr.
    #[arg(short, long, global = true)]
    pub(super) verbose: bool,
    #[command(subcommand)]
    command: Command,
}

impl Cli {
    /// The level of the messages the command prints on stderr: info (progress), warn
    /// with `-q`, debug with `-v`.
    pub(super) fn log_level(&self) -> log::LevelFilter {
        if self.quiet {
            log::LevelFilter::Warn
        } else if self.verbose {
            log::LevelFilter::Debug
        } else {
            log::LevelFilter::Info
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Generate the built-in scene, train with no / static / motion-aware 3D filter,
    /// evaluate at 1/4x..4x and write a report (the README's main command).
    Demo(cli::demo::DemoArgs),
    /// Print the version, the float types and the worker thread count, and exit.
    Info,
    /// Write a built-in synthetic dynamic scene (D-NeRF format, supersampled, with flow).
    Generate(cli::generate::GenerateArgs),
    /// Write the cameras of a data set's split as camera files for render --camera.
    Cameras(cli::cameras::CamerasArgs),
    /// Summarise a data set in any of the three layouts maaf reads (D-NeRF, Plenoptic
    /// Video, Dynamic 3D Gaussians): views, resolution, times, cameras, bounds.
    Inspect(cli::inspect::InspectArgs),
    /// Train a 4D Gaussian model (SaRO-GS or Deformable-3DGS, + 3D filter) on a data set.
    Train(cli::train::TrainArgs),
    /// Render a static 3DGS PLY from a camera JSON to a PNG or float32 NPY image.
    RenderPly(cli::render_ply::RenderPlyArgs),
    /// Evaluate a trained run at several scales (PSNR, SSIM, LPIPS; --temporal: W-Temporal
    /// Error, W-SSIM, W-LPIPS) and write RUN/eval.json.
    Eval(cli::eval::EvalArgs),
    /// Render one image of a trained run at a time from a data-set view or camera JSON.
    Render(cli::render::RenderArgs),
    /// Render a video of a trained run (PNG frames + GIF): one camera over time, an
    /// orbit or spiral path, or the data set's test views.
    RenderVideo(cli::render::RenderVideoArgs),
    /// Compare evaluated runs: markdown tables (paper Tab. 2 layout) and PNG charts.
    Report(cli::report::ReportArgs),
    /// PSNR, SSIM and LPIPS of two images (the conventions of `maaf eval`).
    Compare(cli::compare::CompareArgs),
    /// Time one training step phase by phase at several Gaussian counts, against this
    /// machine's measured GEMM and copy rates.
    Bench(cli::bench::BenchArgs),
    /// Export a trained run at a time (or N frames) as standard 3DGS PLY.
    ExportPly(cli::export_ply::ExportPlyArgs),
    /// Write an ablation grid as run folders plus a plain job list (jobs.txt: one
    /// train-and-eval line per point, for bash, GNU parallel or array jobs).
    Sweep(cli::sweep::SweepArgs),
    /// The D-NeRF protocol over a folder of scenes (scene x preset x filter x
    /// background: train, evaluate at 1/4x..4x) as a resumable job list, and one Tab.
    /// 2-shaped report beside the published rows.
    BenchSuite(cli::bench_suite::BenchSuiteArgs),
}

/// Runs the parsed command; `plugins` are the terms, representations, filters and
/// strategies a run may name (the other commands load runs through its
/// representations) and the data layouts every command that opens a data folder
/// reads, `metrics` the per-image metrics `eval` adds.
pub(super) fn run(cli: Cli, plugins: &Plugins, metrics: &MetricRegistry) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo(args) => cli::demo::run(&args)?,
        Command::Generate(args) => cli::generate::run(&args)?,
        Command::Inspect(args) => cli::inspect::run(&args, &plugins.formats)?,
        Command::Train(args) => cli::train::run(&args, plugins)?,
        Command::RenderPly(args) => cli::render_ply::run(&args)?,
        Command::Eval(args) => cli::eval::run(&args, plugins, metrics)?,
        Command::Render(args) => cli::render::run(&args, plugins)?,
        Command::RenderVideo(args) => cli::render::run_video(&args, plugins)?,
        Command::Cameras(args) => cli::cameras::run(&args, &plugins.formats)?,
        Command::Report(args) => cli::report::run(&args)?,
        Command::Compare(args) => cli::compare::run(&args)?,
        Command::Bench(args) => cli::bench::run(&args, plugins)?,
        Command::ExportPly(args) => cli::export_ply::run(&args, plugins)?,
        Command::Sweep(args) => cli::sweep::run(&args)?,
        Command::BenchSuite(args) => cli::bench_suite::run(&args, plugins)?,
        Command::Info => {
            println!("maaf {}", env!("CARGO_PKG_VERSION"));
            println!(
                "floats: f32 (training, rendering, evaluation), f64 (gradient checks: autodiff::check)"
            );
            // The pool the commands run on (RAYON_NUM_THREADS, default one per core).
            println!(
                "threads: {} (RAYON_NUM_THREADS, default one per core)",
                rayon::current_num_threads()
            );
        }
    }
    Ok(())
}
