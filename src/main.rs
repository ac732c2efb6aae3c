//! The `maaf` command-line tool (DESIGN.md section 8).

use clap::{Parser, Subcommand};

mod cli;

/// Alias-free 4D Gaussian splatting of dynamic scenes (motion-aware smoothing filter).
#[derive(Parser)]
#[command(name = "maaf", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the build configuration (float types, thread count) and exit.
    Info,
    /// Render a static 3DGS PLY from a camera JSON to a PNG or float32 NPY image.
    RenderPly(cli::render_ply::RenderPlyArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::RenderPly(args) => cli::render_ply::run(&args)?,
        Command::Info => {
            println!("maaf {}", env!("CARGO_PKG_VERSION"));
            println!(
                "threads: {}",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            );
        }
    }
    Ok(())
}
