//! Image outputs of the evaluation and render commands: 8-bit PNGs of float renders,
//! colour-mapped error maps and animated GIFs. Metrics never see these 8-bit images;
//! they are for looking at.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use image::RgbImage;
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

/// An infinitely looping animated GIF written frame by frame into a file, so a video
/// of any length needs the memory of one frame. GIF has 256 colours per frame, so
/// this is a preview; the PNG frames are the faithful output. The file is written in
/// place: a caller that needs it crash-safe writes it into a folder swapped in whole
/// ([`maaf_io::write_dir`]).
pub struct GifWriter {
    encoder: Option<gif::Encoder<BufWriter<File>>>,
    writer: Option<BufWriter<File>>,
    delay: u16,
    path: PathBuf,
}

impl GifWriter {
    /// Creates the file `path` for frames shown `delay_ms` each.
    pub fn create(path: &Path, delay_ms: u32) -> Result<Self, Error> {
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        Ok(GifWriter {
            encoder: None,
            writer: Some(BufWriter::new(file)),
            delay: u16::try_from(delay_ms / 10).unwrap_or(u16::MAX),
            path: path.to_path_buf(),
        })
    }

    /// Appends a frame (every frame must have the first one's size).
    pub fn push(&mut self, frame: &RgbImage) -> Result<(), Error> {
        let bad = |e: gif::EncodingError| {
            Error::Input(format!("{}: cannot encode GIF: {e}", self.path.display()))
        };
        let (w, h) = frame.dimensions();
        let (Ok(w), Ok(h)) = (u16::try_from(w), u16::try_from(h)) else {
            return Err(Error::Input(format!(
                "{}: a GIF frame is at most 65535 px a side, not {w}x{h}",
                self.path.display()
            )));
        };
        if self.encoder.is_none()
            && let Some(writer) = self.writer.take()
        {
            let mut encoder = gif::Encoder::new(writer, w, h, &[]).map_err(bad)?;
            encoder.set_repeat(gif::Repeat::Infinite).map_err(bad)?;
            self.encoder = Some(encoder);
        }
        let Some(encoder) = self.encoder.as_mut() else {
            return Err(Error::Input(format!(
                "{}: GIF already finished",
                self.path.display()
            )));
        };
        let mut gif_frame = gif::Frame::from_rgb_speed(w, h, frame.as_raw(), 10);
        gif_frame.delay = self.delay;
        gif_frame.dispose = gif::DisposalMethod::Background;
        encoder.write_frame(&gif_frame).map_err(bad)
    }

    /// Writes the GIF's trailer and flushes the file; an error (a full disk) is
    /// returned rather than lost.
    pub fn finish(mut self) -> Result<(), Error> {
        let Some(encoder) = self.encoder.take() else {
            return Err(Error::Input(format!(
                "{}: a GIF needs at least one frame",
                self.path.display()
            )));
        };
        let writer = encoder.into_inner().map_err(|e| {
            Error::Input(format!("{}: cannot encode GIF: {e}", self.path.display()))
        })?;
        writer
            .into_inner()
            .map_err(|e| Error::io(&self.path, e.into_error()))?;
        Ok(())
    }
}
