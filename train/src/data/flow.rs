//! Forward optical flow files of the `video` split.
//!
//! A flow file is a NumPy `.npy` array of `float32` with shape `[H, W, 3]`: for the pixel
//! whose centre is `(x + 0.5, y + 0.5)` in frame `t`, channels 0 and 1 are the
//! displacement `(dx, dy)` in pixels to where the same surface point is in frame `t + 1`,
//! and channel 2 is `1` when that point is visible in frame `t + 1` (not occluded, inside
//! the image) and `0` otherwise. Pixels that see no geometry (the background colour) have
//! flow `0` and are valid, since the background does not move under a fixed camera.

use std::path::Path;

use super::downsample::box_downsample;
use super::error::DataError;
use super::image::Image;

/// Writes a `[H, W, 3]` flow image as a `float32` `.npy` file.
pub fn write_flow(flow: &Image, path: &Path) -> Result<(), DataError> {
    use npyz::WriterBuilder;
    use std::io::Write;
    let file = std::fs::File::create(path).map_err(|e| DataError::io(path, "cannot create", e))?;
    let mut buf = std::io::BufWriter::new(file);
    let io_err = |e: std::io::Error| DataError::io(path, "cannot write flow", e);
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[flow.height as u64, flow.width as u64, flow.channels as u64])
        .writer(&mut buf)
        .begin_nd()
        .map_err(io_err)?;
    w.extend(flow.data.iter().copied()).map_err(io_err)?;
    w.finish().map_err(io_err)?;
    buf.flush().map_err(io_err)
}

/// Reads a flow `.npy` file (`float32`, shape `[H, W, 3]`, C order).
pub fn read_flow(path: &Path) -> Result<Image, DataError> {
    let bytes = std::fs::read(path).map_err(|e| DataError::io(path, "cannot read", e))?;
    let bad = |m: String| DataError::Image {
        path: path.display().to_string(),
        message: m,
    };
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| bad(format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    if shape.len() != 3 || shape[2] != 3 || npy.order() != npyz::Order::C {
        return Err(bad(format!(
            "flow must be a C-order [H, W, 3] array, got shape {shape:?}"
        )));
    }
    let data: Vec<f32> = npy
        .into_vec::<f32>()
        .map_err(|e| bad(format!("flow must be float32: {e}")))?;
    Ok(Image {
        width: shape[1] as u32,
        height: shape[0] as u32,
        channels: 3,
        data,
    })
}

/// Flow at `1/k` of the resolution: the displacement is the block mean divided by `k`
/// (pixel units shrink with the image) and a block is valid only if all its pixels are.
/// Returns `None` when `k` does not divide the size.
pub fn downsample_flow(flow: &Image, k: u32) -> Option<Image> {
    let (w, h, k) = (flow.width as usize, flow.height as usize, k as usize);
    let mut out = box_downsample(&flow.data, w, h, 3, k)?;
    for px in out.chunks_exact_mut(3) {
        px[0] /= k as f32;
        px[1] /= k as f32;
        px[2] = if px[2] >= 1.0 - 1e-6 { 1.0 } else { 0.0 };
    }
    Some(Image {
        width: flow.width / k as u32,
        height: flow.height / k as u32,
        channels: 3,
        data: out,
    })
}
