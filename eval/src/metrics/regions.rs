//! PSNR by region of a view whose moving-object coverage is known (the generated
//! multi-view scenes' `cam00/masks/`): moving pixels, static pixels and the
//! silhouette band between them, as the paper's supplementary splits its results.
//!
//! With `c` the coverage at the evaluated scale (the box average of the source mask):
//! - **band**: partly covered pixels (`0.02 < c < 0.98`) and pixels whose 3x3
//!   neighbourhood (clamped at the border) holds both a pixel with `c >= 0.5` and one
//!   with `c < 0.5`;
//! - **moving**: `c >= 0.5`, not in the band;
//! - **static**: `c < 0.5`, not in the band.
//!
//! A region's PSNR is `10 log10(1 / MSE)` over its pixels and channels (data range 1);
//! a view without pixels in a region has no value there.

use maaf_autodiff::{Float, Tensor};
use maaf_scene::metrics::{MetricError, masked_dims};
use serde::{Deserialize, Serialize};

/// The three regions, in [`RegionPsnr`] order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Region {
    /// Moving-object pixels away from the silhouette.
    Moving,
    /// Static pixels away from the silhouette.
    Static,
    /// The silhouette band.
    Band,
}

/// The region of every pixel of a `width x height` coverage map (row-major).
pub fn classify(coverage: &[f32], width: usize, height: usize) -> Vec<Region> {
    let covered = |x: usize, y: usize| coverage[y * width + x] >= 0.5;
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let c = coverage[y * width + x];
            let (mut any_in, mut any_out) = (false, false);
            for ny in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                    if covered(nx, ny) {
                        any_in = true;
                    } else {
                        any_out = true;
                    }
                }
            }
            out.push(if (0.02 < c && c < 0.98) || (any_in && any_out) {
                Region::Band
            } else if c >= 0.5 {
                Region::Moving
            } else {
                Region::Static
            });
        }
    }
    out
}

/// PSNR of one view by region (`None` where the region has no pixel).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RegionPsnr {
    /// Moving pixels.
    pub moving: Option<f64>,
    /// Static pixels.
    pub static_: Option<f64>,
    /// Silhouette band.
    pub band: Option<f64>,
}

/// [`RegionPsnr`] of `render` against `gt` (`[H, W, C]`, values in \[0, 1]) with the
/// `[H, W]` coverage `coverage`.
pub fn region_psnr<T: Float>(
    render: &Tensor<T>,
    gt: &Tensor<T>,
    coverage: &[f32],
) -> Result<RegionPsnr, MetricError> {
    let (h, w, c) = masked_dims(render, gt, coverage)?;
    let regions = classify(coverage, w, h);
    let mut sum = [0.0f64; 3];
    let mut count = [0usize; 3];
    for (p, region) in regions.iter().enumerate() {
        let k = *region as usize;
        for ch in 0..c {
            let d = render.data()[p * c + ch].to_f64() - gt.data()[p * c + ch].to_f64();
            sum[k] += d * d;
        }
        count[k] += c;
    }
    let psnr = |k: usize| (count[k] > 0).then(|| -10.0 * (sum[k] / count[k] as f64).log10());
    Ok(RegionPsnr {
        moving: psnr(Region::Moving as usize),
        static_: psnr(Region::Static as usize),
        band: psnr(Region::Band as usize),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_of_a_square_and_their_psnr_by_hand() {
        // 6x6, a covered 2x2 square at (2..4, 2..4).
        let (w, h) = (6, 6);
        let mut cov = vec![0.0f32; w * h];
        for y in 2..4 {
            for x in 2..4 {
                cov[y * w + x] = 1.0;
            }
        }
        let r = classify(&cov, w, h);
        // Every covered pixel touches an uncovered one: all four are band, as is the
        // ring around them; the rest is static; nothing is moving.
        let band = r.iter().filter(|&&x| x == Region::Band).count();
        assert_eq!(band, 16);
        assert_eq!(r.iter().filter(|&&x| x == Region::Moving).count(), 0);
        assert_eq!(r[0], Region::Static);
        // A bigger square (4x4 in 8x8) has a moving core of 2x2, a band of its
        // outer ring plus the ring around it (12 + 20), and 28 static pixels.
        let mut big = vec![0.0f32; 64];
        for y in 2..6 {
            for x in 2..6 {
                big[y * 8 + x] = 1.0;
            }
        }
        let r = classify(&big, 8, 8);
        let count = |k: Region| r.iter().filter(|&&x| x == k).count();
        assert_eq!(
            (
                count(Region::Moving),
                count(Region::Band),
                count(Region::Static)
            ),
            (4, 32, 28)
        );
        assert_eq!(r[3 * 8 + 3], Region::Moving);

        // Errors: 0.1 on static pixels, 0.3 on band pixels, 0 on moving pixels.
        let gt = Tensor::<f64>::zeros(&[8, 8, 1]);
        let render = Tensor::from_vec(
            r.iter()
                .map(|x| match x {
                    Region::Static => 0.1,
                    Region::Band => 0.3,
                    Region::Moving => 0.0,
                })
                .collect(),
            &[8, 8, 1],
        );
        let p = region_psnr(&render, &gt, &big).expect("psnr");
        assert!((p.static_.expect("static") - 20.0).abs() < 1e-9);
        assert!((p.band.expect("band") - (-10.0 * 0.09f64.log10())).abs() < 1e-9);
        assert_eq!(p.moving, Some(f64::INFINITY));
        // Partial coverage is band even far from a boundary; no mask pixels, no moving.
        let half = vec![0.3f32; 36];
        assert!(classify(&half, 6, 6).iter().all(|&x| x == Region::Band));
        let none = region_psnr(&render, &gt, &[0.0; 64]).expect("psnr");
        assert_eq!((none.moving, none.band), (None, None));
        assert!(region_psnr(&render, &gt, &[0.0; 63]).is_err());
    }
}
