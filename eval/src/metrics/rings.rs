//! Squared error by distance from the object silhouette, the partition of the paper's
//! supplementary table "Where the zoom-out error reduction comes from"
//! (`tab:supp_region`): which share of one method's error reduction over another
//! lies on the silhouette, near it, deep inside the object or in the background.
//!
//! A pixel is *object* when its coverage `c` (the box average of the source's alpha at
//! the evaluated scale, [`maaf_data::View::coverage`]) is at least 0.5, else
//! *background*. Its distance `d` is the chessboard distance (`max(|dx|, |dy|)`, in
//! pixels) to the nearest pixel of the other kind, so `d = 1` is an 8-neighbour of the
//! silhouette. The rings:
//! - [`Ring::Edge`]: object, `d = 1` (the paper's "silhouette ring", about 1.7 % of
//!   the pixels);
//! - [`Ring::Inside`]: object, `2 <= d <= 5` ("inside band");
//! - [`Ring::Interior`]: object, `d > 5`, or no background in the view ("deep
//!   interior");
//! - [`Ring::Halo`]: background, `d <= 2` ("background halo");
//! - [`Ring::Far`]: background, `d > 2`, or no object in the view ("far background").
//!
//! The paper's "silhouette boundary band, <= 2 px on either side" is Edge, Halo and
//! the `d = 2` part of Inside. Per ring the evaluation keeps the sum of squared errors
//! over its pixels and channels ([`RingErrors`]), so the share of an error reduction
//! is a difference of two runs' sums: `(SSE_base(r) - SSE_ours(r)) / (SSE_base -
//! SSE_ours)`, the sums taken over every evaluated view
//! ([`crate::report::rings::RingSharesAt::of_sums`]).

use maaf_autodiff::{Float, Tensor};
use maaf_scene::metrics::{MetricError, masked_dims};
use serde::{Deserialize, Serialize};

/// The five rings, in [`RingErrors`] order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ring {
    /// Object pixels next to the silhouette (`d = 1`).
    Edge,
    /// Object pixels at `2 <= d <= 5`.
    Inside,
    /// Object pixels at `d > 5`.
    Interior,
    /// Background pixels at `d <= 2`.
    Halo,
    /// Background pixels at `d > 2`.
    Far,
}

impl Ring {
    /// Every ring, in [`RingErrors`] order.
    pub const ALL: [Ring; 5] = [
        Ring::Edge,
        Ring::Inside,
        Ring::Interior,
        Ring::Halo,
        Ring::Far,
    ];

    /// The row label of the reports (the paper's wording).
    pub fn label(self) -> &'static str {
        match self {
            Ring::Edge => "silhouette ring (object, d = 1 px)",
            Ring::Inside => "inside band (object, d = 2-5 px)",
            Ring::Interior => "deep interior (object, d > 5 px)",
            Ring::Halo => "background halo (d <= 2 px)",
            Ring::Far => "far background (d > 2 px)",
        }
    }
}

/// Chessboard distance of every pixel of a `width x height` mask to the nearest pixel
/// of the other kind (`object[p]` true against false), `u32::MAX` when the view has
/// only one kind. Two raster passes of the 8-neighbour chamfer with unit steps, which
/// is exact for the chessboard metric.
pub fn distance_to_other(object: &[bool], width: usize, height: usize) -> Vec<u32> {
    let inf = u32::MAX;
    let mut d: Vec<u32> = vec![inf; object.len()];
    // Seeds: the pixels with an 8-neighbour of the other kind are at distance 1.
    for y in 0..height {
        for x in 0..width {
            let me = object[y * width + x];
            let touches = (y.saturating_sub(1)..(y + 2).min(height)).any(|ny| {
                (x.saturating_sub(1)..(x + 2).min(width)).any(|nx| object[ny * width + nx] != me)
            });
            if touches {
                d[y * width + x] = 1;
            }
        }
    }
    // Within one kind, distances grow by one per step; a step never crosses the
    // silhouette (a pixel next to the other kind is already at 1).
    let relax = |d: &mut [u32], p: usize, q: usize| {
        if object[p] == object[q] && d[q] != inf && d[q] + 1 < d[p] {
            d[p] = d[q] + 1;
        }
    };
    for y in 0..height {
        for x in 0..width {
            let p = y * width + x;
            if x > 0 {
                relax(&mut d, p, p - 1);
            }
            if y > 0 {
                let up = p - width;
                relax(&mut d, p, up);
                if x > 0 {
                    relax(&mut d, p, up - 1);
                }
                if x + 1 < width {
                    relax(&mut d, p, up + 1);
                }
            }
        }
    }
    for y in (0..height).rev() {
        for x in (0..width).rev() {
            let p = y * width + x;
            if x + 1 < width {
                relax(&mut d, p, p + 1);
            }
            if y + 1 < height {
                let down = p + width;
                relax(&mut d, p, down);
                if x > 0 {
                    relax(&mut d, p, down - 1);
                }
                if x + 1 < width {
                    relax(&mut d, p, down + 1);
                }
            }
        }
    }
    d
}

