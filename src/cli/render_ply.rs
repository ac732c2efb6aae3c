//! `maaf render-ply`: render a static 3DGS PLY from a camera JSON to PNG or NPY.

use std::path::PathBuf;

use maaf_splat::output::save_image;
use maaf_splat::{Camera, Filter2d, RenderSettings, read_ply, render_gaussians};

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
    /// Background colour as r,g,b in [0,1].
    #[arg(long, value_parser = parse_rgb, default_value = "0,0,0")]
    pub background: [f64; 3],
    /// Screen-space filter.
    #[arg(long, value_enum, default_value_t = Filter2dArg::Mip)]
    pub filter2d: Filter2dArg,
    /// SH degree to evaluate (capped at the degree stored in the PLY).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub sh_degree: u8,
}

fn parse_rgb(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected r,g,b (three numbers), got `{s}`"));
    }
    let mut rgb = [0.0; 3];
    for (v, p) in rgb.iter_mut().zip(&parts) {
        *v = p
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{p}` in `{s}` is not a finite number"))?;
    }
    Ok(rgb)
}

/// Runs `maaf render-ply`.
pub fn run(args: &RenderPlyArgs) -> anyhow::Result<()> {
    let camera = Camera::from_json_file(&args.camera)?;
    let gaussians = read_ply(&args.ply)?;
    let settings = RenderSettings {
        background: args.background,
        filter2d: match args.filter2d {
            Filter2dArg::Classic => Filter2d::Classic,
            Filter2dArg::Mip => Filter2d::Mip,
        },
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
