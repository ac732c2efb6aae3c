//! `maaf render-ply`: render a static 3DGS PLY from a camera JSON to PNG or NPY. A
//! frame `maaf export-ply` wrote carries its run's background and screen-space filter
//! in its header, which are the defaults here, so it renders as `maaf render` does.

use std::path::PathBuf;

use maaf_eval::export::FrameHeader;
use maaf_splat::output::save_image;
use maaf_splat::ply::read_ply_with_comments;
use maaf_splat::{Camera, Filter2d, RenderSettings, render_gaussians};

use super::Background;

/// The screen-space filter on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Filter2dArg {
    /// 3DGS dilation: +0.3 px^2, no opacity compensation.
    Classic,
    /// Mip-Splatting 2D Mip filter: +0.1 px^2 with opacity compensation.
    Mip,
}

/// Arguments of `maaf render-ply`.
#[derive(clap::Args, Debug)]
pub struct RenderPlyArgs {
    /// Standard 3DGS PLY (x y z f_dc_* f_rest_* opacity scale_* rot_*).
    #[arg(long)]
    pub ply: PathBuf,
    /// Camera JSON: {"width","height","fx","fy","cx","cy","world_to_camera":[[4]x4]}
    /// (OpenCV axes, row-major world-to-camera).
    #[arg(long)]
    pub camera: PathBuf,
    /// Output image: .png (8-bit) or .npy (float32 [H,W,3], linear, unquantised).
    #[arg(long)]
    pub out: PathBuf,
    /// Background: white, black, or r,g,b in [0, 1] [default: the one the PLY's header
    /// records (an exported frame: its run's), else black].
    #[arg(long, value_parser = Background::parse)]
    pub background: Option<Background>,
    /// Screen-space filter [default: the one the PLY's header records (an exported
    /// frame: its run's), else mip].
    #[arg(long, value_enum)]
    pub filter2d: Option<Filter2dArg>,
    /// SH degree to evaluate (capped at the degree stored in the PLY).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub sh_degree: u8,
}

/// Runs `maaf render-ply`.
pub fn run(args: &RenderPlyArgs) -> anyhow::Result<()> {
    let camera = Camera::from_json_file(&args.camera)?;
    let (gaussians, comments) = read_ply_with_comments(&args.ply)?;
    let header = FrameHeader::parse(&comments, &args.ply.display().to_string())?;
    let background = args.background.or(header.background).unwrap_or_default();
    let filter2d = match args.filter2d {
        Some(Filter2dArg::Classic) => Filter2d::Classic,
        Some(Filter2dArg::Mip) => Filter2d::Mip,
        None => header.filter2d.unwrap_or_default(),
    };
    let settings = RenderSettings {
        background: background.rgb().map(f64::from),
        filter2d,
        sh_degree: args.sh_degree as usize,
        ..RenderSettings::default()
    };
    let frame = render_gaussians(&gaussians, &camera, &settings);
    save_image(&args.out, &frame.image)?;
    eprintln!(
        "rendered {} Gaussians ({} visible) at {}x{} to {}",
        gaussians.len(),
        frame.radii.iter().filter(|&&r| r > 0).count(),
        camera.width,
        camera.height,
        args.out.display()
    );
    Ok(())
}