/// The [`Ring`] of every pixel of a `width x height` coverage map (row-major).
pub fn silhouette_rings(coverage: &[f32], width: usize, height: usize) -> Vec<Ring> {
    let object: Vec<bool> = coverage.iter().map(|&c| c >= 0.5).collect();
    let d = distance_to_other(&object, width, height);
    object
        .iter()
        .zip(&d)
        .map(|(&o, &d)| match (o, d) {
            (true, 1) => Ring::Edge,
            (true, 2..=5) => Ring::Inside,
            (true, _) => Ring::Interior,
            (false, 0..=2) => Ring::Halo,
            (false, _) => Ring::Far,
        })
        .collect()
}

/// Pixels and summed squared error (over the pixels and channels) of each ring, in
/// [`Ring::ALL`] order, summed over the views added.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RingErrors {
    /// Pixels per ring.
    pub pixels: [u64; 5],
    /// Sum of `(render - gt)^2` over each ring's pixels and channels.
    pub sse: [f64; 5],
}

impl RingErrors {
    /// The errors of one view: `render` against `gt` (`[H, W, C]`, values in \[0, 1])
    /// with the `[H, W]` coverage `coverage`.
    pub fn of_view<T: Float>(
        render: &Tensor<T>,
        gt: &Tensor<T>,
        coverage: &[f32],
    ) -> Result<Self, MetricError> {
        let (h, w, c) = masked_dims(render, gt, coverage)?;
        let mut out = RingErrors::default();
        let pixels = render.data().chunks_exact(c).zip(gt.data().chunks_exact(c));
        for (ring, (r, g)) in silhouette_rings(coverage, w, h).into_iter().zip(pixels) {
            let k = ring as usize;
            out.pixels[k] += 1;
            out.sse[k] += r
                .iter()
                .zip(g)
                .map(|(&r, &g)| (r.to_f64() - g.to_f64()).powi(2))
                .sum::<f64>();
        }
        Ok(out)
    }

    /// The sums of `self` and `other` (another view).
    pub fn add(&mut self, other: &RingErrors) {
        for k in 0..5 {
            self.pixels[k] += other.pixels[k];
            self.sse[k] += other.sse[k];
        }
    }

