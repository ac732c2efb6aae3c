//! `maaf cameras`: write the cameras of a data set's split as maaf camera files, so
//! `maaf render --camera` and `maaf render-ply --camera` can be driven without
//! hand-made JSON.

use std::path::PathBuf;

use anyhow::{Context, bail};
use maaf_scene::write_atomic;
use maaf_train::data::{Dataset, DatasetOptions, Split};

/// Arguments of `maaf cameras`.
#[derive(clap::Args, Debug)]
pub struct CamerasArgs {
    /// Data folder (D-NeRF or multi-view video layout).
    #[arg(long)]
    pub data: PathBuf,
    /// Split whose cameras are written.
    #[arg(long, value_enum, default_value = "test")]
    pub split: CameraSplitArg,
    /// Image scale relative to the source images (0.25 = the D-NeRF training size); the
    /// source size must be divisible by 1 / scale.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Output folder: NNNN.json per view (the camera format of `render --camera`) and
    /// cameras.json listing each file with its view's time.
    #[arg(long)]
    pub out: PathBuf,
}

/// `--split` values of `maaf cameras`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum CameraSplitArg {
    /// transforms_test.json (multi-view video: cam00).
    Test,
    /// transforms_val.json.
    Val,
    /// transforms_train.json.
    Train,
    /// The fixed-camera video of a generated scene.
    Video,
}

impl From<CameraSplitArg> for Split {
    fn from(s: CameraSplitArg) -> Self {
        match s {
            CameraSplitArg::Test => Split::Test,
            CameraSplitArg::Val => Split::Val,
            CameraSplitArg::Train => Split::Train,
            CameraSplitArg::Video => Split::Video,
        }
    }
}

/// Runs `maaf cameras`.
pub fn run(args: &CamerasArgs) -> anyhow::Result<()> {
    if !(args.scale.is_finite() && args.scale > 0.0 && args.scale <= 1.0) {
        bail!("--scale {}: must be in (0, 1]", args.scale);
    }
    let data = Dataset::open(&args.data, DatasetOptions::default())?;
    let split = Split::from(args.split);
    let cameras = data.cameras(split, args.scale)?;
    if cameras.is_empty() {
        bail!("{}: the split has no views", args.data.display());
    }
    let times = data.times(split);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let mut index = Vec::with_capacity(cameras.len());
    for (i, (camera, time)) in cameras.iter().zip(&times).enumerate() {
        let name = format!("{i:04}.json");
        write_atomic(&args.out.join(&name), camera.to_json_string().as_bytes())?;
        index.push(serde_json::json!({ "file": name, "time": time }));
    }
    let listing = serde_json::to_string_pretty(&serde_json::json!({ "cameras": index }))?;
    write_atomic(&args.out.join("cameras.json"), listing.as_bytes())?;
    let (w, h) = (cameras[0].width, cameras[0].height);
    println!(
        "wrote {} cameras ({w}x{h}) to {} (NNNN.json, cameras.json)",
        cameras.len(),
        args.out.display()
    );
    Ok(())
}
