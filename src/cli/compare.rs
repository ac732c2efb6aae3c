//! `maaf compare`: PSNR, SSIM and LPIPS of two images, with the conventions of
//! `maaf eval` (values `v / 255` on [0, 1], no gamma change, straight alpha composited
//! on the background, PSNR and SSIM of [`maaf_eval::metrics`], LPIPS of
//! [`maaf_lpips`] on RGB at the images' own size).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_autodiff::Tensor;
use maaf_lpips::{Lpips, Net};
use maaf_scene::metrics::{psnr, ssim};
use maaf_train::data::downsample::{composite_premultiplied, premultiply};
use maaf_train::data::image::decode_rgba;
use serde_json::json;

use super::Background;

/// Arguments of `maaf compare`.
#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// The image to score (PNG or JPEG), e.g. a render.
    #[arg(long = "render", value_name = "IMAGE")]
    pub a: PathBuf,
    /// The reference image of the same size, e.g. the ground truth.
    #[arg(long = "gt", value_name = "IMAGE")]
    pub b: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Background for pixels with alpha < 1 (opaque images are unaffected): white,
    /// black, or r,g,b in [0, 1].
    #[arg(long, value_parser = Background::parse, default_value_t = Background::default())]
    pub background: Background,
    /// LPIPS backbone: alex or vgg (as `maaf eval --lpips-net`).
    #[arg(long, default_value = "alex")]
    pub lpips_net: Net,
}

/// An image file as an `[H, W, 3]` tensor on [0, 1], alpha composited on `bg`.
fn load_rgb(path: &Path, bg: [f32; 3]) -> anyhow::Result<Tensor<f32>> {
    let mut img = decode_rgba(path)?;
    premultiply(&mut img.data);
    let rgb = composite_premultiplied(&img.data, bg);
    Ok(Tensor::from_vec(
        rgb,
        &[img.height as usize, img.width as usize, 3],
    ))
}

/// Runs `maaf compare`.
pub fn run(args: &CompareArgs) -> anyhow::Result<()> {
    let bg = args.background.rgb();
    let a = load_rgb(&args.a, bg)?;
    let b = load_rgb(&args.b, bg)?;
    if a.shape() != b.shape() {
        bail!(
            "{} is {}x{} but {} is {}x{}: compare needs images of the same size",
            args.a.display(),
            a.shape()[1],
            a.shape()[0],
            args.b.display(),
            b.shape()[1],
            b.shape()[0]
        );
    }
    let names = || format!("{} vs {}", args.a.display(), args.b.display());
    let p = psnr(&a, &b).with_context(names)?;
    let s = ssim(&a, &b).with_context(names)?;
    // LPIPS is optional: without weights (or for tiny images) it is reported as
    // missing with the reason, as eval does.
    let lpips = Lpips::load_default(args.lpips_net).and_then(|m| m.distance(&a, &b));
    if args.json {
        let (value, reason) = match &lpips {
            Ok(v) => (json!(v), json!(null)),
            Err(e) => (json!(null), json!(e.to_string())),
        };
        let out = json!({
            "a": args.a.display().to_string(),
            "b": args.b.display().to_string(),
            "width": a.shape()[1],
            "height": a.shape()[0],
            "psnr": if p.is_finite() { json!(p) } else { json!(null) },
            "identical": p.is_infinite(),
            "ssim": s,
            "lpips": value,
            "lpips_unavailable": reason,
        });
        println!("{out}");
    } else {
        println!("{} ({}x{})", names(), a.shape()[1], a.shape()[0]);
        println!("PSNR  {p:.3} dB");
        println!("SSIM  {s:.5}");
        match lpips {
            Ok(v) => println!("LPIPS {v:.5} ({} v0.1)", args.lpips_net),
            Err(e) => println!("LPIPS unavailable: {e}"),
        }
    }
    Ok(())
}