    /// The sums over `views` (`None` when there are none).
    pub fn total(views: impl Iterator<Item = RingErrors>) -> Option<Self> {
        views.reduce(|mut acc, v| {
            acc.add(&v);
            acc
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Chessboard distance by brute force: every pixel against every pixel of the
    /// other kind.
    fn distance_by_search(object: &[bool], w: usize, h: usize) -> Vec<u32> {
        (0..w * h)
            .map(|p| {
                let (px, py) = ((p % w) as i64, (p / w) as i64);
                (0..w * h)
                    .filter(|&q| object[q] != object[p])
                    .map(|q| {
                        let (qx, qy) = ((q % w) as i64, (q / w) as i64);
                        (px - qx).abs().max((py - qy).abs()) as u32
                    })
                    .min()
                    .unwrap_or(u32::MAX)
            })
            .collect()
    }

    #[test]
    fn the_two_pass_distance_equals_the_search_on_random_masks() {
        // Blobs of random density (a fixed LCG), odd sizes, and the one-kind cases.
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f64 / (1u64 << 31) as f64
        };
        for (w, h, density) in [(13, 9, 0.5), (20, 17, 0.1), (7, 23, 0.9), (16, 16, 0.02)] {
            let object: Vec<bool> = (0..w * h).map(|_| next() < density).collect();
            assert_eq!(
                distance_to_other(&object, w, h),
                distance_by_search(&object, w, h),
                "{w}x{h} at density {density}"
            );
        }
        for kind in [true, false] {
            assert!(
                distance_to_other(&[kind; 12], 4, 3)
                    .iter()
                    .all(|&d| d == u32::MAX)
            );
        }
    }

    #[test]
    fn rings_of_a_square_by_hand() {
        // A 14x14 object square at (3..17, 3..17) in 20x20: edge is its outer ring of
        // 52, inside its next four rings (44 + 36 + 28 + 20), interior the 4x4 core;
        // the halo is the two rings around it (60 + 68) and the rest is far.
        let (w, h) = (20, 20);
        let cov: Vec<f32> = (0..w * h)
            .map(|p| {
                let (x, y) = (p % w, p / w);
                if (3..17).contains(&x) && (3..17).contains(&y) {
                    0.8
                } else {
                    0.1
                }
            })
            .collect();
        let rings = silhouette_rings(&cov, w, h);
        let count = |r: Ring| rings.iter().filter(|&&x| x == r).count();
        assert_eq!(count(Ring::Edge), 52);
        assert_eq!(count(Ring::Inside), 44 + 36 + 28 + 20);
        assert_eq!(count(Ring::Interior), 16);
        assert_eq!(count(Ring::Halo), 60 + 68);
        assert_eq!(count(Ring::Far), 400 - 196 - 128);
        assert_eq!(rings[0], Ring::Far);
        assert_eq!(rings[2 * w + 2], Ring::Halo);
        assert_eq!(rings[3 * w + 3], Ring::Edge);
        assert_eq!(rings[10 * w + 10], Ring::Interior);
    }

    #[test]
    fn errors_add_up_per_ring_and_over_views() {
        // 8x8, the left half object; the render is off by 0.5 in channel 0 of pixel
        // (0, 0) (object, d = 4) and by 0.1 in both channels of pixel (4, 0)
        // (background next to the silhouette).
        let (w, h, c) = (8, 8, 2);
        let cov: Vec<f32> = (0..w * h)
            .map(|p| if p % w < 4 { 1.0 } else { 0.0 })
            .collect();
        let gt = Tensor::<f64>::zeros(&[h, w, c]);
        let mut render = gt.clone();
        render.data_mut()[0] = 0.5;
        render.data_mut()[4 * c] = 0.1;
        render.data_mut()[4 * c + 1] = 0.1;
        let e = RingErrors::of_view(&render, &gt, &cov).expect("rings");
        // A coverage of another size, or images of two shapes, are refused.
        assert!(matches!(
            RingErrors::of_view(&render, &gt, &cov[..60]),
            Err(MetricError::NotAnImage { .. })
        ));
        let other = Tensor::<f64>::zeros(&[h, w - 1, c]);
        assert!(matches!(
            RingErrors::of_view(&render, &other, &cov),
            Err(MetricError::ShapeMismatch { .. })
        ));
        // Object columns 0..4: x = 3 edge, x = 0..3 inside (d = 4, 3, 2); the
        // background columns 4, 5 halo, 6, 7 far.
        assert_eq!(e.pixels, [8, 24, 0, 16, 16]);
        assert_eq!(e.sse, [0.0, 0.25, 0.0, 0.1f64.powi(2) * 2.0, 0.0]);
        let mut two = e;
        two.add(&e);
        assert_eq!(two.pixels, [16, 48, 0, 32, 32]);
        assert_eq!(RingErrors::total([e, e].into_iter()), Some(two));
    }
}
