//! The moving-pixel masks of [`Dataset::moving_mask`]: coverage files read as they
//! are, or background subtraction against a test camera's temporal median (computed
//! once per camera and cached), then box-downsampled to the evaluated scale.

use std::path::Path;
use std::sync::Arc;

use maaf_splat::Camera;
use rayon::prelude::*;

use super::Dataset;
use crate::dnerf::Split;
use crate::downsample::box_downsample;
use crate::error::DataError;
use crate::image::{Image, decode_rgba};
use crate::median_mask::{MEDIAN_THRESHOLD, Rgb8, decode_rgb8, moving_mask, temporal_median};

/// A coverage file (grey, first channel) at the camera's size, as `[H, W, 1]`.
pub(super) fn read_coverage(path: &Path, camera: &Camera) -> Result<Image, DataError> {
    let full = decode_rgba(path)?;
    if (full.width, full.height) != (camera.width, camera.height) {
        return Err(DataError::Image {
            path: path.display().to_string(),
            message: format!(
                "mask is {}x{} but the test frames are {}x{}",
                full.width, full.height, camera.width, camera.height
            ),
        });
    }
    Ok(Image {
        width: full.width,
        height: full.height,
        channels: 1,
        data: full.data.chunks_exact(4).map(|p| p[0]).collect(),
    })
}

/// The moving mask of the test image `file` of camera `group` against that camera's
/// temporal median over every test view of the group (`camera` lists each test view's
/// group), as a `[H, W, 1]` image of zeros and ones.
pub(super) fn median_coverage(
    data: &Dataset,
    group: usize,
    camera: &[usize],
    file: &Path,
) -> Result<Image, DataError> {
    let median = median_of(data, group, camera)?;
    let frame = decode_rgb8(file)?;
    let mask = moving_mask(&frame, &median, MEDIAN_THRESHOLD).ok_or_else(|| DataError::Image {
        path: file.display().to_string(),
        message: format!(
            "is {}x{} but its camera's other frames are {}x{}",
            frame.width, frame.height, median.width, median.height
        ),
    })?;
    Ok(Image {
        width: frame.width,
        height: frame.height,
        channels: 1,
        data: mask,
    })
}

/// The cached temporal median of camera `group`, computed on first use.
fn median_of(data: &Dataset, group: usize, camera: &[usize]) -> Result<Arc<Rgb8>, DataError> {
    let meta = data.split(Split::Test)?;
    if let Some(m) = data
        .medians
        .lock()
        .ok()
        .and_then(|c| c.get(&group).cloned())
    {
        return Ok(m);
    }
    let files: Vec<&Path> = meta
        .frames
        .iter()
        .zip(camera)
        .filter(|(_, g)| **g == group)
        .map(|(f, _)| f.file.as_path())
        .collect();
    let frames: Vec<Rgb8> = files
        .par_iter()
        .map(|f| decode_rgb8(f))
        .collect::<Result<_, _>>()?;
    let median = Arc::new(temporal_median(&frames).ok_or_else(|| {
        DataError::request(
            &meta.json,
            format!("test camera {group}: its frames are missing or differ in size"),
        )
    })?);
    if let Ok(mut cache) = data.medians.lock() {
        cache.insert(group, Arc::clone(&median));
    }
    Ok(median)
}

/// A full-size `[H, W, 1]` coverage box-averaged by the factor `k` (`scale` and `file`
/// name the request in errors).
pub(super) fn downsample_coverage(
    full: Image,
    k: u32,
    scale: f64,
    file: &Path,
) -> Result<Option<Image>, DataError> {
    let (w, h) = (full.width as usize, full.height as usize);
    let data = box_downsample(&full.data, w, h, 1, k as usize).ok_or_else(|| DataError::Scale {
        path: file.display().to_string(),
        scale,
        message: format!("factor {k} does not divide {w}x{h}"),
    })?;
    Ok(Some(Image {
        width: full.width / k,
        height: full.height / k,
        channels: 1,
        data,
    }))
}
