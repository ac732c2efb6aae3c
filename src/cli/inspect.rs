//! `maaf inspect`: summarise a data set (D-NeRF, Plenoptic Video or the Dynamic 3D
//! Gaussians layout) before training.

use std::path::PathBuf;

use maaf_train::data::FormatRegistry;
use maaf_train::data::inspect::inspect;

/// Arguments of `maaf inspect`.
#[derive(clap::Args, Debug)]
pub struct InspectArgs {
    /// Data folder: D-NeRF (transforms_{train,val,test}.json), Plenoptic Video
    /// (poses_bounds.npy, camXX/) or the Dynamic 3D Gaussians layout (train_meta.json,
    /// ims/).
    #[arg(long)]
    pub data: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Only read image headers; skip decoding every image.
    #[arg(long)]
    pub no_decode: bool,
}

/// Runs `maaf inspect` on a data folder in a built-in layout or one of `formats`.
pub fn run(args: &InspectArgs, formats: &FormatRegistry) -> anyhow::Result<()> {
    let summary = inspect(&args.data, !args.no_decode, formats)?;
    if args.json {
        println!("{}", summary.to_json_string());
    } else {
        print!("{}", summary.to_text());
    }
    Ok(())
}
