//! Tile binning and the per-tile depth sort of the rasterizer (not differentiable).
//!
//! The image is cut into 16x16 tiles. Every visible Gaussian is listed in each tile
//! its pixel box (the bounding box of its opacity-dependent support ellipse) touches;
//! each tile's list is sorted front to back by `(depth, index)`.

use maaf_autodiff::Float;
use rayon::prelude::*;

use crate::compositing::{TILE, support_power};
use crate::project::pixel_range;

/// Per-tile sorted Gaussian lists: tile `t` holds `ids[offsets[t]..offsets[t+1]]`.
#[derive(Clone, Debug, Default)]
pub struct Binning {
    /// Tiles along x.
    pub tiles_x: usize,
    /// Tiles along y.
    pub tiles_y: usize,
    /// Start of each tile's list in `ids` (length `tiles + 1`).
    pub offsets: Vec<usize>,
    /// Gaussian indices, each tile's run sorted front to back by `(depth, index)`.
    pub ids: Vec<u32>,
    /// Per Gaussian: inclusive pixel box `[x_lo, x_hi, y_lo, y_hi]` of its support
    /// ellipse in the image (`x_lo > x_hi` when not listed in any tile).
    pub boxes: Vec<[u32; 4]>,
}

impl Binning {
    /// Number of tile-Gaussian pairs.
    pub fn intersections(&self) -> usize {
        self.ids.len()
    }

    /// The sorted list of tile `t`.
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.ids[self.offsets[t]..self.offsets[t + 1]]
    }
}

/// Inclusive pixel box `[x_lo, x_hi, y_lo, y_hi]` of the pixel centres within
/// half-extents `(rx, ry)` of `(mx, my)`, clamped to the image, or `None`.
fn pixel_box(mx: f64, my: f64, rx: f64, ry: f64, w: u32, h: u32) -> Option<[u32; 4]> {
    let (xl, xh) = pixel_range(mx, rx, w)?;
    let (yl, yh) = pixel_range(my, ry, h)?;
    Some([xl, xh, yl, yh])
}

/// Bins visible Gaussians (`radius > 0`) into 16x16 tiles and sorts each tile's list
/// by `(depth as f32, index)`; not differentiable.
///
/// The box of a Gaussian is the bounding box of its support ellipse
/// `power <= P = ln(255 o)` ([`support_power`]: where its alpha reaches 1/255), i.e.
/// half-extents `sqrt(2 P Sigma_xx)` and `sqrt(2 P Sigma_yy)` of the dilated 2D
/// covariance `Sigma = conic^-1` (gsplat's opacity-aware per-axis radius), capped by
/// the isotropic `radius`; a 1e-4 relative and 1e-3 px margin absorbs rounding so
/// that no pixel in the support is ever left out. Gaussians with `o <= 1/255` have no
/// support and are not listed.
pub fn bin_gaussians<T: Float>(
    means2d: &[T],
    conics: &[T],
    opacity: &[T],
    radii: &[T],
    depths: &[T],
    width: u32,
    height: u32,
) -> Binning {
    let tiles_x = (width as usize).div_ceil(TILE);
    let tiles_y = (height as usize).div_ceil(TILE);
    let n = radii.len();
    let boxes: Vec<Option<[u32; 4]>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let r = Float::to_f64(radii[i]);
            let p = support_power(Float::to_f64(opacity[i]));
            if r > 0.0 && p >= 0.0 {
                let (a, b, c) = (
                    Float::to_f64(conics[3 * i]),
                    Float::to_f64(conics[3 * i + 1]),
                    Float::to_f64(conics[3 * i + 2]),
                );
                let det = a * c - b * b;
                let ext = |v: f64| {
                    let e = (2.0 * p * v / det).sqrt() * (1.0 + 1e-4) + 1e-3;
                    if e.is_finite() && det > 0.0 {
                        e.min(r)
                    } else {
                        r
                    }
                };
                pixel_box(
                    Float::to_f64(means2d[2 * i]),
                    Float::to_f64(means2d[2 * i + 1]),
                    ext(c),
                    ext(a),
                    width,
                    height,
                )
            } else {
                None
            }
        })
        .collect();
    let rects: Vec<Option<(usize, usize, usize, usize)>> = boxes
        .iter()
        .map(|b| {
            b.map(|[xl, xh, yl, yh]| {
                let t = |v: u32| v as usize / TILE;
                (t(xl), t(xh), t(yl), t(yh))
            })
        })
        .collect();
    let mut counts = vec![0usize; tiles_x * tiles_y + 1];
    for (x0, x1, y0, y1) in rects.iter().flatten() {
        for ty in *y0..=*y1 {
            for c in &mut counts[ty * tiles_x + x0..=ty * tiles_x + x1] {
                *c += 1;
            }
        }
    }
    let mut offsets = vec![0usize; tiles_x * tiles_y + 1];
    for t in 0..tiles_x * tiles_y {
        offsets[t + 1] = offsets[t] + counts[t];
    }
    let mut cursor = offsets.clone();
    let mut ids = vec![0u32; offsets[tiles_x * tiles_y]];
    for (i, rect) in rects.iter().enumerate() {
        if let Some((x0, x1, y0, y1)) = *rect {
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    let t = ty * tiles_x + tx;
                    ids[cursor[t]] = i as u32;
                    cursor[t] += 1;
                }
            }
        }
    }
    // Depths of visible Gaussians are > near > 0, so their f32 bit patterns order
    // like the values; the index in the low bits breaks ties and makes keys unique.
    let key =
        |g: u32| ((Float::to_f64(depths[g as usize]) as f32).to_bits() as u64) << 32 | g as u64;
    let mut slices: Vec<&mut [u32]> = Vec::with_capacity(tiles_x * tiles_y);
    let mut rest = ids.as_mut_slice();
    for t in 0..tiles_x * tiles_y {
        let (head, tail) = rest.split_at_mut(counts[t]);
        slices.push(head);
        rest = tail;
    }
    slices.par_iter_mut().for_each(|s| {
        let mut keyed: Vec<u64> = s.iter().map(|&g| key(g)).collect();
        keyed.sort_unstable();
        for (d, k) in s.iter_mut().zip(keyed) {
            *d = k as u32;
        }
    });
    Binning {
        tiles_x,
        tiles_y,
        offsets,
        ids,
        boxes: boxes
            .into_iter()
            .map(|b| b.unwrap_or([1, 0, 1, 0]))
            .collect(),
    }
}
