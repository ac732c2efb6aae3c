//! Image outputs of the evaluation and render commands: 8-bit PNGs of float renders,
//! colour-mapped error maps and animated GIFs. Metrics never see these 8-bit images;
//! they are for looking at.

use std::path::Path;

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, RgbImage, RgbaImage};
use maaf_autodiff::Tensor;

use super::EvalError;

/// Error value mapped to the top of the error colour ramp (mean absolute RGB error;
/// larger errors saturate). Fixed so error maps of different runs are comparable.
pub const ERROR_MAP_MAX: f32 = 0.25;

/// Converts a float `[H, W, 3]` image on [0, 1] to 8-bit RGB (clamped, rounded).
pub fn to_rgb8(image: &Tensor<f32>) -> Result<RgbImage, EvalError> {
    let shape = image.shape();
    if shape.len() != 3 || shape[2] != 3 {
        return Err(EvalError::Input(format!(
            "expected an [H, W, 3] image, got shape {shape:?}"
        )));
    }
    let (h, w) = (shape[0] as u32, shape[1] as u32);
    let bytes: Vec<u8> = image
        .data()
        .iter()
        .map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    RgbImage::from_raw(w, h, bytes)
        .ok_or_else(|| EvalError::Input("image buffer does not match its shape".into()))
}

/// A colour ramp (black, purple, red, orange, pale yellow) for `v` on [0, 1].
fn ramp(v: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [0.35, 0.05, 0.45],
        [0.80, 0.15, 0.25],
        [0.98, 0.55, 0.05],
        [1.0, 1.0, 0.75],
    ];
    let x = v.clamp(0.0, 1.0) * (STOPS.len() - 1) as f32;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    let c = |k: usize| STOPS[i][k] + (STOPS[i + 1][k] - STOPS[i][k]) * f;
    [0, 1, 2].map(|k| (c(k) * 255.0).round() as u8)
}

/// Colour-maps an `[H, W]` error map: 0 is black, [`ERROR_MAP_MAX`] and above pale yellow.
pub fn error_to_rgb8(error: &Tensor<f32>) -> Result<RgbImage, EvalError> {
    let shape = error.shape();
    if shape.len() != 2 {
        return Err(EvalError::Input(format!(
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
        .ok_or_else(|| EvalError::Input("error map buffer does not match its shape".into()))
}

/// Writes `img` as PNG to `path` (not atomic: callers write into a temporary folder
/// or use [`save_png_atomic`]).
pub fn save_png(img: &RgbImage, path: &Path) -> Result<(), EvalError> {
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| EvalError::Input(format!("{}: cannot write PNG: {e}", path.display())))
}

/// Writes `img` as PNG to `path` through a temporary sibling file and a rename.
pub fn save_png_atomic(img: &RgbImage, path: &Path) -> Result<(), EvalError> {
    let tmp = super::tmp_sibling(path);
    save_png(img, &tmp)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        EvalError::io(path, e)
    })
}

/// Writes `frames` as an infinitely looping animated GIF (`delay_ms` per frame),
/// atomically. GIF has 256 colours per frame, so this is a preview; the PNG frames
/// are the faithful output.
pub fn save_gif(frames: &[RgbImage], delay_ms: u32, path: &Path) -> Result<(), EvalError> {
    let tmp = super::tmp_sibling(path);
    let result = (|| {
        let file = std::fs::File::create(&tmp).map_err(|e| EvalError::io(&tmp, e))?;
        let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
        enc.set_repeat(Repeat::Infinite)
            .map_err(|e| EvalError::Input(format!("{}: {e}", path.display())))?;
        let gif_frames = frames.iter().map(|f| {
            let rgba: RgbaImage = image::DynamicImage::ImageRgb8(f.clone()).to_rgba8();
            image::Frame::from_parts(rgba, 0, 0, Delay::from_numer_denom_ms(delay_ms, 1))
        });
        enc.encode_frames(gif_frames)
            .map_err(|e| EvalError::Input(format!("{}: cannot write GIF: {e}", path.display())))
    })();
    match result {
        Ok(()) => std::fs::rename(&tmp, path).map_err(|e| EvalError::io(path, e)),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_ends() {
        assert_eq!(ramp(0.0), [0, 0, 0]);
        assert_eq!(ramp(1.0), [255, 255, 191]);
        assert_eq!(ramp(7.0), ramp(1.0));
    }

    #[test]
    fn rgb8_rounds_and_clamps() {
        let t = Tensor::from_vec(vec![0.0, 0.5, 1.5, -1.0, 1.0, 0.2], &[1, 2, 3]);
        let img = to_rgb8(&t).expect("image");
        assert_eq!(img.as_raw(), &vec![0, 128, 255, 0, 255, 51]);
    }
}
