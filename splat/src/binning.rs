//! Tile binning and the per-tile depth sort of the rasterizer (not differentiable).
//!
//! The image is cut into 16x16 tiles. Every visible Gaussian is listed in each tile
//! its pixel box (the bounding box of its support ellipse) touches; each tile's list
//! is sorted front to back by `(depth, index)`. Per row of each box, the columns the
//! ellipse can cover are solved once here and shared by the forward and backward
//! blend loops of every tile.

use maaf_autodiff::Float;
use rayon::prelude::*;

use crate::project::pixel_range;
use crate::rasterize::{SUPPORT_POWER, TILE};

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
    /// Per Gaussian: where its rows start in `row_spans` (one entry per box row).
    pub span_offsets: Vec<usize>,
    /// Per box row of each Gaussian: the inclusive columns `[lo, hi]` whose pixel
    /// centres can lie in the support ellipse (`lo > hi` when none), see
    /// [`RowSpans`].
    pub row_spans: Vec<[u32; 2]>,
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

    /// The row spans of Gaussian `g`, one per row of its box.
    pub fn spans(&self, g: usize) -> &[[u32; 2]] {
        let [_, _, yl, yh] = self.boxes[g];
        let rows = (yh + 1).saturating_sub(yl) as usize;
        &self.row_spans[self.span_offsets[g]..self.span_offsets[g] + rows]
    }
}

/// Per row of a Gaussian's box, the columns whose pixel centres can lie in the
/// support ellipse `power = (A dx^2 + C dy^2)/2 + B dx dy <= P`. For a fixed `dy`
/// this is the interval `dx = (-B dy +- sqrt(D)) / A` with
/// `D = (B^2 - A C) dy^2 + 2 A P`, empty when `D < 0`. Solved in f64 with
/// `P =` [`support_limit`] slightly above 4.5, so each interval is a superset of the
/// pixels the f32 lane test accepts, and the lane test still decides. Walking these
/// intervals instead of whole box rows skips the box corners, and most of the box
/// of a thin tilted splat.
struct RowSpans {
    mx: f64,
    my: f64,
    /// `B / A`.
    b_a: f64,
    /// `1 / A`.
    inv_a: f64,
    /// `B^2 - A C`.
    disc: f64,
    /// `2 A P`.
    lim: f64,
}

/// `4.5` plus a bound on the f32 rounding of `power` in the blend lanes, for mean
/// `(mx, my)`, conic `(a, b, c)` and pixel box `bbox`. The lanes compute
/// `dx = (x + 0.5) - mx` (exact up to one rounding of the small result) and then
/// `power` in six operations, so the error is a few ulps of the sum of the absolute
/// terms `S = (A dx^2 + C dy^2)/2 + |B dx dy|`, bounded over the box; the bound
/// used is `4e-6 (1 + S)`, about ten times that. `S` is large only for splats that
/// are thin and tilted (terms that cancel).
pub(crate) fn support_limit(mx: f64, my: f64, [a, b, c]: [f64; 3], bbox: [u32; 4]) -> f64 {
    let [xl, xh, yl, yh] = bbox.map(f64::from);
    let rx = (xl + 0.5 - mx).abs().max((xh + 0.5 - mx).abs());
    let ry = (yl + 0.5 - my).abs().max((yh + 0.5 - my).abs());
    let terms = 0.5 * (a.abs() * rx * rx + c.abs() * ry * ry) + b.abs() * rx * ry;
    SUPPORT_POWER + 4e-6 * (1.0 + terms)
}

impl RowSpans {
    /// For mean `(mx, my)`, conic `(a, b, c)` and pixel box `bbox`; `None` when the
    /// conic is not positive in `x` (no ellipse: whole box rows are walked).
    fn new(mx: f64, my: f64, [a, b, c]: [f64; 3], bbox: [u32; 4]) -> Option<Self> {
        if a.is_nan() || a <= 0.0 {
            return None;
        }
        let p = support_limit(mx, my, [a, b, c], bbox);
        Some(RowSpans {
            mx,
            my,
            b_a: b / a,
            inv_a: 1.0 / a,
            disc: b * b - a * c,
            lim: 2.0 * a * p,
        })
    }

