//! Moving pixels of a fixed camera's video by background subtraction against its
//! temporal median, for test cameras that ship no masks (the CMU Panoptic test
//! cameras of [`super::dynamic3dgs`]).
//!
//! For a camera with frames `I_1 .. I_F` (8-bit RGB), the background is the per-pixel,
//! per-channel median `B = median_j I_j` (the lower median for even `F`): a pixel
//! shows the static scene whenever movers cover it in fewer than half of the frames.
//! Frame `j`'s mask is `1` where `max_c |I_j(p, c) - B(p, c)| > tau` and `0`
//! elsewhere, with `tau` = [`MEDIAN_THRESHOLD`] (25 of 255). The evaluation then
//! box-averages the mask to its scale, the same coverage the generator's exact masks
//! give (`maaf_eval::metrics::regions`).
//!
//! Limits: a mover that stays in place for half of the sequence or longer becomes
//! background; a mover coloured like the background behind it within `tau` is missed
//! (the test on generated scenes measures both against the exact masks).

use std::path::Path;

use rayon::prelude::*;

use super::error::DataError;

/// Difference to the median, in 8-bit levels, above which a pixel is moving (25 of
/// 255, about 10 %: above JPEG noise and the sensor's frame-to-frame flicker).
pub const MEDIAN_THRESHOLD: u8 = 25;

/// An 8-bit RGB frame, `[H, W, 3]` row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb8 {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 W H` bytes.
    pub data: Vec<u8>,
}

/// Decodes an image file to 8-bit RGB (alpha dropped).
pub fn decode_rgb8(path: &Path) -> Result<Rgb8, DataError> {
    let img = image::ImageReader::open(path)
        .map_err(|e| DataError::io(path, "cannot open image", e))?
        .with_guessed_format()
        .map_err(|e| DataError::io(path, "cannot read image", e))?
        .decode()
        .map_err(|e| DataError::Image {
            path: path.display().to_string(),
            message: format!("image does not decode: {e}"),
        })?
        .to_rgb8();
    let (width, height) = img.dimensions();
    Ok(Rgb8 {
        width,
        height,
        data: img.into_raw(),
    })
}

/// The per-pixel, per-channel temporal median of equally sized frames (the lower
/// median, element `(F - 1) / 2` of the sorted values, for even `F`); `None` when
/// there are no frames or their sizes differ.
pub fn temporal_median(frames: &[Rgb8]) -> Option<Rgb8> {
    let first = frames.first()?;
    if frames
        .iter()
        .any(|f| (f.width, f.height) != (first.width, first.height))
    {
        return None;
    }
    let mid = (frames.len() - 1) / 2;
    let mut data = vec![0u8; first.data.len()];
    data.par_chunks_mut(4096)
        .enumerate()
        .for_each(|(block, out)| {
            let mut values = Vec::with_capacity(frames.len());
            for (o, v) in out.iter_mut().enumerate() {
                let i = block * 4096 + o;
                values.clear();
                values.extend(frames.iter().map(|f| f.data[i]));
                *v = *values.select_nth_unstable(mid).1;
            }
        });
    Some(Rgb8 {
        width: first.width,
        height: first.height,
        data,
    })
}

/// The moving mask of `frame` against the background `median`: one value per pixel,
/// `1` where some channel differs by more than `threshold` levels, else `0`; `None`
/// when the sizes differ.
pub fn moving_mask(frame: &Rgb8, median: &Rgb8, threshold: u8) -> Option<Vec<f32>> {
    if (frame.width, frame.height) != (median.width, median.height) {
        return None;
    }
    Some(
        frame
            .data
            .chunks_exact(3)
            .zip(median.data.chunks_exact(3))
            .map(|(p, b)| {
                let moving = p.iter().zip(b).any(|(&x, &y)| x.abs_diff(y) > threshold);
                f32::from(u8::from(moving))
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(values: &[[u8; 3]]) -> Rgb8 {
        Rgb8 {
            width: values.len() as u32,
            height: 1,
            data: values.iter().flatten().copied().collect(),
        }
    }

    #[test]
    fn median_is_the_middle_value_per_channel() {
        let frames = [
            frame(&[[10, 0, 200], [1, 1, 1]]),
            frame(&[[30, 5, 100], [9, 9, 9]]),
            frame(&[[20, 9, 0], [5, 5, 5]]),
        ];
        let m = temporal_median(&frames).expect("same sizes");
        assert_eq!(m.data, vec![20, 5, 100, 5, 5, 5]);
        // Even count: the lower median.
        let m = temporal_median(&frames[..2]).expect("same sizes");
        assert_eq!(m.data, vec![10, 0, 100, 1, 1, 1]);
    }

    #[test]
    fn mask_marks_pixels_beyond_the_threshold_in_any_channel() {
        let bg = frame(&[[100, 100, 100]; 4]);
        let f = frame(&[[100, 100, 100], [125, 100, 100], [100, 100, 126], [0, 0, 0]]);
        let m = moving_mask(&f, &bg, 25).expect("same size");
        assert_eq!(m, vec![0.0, 0.0, 1.0, 1.0]);
        assert!(moving_mask(&frame(&[[0, 0, 0]]), &bg, 25).is_none());
    }
}
