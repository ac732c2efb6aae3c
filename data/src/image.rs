//! A plain float image (`[H, W, C]` row-major `f32`) and PNG decoding to straight RGBA.

use std::path::Path;

use super::error::DataError;

/// A float image stored row-major as `[height, width, channels]`:
/// the value of channel `c` at pixel `(x, y)` is `data[(y * width + x) * channels + c]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Channels per pixel (3 for composited RGB, 4 for RGBA).
    pub channels: usize,
    /// `height * width * channels` values, row-major.
    pub data: Vec<f32>,
}

impl Image {
    /// The pixels as a `[H, W, C]` tensor (what the objective and the metrics take).
    pub fn to_tensor(&self) -> maaf_autodiff::Tensor<f32> {
        maaf_autodiff::Tensor::from_vec(
            self.data.clone(),
            &[self.height as usize, self.width as usize, self.channels],
        )
    }

    /// An image of the given size filled with `value`.
    pub fn filled(width: u32, height: u32, channels: usize, value: f32) -> Self {
        Image {
            width,
            height,
            channels,
            data: vec![value; width as usize * height as usize * channels],
        }
    }

    /// Number of pixels, `width * height`.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The `channels` values of pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let i = (y as usize * self.width as usize + x as usize) * self.channels;
        &self.data[i..i + self.channels]
    }
}

/// Decodes an image file (PNG, or JPEG) to straight (non-premultiplied) RGBA in `[0, 1]`:
/// 8-bit values `v` become `v / 255`, 16-bit values `v / 65535`; images without alpha get
/// `a = 1`. No gamma conversion: values stay in the file's (sRGB-encoded) space, the
/// space every D-NeRF method trains and evaluates in.
pub fn decode_rgba(path: &Path) -> Result<Image, DataError> {
    let shown = || path.display().to_string();
    let reader = image::ImageReader::open(path)
        .map_err(|e| DataError::io(path, "cannot open image", e))?
        .with_guessed_format()
        .map_err(|e| DataError::io(path, "cannot read image", e))?;
    let decoded = reader.decode().map_err(|e| DataError::Image {
        path: shown(),
        message: format!("image does not decode: {e}"),
    })?;
    let rgba = decoded.to_rgba32f();
    let (width, height) = rgba.dimensions();
    Ok(Image {
        width,
        height,
        channels: 4,
        data: rgba.into_raw(),
    })
}

/// Reads only the header of an image file and returns `(width, height)`.
pub fn image_size(path: &Path) -> Result<(u32, u32), DataError> {
    let reader = image::ImageReader::open(path)
        .map_err(|e| DataError::io(path, "cannot open image", e))?
        .with_guessed_format()
        .map_err(|e| DataError::io(path, "cannot read image", e))?;
    reader.into_dimensions().map_err(|e| DataError::Image {
        path: path.display().to_string(),
        message: format!("image header does not decode: {e}"),
    })
}

/// Encodes straight RGBA in `[0, 1]` (`[H, W, 4]`) as an 8-bit RGBA PNG, rounding
/// `round(255 v)` after clamping to `[0, 1]`. Uses fast compression.
pub fn encode_rgba_png(img: &Image, path: &Path) -> Result<(), DataError> {
    if img.channels != 4 {
        return Err(DataError::request(
            path,
            format!("PNG writer expects 4 channels, got {}", img.channels),
        ));
    }
    write_quantised_png(img, path, image::ExtendedColorType::Rgba8, "PNG")
}

/// Writes an image with values in `[0, 1]` as an 8-bit PNG of colour type `color`
/// (whose channel count is the image's), `round(255 clamp(v, 0, 1))` per value; `what`
/// names the file kind in the error.
pub(crate) fn write_quantised_png(
    img: &Image,
    path: &Path,
    color: image::ExtendedColorType,
    what: &str,
) -> Result<(), DataError> {
    let bytes: Vec<u8> = img
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    write_png(path, &bytes, img.width, img.height, color, what)
}

/// Writes raw pixel bytes as a PNG with fast compression; `what` names the file kind
/// in the error (e.g. "flow PNG").
pub(crate) fn write_png(
    path: &Path,
    bytes: &[u8],
    width: u32,
    height: u32,
    color: image::ExtendedColorType,
    what: &str,
) -> Result<(), DataError> {
    use image::ImageEncoder;
    let file = std::fs::File::create(path).map_err(|e| DataError::io(path, "cannot create", e))?;
    let encoder = image::codecs::png::PngEncoder::new_with_quality(
        std::io::BufWriter::new(file),
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Adaptive,
    );
    encoder
        .write_image(bytes, width, height, color)
        .map_err(|e| DataError::Io {
            path: path.display().to_string(),
            message: format!("cannot write {what}: {e}"),
        })
}
