//! The masks of a data set: the test views' moving-pixel masks
//! ([`Dataset::moving_mask`]: coverage files read as they are, or background
//! subtraction against a test camera's temporal median, computed once per camera and
//! cached) and the training views' foreground masks ([`Dataset::train_foreground`]),
//! box-downsampled to the scale asked for.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use maaf_splat::Camera;
use rayon::prelude::*;

use super::Dataset;
use crate::dnerf::Split;
use crate::downsample::box_downsample;
use crate::error::DataError;
use crate::image::{Image, decode_rgba};
use crate::median_mask::{MEDIAN_THRESHOLD, Rgb8, decode_rgb8, moving_mask, temporal_median};

/// Where the moving-pixel masks of the `test` views come from.
#[derive(Clone, Debug, Default)]
pub enum MaskSource {
    /// The data set has none.
    #[default]
    None,
    /// One coverage file per test view (8-bit grey, `None` where a view has none).
    Files(Vec<Option<PathBuf>>),
    /// Background subtraction against each test camera's temporal median
    /// ([`crate::median_mask`]); `camera[i]` is the camera group of test view `i`.
    TemporalMedian {
        /// Camera group of every test view.
        camera: Vec<usize>,
    },
}

impl Dataset {
    /// Moving-object coverage of `test` frame `index` at `scale` (`[H, W, 1]`, the
    /// fraction of each pixel that sees a moving object, box-averaged over the `k x k`
    /// source pixels), or `None` when the data set has no masks. Generated scenes ship
    /// exact masks (`cam00/masks/`, or `seg/` of every camera in the Dynamic 3D
    /// Gaussians layout); real Dynamic 3D Gaussians test cameras get theirs by
    /// background subtraction ([`MaskSource::TemporalMedian`]).
    pub fn moving_mask(&self, index: usize, scale: f64) -> Result<Option<Image>, DataError> {
        let k = self.factor(Split::Test, scale)?;
        let frame = self.frame(Split::Test, index)?;
        let full = match &self.masks {
            MaskSource::None => return Ok(None),
            MaskSource::Files(files) => match files.get(index) {
                Some(Some(path)) => read_coverage(path, &frame.camera)?,
                _ => return Ok(None),
            },
            MaskSource::TemporalMedian { camera } => {
                let group = camera.get(index).copied().unwrap_or(0);
                median_coverage(self, group, camera, &frame.file)?
            }
        };
        downsample_coverage(full, k, scale, &frame.file)
    }

    /// Where the test views' moving masks come from.
    pub fn mask_source(&self) -> &MaskSource {
        &self.masks
    }

    /// Foreground coverage of `train` view `index` at `scale` (`[H, W, 1]`, the
    /// fraction of each pixel its mask file calls foreground, box-averaged over the
    /// `k x k` source pixels), or `None` when the view has no mask file (only the
    /// Dynamic 3D Gaussians layout's `seg/` gives training views masks).
    pub fn train_foreground(&self, index: usize, scale: f64) -> Result<Option<Image>, DataError> {
        let k = self.factor(Split::Train, scale)?;
        let frame = self.frame(Split::Train, index)?;
        let Some(path) = self.train_mask(&frame.file) else {
            return Ok(None);
        };
        let full = read_coverage(path, &frame.camera)?;
        let binary = Image {
            data: full
                .data
                .iter()
                .map(|&v| f32::from(u8::from(v > 0.5)))
                .collect(),
            ..full
        };
        downsample_coverage(binary, k, scale, path)
    }

    /// The foreground mask file of a training image, when the data set has one.
    pub fn train_mask(&self, image: &Path) -> Option<&Path> {
        self.train_masks.get(image).map(PathBuf::as_path)
    }
}

/// A coverage file (grey, first channel) at the camera's size, as `[H, W, 1]`.
fn read_coverage(path: &Path, camera: &Camera) -> Result<Image, DataError> {
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
fn median_coverage(
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
fn downsample_coverage(
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
