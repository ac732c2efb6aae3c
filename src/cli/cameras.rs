//! `maaf cameras`: write the cameras of a data set's split as maaf camera files, so
//! `maaf render --camera` and `maaf render-ply --camera` can be driven without
//! hand-made JSON. Each file carries its view's time (`"time"`), at which `maaf render
//! --camera` renders unless `--time` says otherwise; [`read_camera_file`] reads both.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_scene::write_atomic;
use maaf_splat::Camera;
use maaf_train::data::{Dataset, DatasetOptions, FormatRegistry, Split};

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
    /// Output folder: NNNN.json per view (the camera format of `render --camera`, with
    /// the view's time) and cameras.json listing each file with its view's time; a
    /// folder written earlier is replaced whole.
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

/// The listing of the camera files and their times.
const LISTING: &str = "cameras.json";

/// Name of the camera file of view `i`, `NNNN.json`.
fn camera_file(i: usize) -> String {
    format!("{i:04}.json")
}

/// Refuses an existing `out` holding anything but an earlier `maaf cameras`'s files
/// (`NNNN.json`, `cameras.json`), which replacing it would lose.
fn refuse_foreign_files(out: &Path) -> anyhow::Result<()> {
    if !out.exists() {
        return Ok(());
    }
    let entries =
        std::fs::read_dir(out).with_context(|| format!("{}: cannot read", out.display()))?;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let ours = name == LISTING
            || name
                .strip_suffix(".json")
                .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()));
        if !ours {
            bail!(
                "{}: holds `{name}`, which is not a camera file of an earlier `maaf cameras`; give a new or empty folder",
                out.display()
            );
        }
    }
    Ok(())
}

/// A camera file (the format `maaf cameras` writes) and its optional `"time"`; errors
/// name the file and the field.
pub fn read_camera_file(path: &Path) -> anyhow::Result<(Camera, Option<f64>)> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let shown = path.display().to_string();
    let camera = Camera::from_json_str(&text, &shown)?;
    let value: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{shown}: not a camera file"))?;
    let time = match value.get("time") {
        None | Some(serde_json::Value::Null) => None,
        Some(t) => match t.as_f64().filter(|t| t.is_finite()) {
            Some(t) => Some(t),
            None => bail!("{shown}: time = {t}: must be a finite number"),
        },
    };
    Ok((camera, time))
}

/// Runs `maaf cameras` on a data folder in a built-in layout or one of `formats`.
pub fn run(args: &CamerasArgs, formats: &FormatRegistry) -> anyhow::Result<()> {
    if !(args.scale.is_finite() && args.scale > 0.0 && args.scale <= 1.0) {
        bail!("--scale {}: must be in (0, 1]", args.scale);
    }
    let data = Dataset::open_with(&args.data, DatasetOptions::default(), formats)?;
    let split = Split::from(args.split);
    let cameras = data.cameras(split, args.scale)?;
    if cameras.is_empty() {
        bail!("{}: the split has no views", args.data.display());
    }
    let times = data.times(split);
    refuse_foreign_files(&args.out)?;
    // Built aside and swapped in whole: no camera of an earlier, longer split stays.
    maaf_io::write_dir(
        &args.out,
        |p, e| anyhow::anyhow!("{}: {e}", p.display()),
        |tmp| {
            let mut index = Vec::with_capacity(cameras.len());
            for (i, (camera, time)) in cameras.iter().zip(&times).enumerate() {
                let name = camera_file(i);
                let mut file = serde_json::to_value(camera)?;
                file["time"] = serde_json::json!(time);
                let text = serde_json::to_string_pretty(&file)?;
                write_atomic(&tmp.join(&name), text.as_bytes())?;
                index.push(serde_json::json!({ "file": name, "time": time }));
            }
            let listing = serde_json::to_string_pretty(&serde_json::json!({ "cameras": index }))?;
            write_atomic(&tmp.join(LISTING), listing.as_bytes())?;
            Ok(())
        },
    )?;
    let (w, h) = (cameras[0].width, cameras[0].height);
    println!(
        "wrote {} cameras ({w}x{h}) to {} (NNNN.json, cameras.json)",
        cameras.len(),
        args.out.display()
    );
    Ok(())
}