    /// Columns `[lo, hi]` of row `y` whose centres `x + 0.5` can be in the support,
    /// intersected with `[x_lo, x_hi]` (`lo > hi` when empty).
    fn cols(&self, y: u32, x_lo: u32, x_hi: u32) -> [u32; 2] {
        let dy = f64::from(y) + 0.5 - self.my;
        let d = self.disc * dy * dy + self.lim;
        if d.is_nan() || d < 0.0 {
            return [1, 0];
        }
        let (centre, half) = (self.mx - self.b_a * dy - 0.5, d.sqrt() * self.inv_a);
        let lo = (centre - half).max(f64::from(x_lo));
        let hi = (centre + half).min(f64::from(x_hi));
        if lo > hi {
            return [1, 0];
        }
        // ceil and floor of non-negative values by truncation (libm's are calls on
        // baseline x86-64).
        let (tl, th) = (lo as u32, hi as u32);
        [tl + u32::from(f64::from(tl) < lo), th]
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
/// The box of a Gaussian is the bounding box of its support ellipse `power <= 4.5`,
/// i.e. half-extents `3 sqrt(Sigma_xx)` and `3 sqrt(Sigma_yy)` of the dilated 2D
/// covariance `Sigma = conic^-1` (like gsplat's per-axis radius), capped by the
/// isotropic 3DGS `radius`; a 1e-4 relative margin absorbs rounding so that no pixel
/// with `power <= 4.5` is ever left out. Flat splats seen edge-on touch far fewer
/// tiles than with the isotropic radius.
pub fn bin_gaussians<T: Float>(
    means2d: &[T],
    conics: &[T],
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
            if r > 0.0 {
                let (a, b, c) = (
                    Float::to_f64(conics[3 * i]),
                    Float::to_f64(conics[3 * i + 1]),
                    Float::to_f64(conics[3 * i + 2]),
                );
                let det = a * c - b * b;
                let ext = |v: f64| {
                    let e = (9.0 * v / det).sqrt() * (1.0 + 1e-4) + 1e-4;
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
    let (span_offsets, row_spans) = row_spans(means2d, conics, &boxes);
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
        span_offsets,
        row_spans,
    }
}

/// [`Binning::span_offsets`] and [`Binning::row_spans`] for the boxes.
fn row_spans<T: Float>(
    means2d: &[T],
    conics: &[T],
    boxes: &[Option<[u32; 4]>],
) -> (Vec<usize>, Vec<[u32; 2]>) {
    let rows = |b: &Option<[u32; 4]>| b.map_or(0, |[_, _, yl, yh]| (yh - yl + 1) as usize);
    let mut offsets = Vec::with_capacity(boxes.len());
    let mut total = 0;
    for b in boxes {
        offsets.push(total);
        total += rows(b);
    }
    let mut spans = vec![[1u32, 0]; total];
    let mut chunks: Vec<(usize, &mut [[u32; 2]])> = Vec::with_capacity(boxes.len());
    let mut rest = spans.as_mut_slice();
    for (i, b) in boxes.iter().enumerate() {
        let (head, tail) = rest.split_at_mut(rows(b));
        chunks.push((i, head));
        rest = tail;
    }
    chunks.into_par_iter().for_each(|(i, out)| {
        let Some(bbox) = boxes[i] else { return };
        let [xl, xh, yl, _] = bbox;
        let f = |v: T| Float::to_f64(v);
        let conic = [f(conics[3 * i]), f(conics[3 * i + 1]), f(conics[3 * i + 2])];
        let spans = RowSpans::new(f(means2d[2 * i]), f(means2d[2 * i + 1]), conic, bbox);
        for (r, s) in out.iter_mut().enumerate() {
            let y = yl + r as u32;
            *s = spans.as_ref().map_or([xl, xh], |sp| sp.cols(y, xl, xh));
        }
    });
    (offsets, spans)
}
