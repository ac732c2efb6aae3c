//! Writing rendered frames: 8-bit PNG or float32 `.npy`, atomically.

use std::path::Path;

use maaf_autodiff::Tensor;

use npyz::WriterBuilder;

/// Errors of [`save_image`]; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The extension is neither `.png` nor `.npy`.
    #[error("{path}: unsupported output extension (use .png or .npy)")]
    Extension {
        /// Offending path.
        path: String,
    },
    /// Encoding or writing failed.
    #[error("{path}: {message}")]
    Write {
        /// File that failed.
        path: String,
        /// What went wrong.
        message: String,
    },
}

/// Quantises a linear `[H,W,3]` image to 8 bits: `round(255 clamp(v, 0, 1))`
/// (3DGS renders are compared with 8-bit images without any transfer function).
pub fn to_rgb8(image: &Tensor<f32>) -> Vec<u8> {
    image
        .data()
        .iter()
        .map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect()
}

/// Saves an `[H,W,3]` image: `.png` as 8-bit RGB ([`to_rgb8`]), `.npy` as float32
/// `[H,W,3]` linear colour before quantisation. Written to a temporary file and
/// renamed.
pub fn save_image(path: &Path, image: &Tensor<f32>) -> Result<(), OutputError> {
    let shown = path.display().to_string();
    let err = |message: String| OutputError::Write {
        path: shown.clone(),
        message,
    };
    let shape = image.shape();
    assert!(
        shape.len() == 3 && shape[2] == 3,
        "save_image: image must be [H,W,3], got {shape:?}"
    );
    let (h, w) = (shape[0], shape[1]);
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let bytes = match ext.as_deref() {
        Some("png") => {
            let buf = image::RgbImage::from_raw(w as u32, h as u32, to_rgb8(image))
                .ok_or_else(|| err("image buffer size mismatch".into()))?;
            let mut out = std::io::Cursor::new(Vec::new());
            buf.write_to(&mut out, image::ImageFormat::Png)
                .map_err(|e| err(format!("PNG encoding failed: {e}")))?;
            out.into_inner()
        }
        Some("npy") => {
            let mut out = Vec::new();
            let mut writer = npyz::WriteOptions::<f32>::new()
                .default_dtype()
                .shape(&[h as u64, w as u64, 3])
                .writer(&mut out)
                .begin_nd()
                .map_err(|e| err(format!("NPY encoding failed: {e}")))?;
            writer
                .extend(image.data().iter().copied())
                .and_then(|()| writer.finish())
                .map_err(|e| err(format!("NPY encoding failed: {e}")))?;
            out
        }
        _ => return Err(OutputError::Extension { path: shown }),
    };
    maaf_io::write_atomic(path, &bytes).map_err(|e| err(e.to_string()))
}
