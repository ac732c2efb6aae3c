//! [`PlaneSample`], the differentiable lookup of the six planes: the taps of one
//! trilinear (bilinear x mip level) lookup, the 2x2 box pyramid, and the op whose
//! backward is the transpose of the same taps followed by the pyramid's adjoint.

use std::sync::Arc;

use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::{Float, Tensor};
use rayon::prelude::*;

use super::{FieldQuery, KPlaneField, PLANE_AXES, PLANE_NAMES, PlaneGeom};

/// Gaussians per rayon task of the forward lookup.
pub(super) const ROWS_PER_TASK: usize = 2048;

/// Up to 8 (pyramid texel, weight) taps: 4 bilinear taps on each of two levels.
type Taps = [(usize, f64); 8];

/// One mip level of a plane's pyramid: width, height and texel offset.
#[derive(Clone, Copy, Debug)]
struct Level {
    w: usize,
    h: usize,
    offset: usize,
}

/// The levels of `g`'s pyramid, finest first.
fn levels_of(g: &PlaneGeom) -> Vec<Level> {
    (0..g.levels)
        .map(|l| {
            let (w, h) = g.dims(l);
            Level {
                w,
                h,
                offset: g.offset(l),
            }
        })
        .collect()
}

/// `x.floor()` for the texel coordinates of a lookup, without the libm call that
/// baseline x86-64 makes of `f64::floor`: exact for finite `|x| < 2^63`, and 0 for
/// NaN (which `plane_taps` then clamps exactly as it clamps `NaN.floor()`).
#[inline]
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x { t - 1.0 } else { t }
}

/// Taps of one lookup of a plane with pyramid `levels`: point (u, v) in \[0,1]^2
/// (clamped at the border), mip level `level` (clamped to the pyramid). Returns the
/// number of taps used.
fn plane_taps(levels: &[Level], u: f64, v: f64, level: f64, taps: &mut Taps) -> usize {
    let max_level = (levels.len() - 1) as f64;
    let level = if level.is_nan() {
        0.0
    } else {
        level.clamp(0.0, max_level)
    };
    let l0 = level as usize;
    let f = level - l0 as f64;
    let mut count = 0;
    let mut add_level = |lv: Level, wl: f64, count: &mut usize| {
        let x = u * lv.w as f64 - 0.5;
        let y = v * lv.h as f64 - 0.5;
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let clampi = |i: f64, n: usize| (i.max(0.0) as usize).min(n - 1);
        let (ix0, ix1) = (clampi(x0, lv.w), clampi(x0 + 1.0, lv.w));
        let (iy0, iy1) = (clampi(y0, lv.h), clampi(y0 + 1.0, lv.h));
        for (iy, wy) in [(iy0, 1.0 - fy), (iy1, fy)] {
            for (ix, wx) in [(ix0, 1.0 - fx), (ix1, fx)] {
                taps[*count] = (lv.offset + iy * lv.w + ix, wl * wx * wy);
                *count += 1;
            }
        }
    };
    add_level(levels[l0], 1.0 - f, &mut count);
    if f > 0.0 && l0 + 1 < levels.len() {
        add_level(levels[l0 + 1], f, &mut count);
    }
    count
}

/// `dst += w * src` over equal-length channel rows.
#[inline]
fn axpy<T: Float>(dst: &mut [T], w: T, src: &[T]) {
    let n = dst.len().min(src.len());
    let (dst, src) = (&mut dst[..n], &src[..n]);
    for k in 0..n {
        dst[k] += w * src[k];
    }
}

/// The (u, v, level) at which Gaussian `i` looks up plane `p`.
pub(super) fn lookup(q: &FieldQuery, i: usize, p: usize) -> (f64, f64, f64) {
    let (a, b) = PLANE_AXES[p];
    let c = &q.coords[i];
    let level = if b == 3 {
        0.0
    } else {
        q.levels[i][a].min(q.levels[i][b])
    };
    (c[a], c[b], level)
}

/// Parent -> children of the 2x2 box pyramid: calls `f(parent, child)` for the four
/// children of every texel of level `l` (l >= 1), indices into the whole pyramid.
fn for_each_child(g: &PlaneGeom, l: usize, mut f: impl FnMut(usize, usize)) {
    let (w, h) = g.dims(l);
    let (wc, hc) = g.dims(l - 1);
    let (off, offc) = (g.offset(l), g.offset(l - 1));
    for j in 0..h {
        for i in 0..w {
            for cj in [(2 * j).min(hc - 1), (2 * j + 1).min(hc - 1)] {
                for ci in [(2 * i).min(wc - 1), (2 * i + 1).min(wc - 1)] {
                    f(off + j * w + i, offc + cj * wc + ci);
                }
            }
        }
    }
}

