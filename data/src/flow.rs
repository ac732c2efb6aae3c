//! Forward optical flow files of the `video` split.
//!
//! In memory a flow is an [`Image`] with 3 channels: for the pixel whose centre is
//! `(x + 0.5, y + 0.5)` in frame `t`, channels 0 and 1 are the displacement `(dx, dy)` in
//! pixels to where the same surface point is in frame `t + 1`, and channel 2 is `1` when
//! that point is visible in frame `t + 1` (not occluded, inside the image) and `0`
//! otherwise. Pixels that see no geometry (the background colour) have flow `0` and are
//! valid when they still see none, since the background does not move.
//!
//! On disk it uses the KITTI flow format: a 16-bit RGB PNG with
//! `R = dx * 64 + 2^15`, `G = dy * 64 + 2^15` (rounded) and `B = valid`. Steps are 1/64
//! pixel (error at most 1/128 px), the range is +-511 px (larger flows are stored as
//! invalid), and the files are a few hundred kB instead of 7.7 MB of float32 at 800x800.

use std::path::Path;

use super::downsample::box_downsample;
use super::error::DataError;
use super::image::{Image, write_png};

/// Flow quantisation: stored value = `round(flow * FLOW_SCALE) + 2^15`.
pub const FLOW_SCALE: f32 = 64.0;

/// Writes a `[H, W, 3]` flow image as a KITTI-format 16-bit PNG.
pub fn write_flow(flow: &Image, path: &Path) -> Result<(), DataError> {
    if flow.channels != 3 {
        return Err(DataError::request(
            path,
            format!("flow needs 3 channels, got {}", flow.channels),
        ));
    }
    let mut bytes = Vec::with_capacity(flow.data.len() * 2);
    for px in flow.data.chunks_exact(3) {
        let fits = px[0].abs() < 511.0 && px[1].abs() < 511.0;
        let enc = |v: f32| (v * FLOW_SCALE + 32768.0).round().clamp(0.0, 65535.0) as u16;
        let valid = u16::from(fits && px[2] >= 0.5);
        for v in [enc(px[0]), enc(px[1]), valid] {
            bytes.extend_from_slice(&v.to_ne_bytes());
        }
    }
    write_png(
        path,
        &bytes,
        flow.width,
        flow.height,
        image::ExtendedColorType::Rgb16,
        "flow PNG",
    )
}

/// Reads a KITTI-format 16-bit flow PNG into a `[H, W, 3]` flow image.
pub fn read_flow(path: &Path) -> Result<Image, DataError> {
    let reader = image::ImageReader::open(path)
        .map_err(|e| DataError::io(path, "cannot open flow", e))?
        .with_guessed_format()
        .map_err(|e| DataError::io(path, "cannot read flow", e))?;
    let img = reader.decode().map_err(|e| DataError::Image {
        path: path.display().to_string(),
        message: format!("flow PNG does not decode: {e}"),
    })?;
    if !matches!(img, image::DynamicImage::ImageRgb16(_)) {
        return Err(DataError::Image {
            path: path.display().to_string(),
            message: format!(
                "flow must be a 16-bit RGB PNG (KITTI format), got {:?}",
                img.color()
            ),
        });
    }
    let rgb = img.to_rgb16();
    let (width, height) = rgb.dimensions();
    let data = rgb
        .pixels()
        .flat_map(|p| {
            [
                (p[0] as f32 - 32768.0) / FLOW_SCALE,
                (p[1] as f32 - 32768.0) / FLOW_SCALE,
                if p[2] > 0 { 1.0 } else { 0.0 },
            ]
        })
        .collect();
    Ok(Image {
        width,
        height,
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
