//! Image outputs of the evaluation and render commands: 8-bit PNGs of float renders,
//! colour-mapped error maps and animated GIFs. Metrics never see these 8-bit images;
//! they are for looking at.

use std::path::Path;

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, RgbImage, RgbaImage};
use maaf_autodiff::Tensor;

use crate::{Error, write_atomic};

/// Error value mapped to the top of the error colour ramp (mean absolute RGB error;
/// larger errors saturate). Fixed so error maps of different runs are comparable.
pub const ERROR_MAP_MAX: f32 = 0.25;

/// Converts a float `[H, W, 3]` image on [0, 1] to 8-bit RGB with the renderer's
/// quantisation ([`maaf_splat::output::to_rgb8`]: `round(255 clamp(v, 0, 1))`).
/// Refuses an image with a non-finite value, which would otherwise quantise to a
/// plausible-looking black or white pixel.
pub fn to_rgb8(image: &Tensor<f32>) -> Result<RgbImage, Error> {
    let shape = image.shape();
    if shape.len() != 3 || shape[2] != 3 {
        return Err(Error::Input(format!(
            "expected an [H, W, 3] image, got shape {shape:?}"
        )));
    }
    if let Some(i) = image.data().iter().position(|v| !v.is_finite()) {
        let pixel = i / 3;
        return Err(Error::Input(format!(
            "the render has a non-finite value ({}) at pixel ({}, {}): the model or the camera is degenerate, nothing written",
            image.data()[i],
            pixel % shape[1],
            pixel / shape[1]
        )));
    }
    let (h, w) = (shape[0] as u32, shape[1] as u32);
    RgbImage::from_raw(w, h, maaf_splat::output::to_rgb8(image))
        .ok_or_else(|| Error::Input("image buffer does not match its shape".into()))
}

/// The error maps' colour for `v` on [0, 1] (clamped): matplotlib's inferno (black,
/// purple, red, orange, pale yellow), perceptually ordered from dark to light.
pub fn ramp(v: f32) -> [u8; 3] {
    let c = colorous::INFERNO.eval_continuous(f64::from(v.clamp(0.0, 1.0)));
    [c.r, c.g, c.b]
}

/// Colour-maps an `[H, W]` error map: 0 is black, [`ERROR_MAP_MAX`] and above pale yellow.
pub fn error_to_rgb8(error: &Tensor<f32>) -> Result<RgbImage, Error> {
    let shape = error.shape();
    if shape.len() != 2 {
        return Err(Error::Input(format!(
            "expected an [H, W] error map, got shape {shape:?}"
        )));
    }
    let (h, w) = (shape[0] as u32, shape[1] as u32);
    let bytes: Vec<u8> = error
        .data()
        .iter()
        .flat_map(|&e| ramp(e / ERROR_MAP_MAX))
        .collect();
    RgbImage::from_raw(w, h, bytes)
        .ok_or_else(|| Error::Input("error map buffer does not match its shape".into()))
}

/// Writes `img` as PNG to `path`, crash-safely ([`write_atomic`]).
pub fn save_png(img: &RgbImage, path: &Path) -> Result<(), Error> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::Input(format!("{}: cannot encode PNG: {e}", path.display())))?;
    write_atomic(path, &bytes)
}

/// Writes `frames` as an infinitely looping animated GIF (`delay_ms` per frame),
/// crash-safely. GIF has 256 colours per frame, so this is a preview; the PNG frames
/// are the faithful output.
pub fn save_gif(frames: &[RgbImage], delay_ms: u32, path: &Path) -> Result<(), Error> {
    let mut bytes = Vec::new();
    {
        let mut enc = GifEncoder::new_with_speed(&mut bytes, 10);
        enc.set_repeat(Repeat::Infinite)
            .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
        let gif_frames = frames.iter().map(|f| {
            let rgba: RgbaImage = image::DynamicImage::ImageRgb8(f.clone()).to_rgba8();
            image::Frame::from_parts(rgba, 0, 0, Delay::from_numer_denom_ms(delay_ms, 1))
        });
        enc.encode_frames(gif_frames)
            .map_err(|e| Error::Input(format!("{}: cannot encode GIF: {e}", path.display())))?;
    }
    write_atomic(path, &bytes)
}