/// Mip pyramid of a plane \[H, W, C]: level 0 is the plane, level l the 2x2 box mean
/// of level l-1 (nvdiffrast's mip construction for power-of-two textures).
pub fn build_pyramid<T: Float>(g: &PlaneGeom, plane: &[T], c: usize) -> Vec<T> {
    let mut pyr = vec![T::zero(); g.pyramid_texels() * c];
    pyr[..plane.len()].copy_from_slice(plane);
    let quarter = T::of(0.25);
    for l in 1..g.levels {
        for_each_child(g, l, |parent, child| {
            for k in 0..c {
                let v = pyr[child * c + k] * quarter;
                pyr[parent * c + k] += v;
            }
        });
    }
    pyr
}

/// Sums the six plane lookups of every Gaussian: output \[N, C]. Inputs: the six planes
/// in [`PLANE_NAMES`] order. The query is a constant of the op (detached).
pub struct PlaneSample {
    query: Arc<FieldQuery>,
    geoms: [PlaneGeom; 6],
    levels: [Vec<Level>; 6],
    channels: usize,
    /// Test-only corruption of the backward (negative control of the gradchecks).
    corrupt_backward: bool,
}

impl PlaneSample {
    /// The op for `field`'s layout and a detached `query`.
    pub fn new(field: &KPlaneField, query: Arc<FieldQuery>) -> Self {
        let geoms: [PlaneGeom; 6] = std::array::from_fn(|p| field.geom(p));
        PlaneSample {
            query,
            levels: geoms.each_ref().map(levels_of),
            geoms,
            channels: field.config.channels,
            corrupt_backward: false,
        }
    }

    /// The same op with a deliberately wrong backward (drops the second mip level's
    /// taps), for negative controls.
    #[cfg(test)]
    pub(crate) fn corrupted(mut self) -> Self {
        self.corrupt_backward = true;
        self
    }
}

impl<T: Float> Op<T> for PlaneSample {
    type Saved = ();

    fn name(&self) -> String {
        "kplane_sample".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        assert_eq!(inputs.len(), 6, "kplane_sample: needs the six planes");
        let c = self.channels;
        let n = self.query.coords.len();
        for (p, g) in self.geoms.iter().enumerate() {
            assert_eq!(
                inputs[p].shape(),
                &[g.height, g.width, c],
                "kplane_sample: plane {} has the wrong shape",
                PLANE_NAMES[p]
            );
        }
        let pyramids: Vec<Vec<T>> = (0..6)
            .into_par_iter()
            .map(|p| build_pyramid(&self.geoms[p], inputs[p].data(), c))
            .collect();
        // Blocks of rows in parallel; inside a block one plane at a time (its pyramid
        // stays in cache), so each row adds the planes' taps in plane order.
        let mut out = vec![T::zero(); n * c];
        if c > 0 {
            out.par_chunks_mut(ROWS_PER_TASK * c)
                .enumerate()
                .for_each(|(chunk, rows)| {
                    let mut taps: Taps = [(0, 0.0); 8];
                    for (p, (levels, pyr)) in self.levels.iter().zip(&pyramids).enumerate() {
                        for (r, row) in rows.chunks_exact_mut(c).enumerate() {
                            let i = chunk * ROWS_PER_TASK + r;
                            let (u, v, level) = lookup(&self.query, i, p);
                            let used = plane_taps(levels, u, v, level, &mut taps);
                            for &(texel, w) in &taps[..used] {
                                axpy(row, T::of(w), &pyr[texel * c..(texel + 1) * c]);
                            }
                        }
                    }
                });
        }
        (vec![Tensor::from_vec(out, &[n, c])], ())
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let c = self.channels;
        let g_out = ctx.grad_outputs[0].data();
        let quarter = T::of(0.25);
        // Planes in parallel: each plane's cotangent is scattered by one task, in row
        // order, so the sums do not depend on the thread count.
        (0..6)
            .into_par_iter()
            .map(|p| {
                if !ctx.needs_grad[p] {
                    return None;
                }
                let g = &self.geoms[p];
                let mut gp = vec![T::zero(); g.pyramid_texels() * c];
                let mut taps: Taps = [(0, 0.0); 8];
                for (i, gi) in g_out.chunks_exact(c).enumerate() {
                    let (u, v, level) = lookup(&self.query, i, p);
                    let mut used = plane_taps(&self.levels[p], u, v, level, &mut taps);
                    if self.corrupt_backward {
                        used = used.min(4);
                    }
                    for &(texel, w) in &taps[..used] {
                        axpy(&mut gp[texel * c..(texel + 1) * c], T::of(w), gi);
                    }
                }
                // Adjoint of the pyramid: coarsest level first, so a parent's total
                // cotangent reaches its children before they pass it further down.
                for l in (1..g.levels).rev() {
                    for_each_child(g, l, |parent, child| {
                        for k in 0..c {
                            let v = gp[parent * c + k] * quarter;
                            gp[child * c + k] += v;
                        }
                    });
                }
                gp.truncate(g.width * g.height * c);
                Some(Tensor::from_vec(gp, &[g.height, g.width, c]))
            })
            .collect()
    }
}
