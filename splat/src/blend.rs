//! The blend loop of one 16x16 tile, forward and backward, over pixel lanes
//! ([`Lanes`]: 4 consecutive pixels of a tile row for f32, one for f64).
//!
//! Each Gaussian of the tile's sorted list visits only the rows of its pixel box and,
//! in each row, only the columns where its support ellipse (`power <= 4.5`) can lie
//! ([`RowSpans`]); lane groups start at the first such column, so a splat 4 pixels
//! wide costs one group per row wherever it sits. Lanes outside the support, already
//! saturated or outside the image are masked. The per-pixel
//! operations and their order along the list are those of the textbook per-pixel loop
//! ([`crate::rasterize::Rasterize`]), so the forward and the backward make the same
//! decisions lane for lane: both evaluate alpha through [`lane_alpha`] on identical
//! inputs.

use crate::lanes::{Lanes, SplatFloat};
use crate::rasterize::{
    ALPHA_MAX, ALPHA_MIN, AlphaCutoff, SMOOTH_TAPER_START, SUPPORT_POWER, T_MIN, TILE,
};

/// Row stride of per-pixel tile state: a tile row plus room for a lane group that
/// starts at the last column (the extra columns are never live).
pub(crate) const ROW: usize = TILE + 4;

/// Per-pixel state slots of a tile, row-major with stride [`ROW`].
pub(crate) const NP: usize = TILE * ROW;

/// One Gaussian as the blend loop reads it, with its inclusive pixel box
/// `[x_lo, x_hi] x [y_lo, y_hi]` in image coordinates and, per box row, the columns
/// its support can cover ([`crate::binning::Binning::row_spans`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Splat<'a, T> {
    pub mx: T,
    pub my: T,
    pub a: T,
    pub b: T,
    pub c: T,
    pub o: T,
    pub col: [T; 3],
    pub z: T,
    pub bbox: [u32; 4],
    pub spans: &'a [[u32; 2]],
}

/// A tile: its pixel rectangle `(x0, y0, x1, y1)` (exclusive ends) in the image.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileRect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl TileRect {
    /// The part of `s`'s pixel box inside the tile as tile-local inclusive
    /// `(first row, last row, first column, last column)`, or `None`.
    fn span<T>(&self, s: &Splat<'_, T>) -> Option<(usize, usize, usize, usize)> {
        let [xl, xh, yl, yh] = s.bbox.map(|v| v as usize);
        let (lx0, lx1) = (xl.max(self.x0), xh.min(self.x1 - 1));
        let (ly0, ly1) = (yl.max(self.y0), yh.min(self.y1 - 1));
        (lx0 <= lx1 && ly0 <= ly1)
            .then(|| (ly0 - self.y0, ly1 - self.y0, lx0 - self.x0, lx1 - self.x0))
    }

    /// Image index `y * width + x` of tile-local pixel `k` (stride [`ROW`]), or
    /// `None` when `k` lies outside the image or in a row's padding.
    pub fn image_pixel(&self, k: usize, width: usize) -> Option<usize> {
        let (x, y) = (self.x0 + k % ROW, self.y0 + k / ROW);
        (x < self.x1 && y < self.y1).then_some(y * width + x)
    }
}

/// A Gaussian's parameters broadcast to every lane.
struct Wide<L> {
    mx: L,
    a: L,
    b: L,
    c: L,
    o: L,
    col: [L; 3],
    z: L,
}

impl<L> Wide<L> {
    fn of<T: Copy>(s: &Splat<'_, T>) -> Self
    where
        L: Lanes<T>,
    {
        Wide {
            mx: L::splat(s.mx),
            a: L::splat(s.a),
            b: L::splat(s.b),
            c: L::splat(s.c),
            o: L::splat(s.o),
            col: s.col.map(L::splat),
            z: L::splat(s.z),
        }
    }
}

/// Lane offsets `dx` of the pixel centres `x + 0.5` of the lane group whose first
/// pixel is image column `x`, from the mean: computed the same way in forward and
/// backward so that both see identical bits.
#[inline(always)]
fn lane_dx<T: SplatFloat>(x: usize, w: &Wide<T::L>) -> T::L {
    T::L::splat(T::of(x as f64)) + T::L::ramp() + T::L::splat(T::of(0.5)) - w.mx
}

/// `power = (A dx^2 + C dy^2)/2 + B dx dy` per lane and whether it lies in the
/// support `[0, 4.5]`; groups where no live lane is in the support are skipped
/// before the exponential.
#[inline(always)]
fn lane_power<T: SplatFloat>(
    w: &Wide<T::L>,
    dx: T::L,
    dy: T::L,
) -> (T::L, <T::L as Lanes<T>>::Mask) {
    let l = T::L::splat;
    let p = l(T::of(0.5)) * (w.a * dx * dx + w.c * dy * dy) + w.b * dx * dy;
    (p, p.ge(l(T::zero())) & p.le(l(T::of(SUPPORT_POWER))))
}

/// What [`lane_alpha`] returns per lane.
struct Alpha<L: Lanes<T>, T> {
    /// Whether the Gaussian counts at the pixel.
    ok: L::Mask,
    /// Its alpha there (meaningful where `ok`).
    alpha: L,
    /// `exp(-power)`.
    g: L,
    /// `power`.
    p: L,
}

/// `g = exp(-power)` and alpha with the [`AlphaCutoff`] rules: hard
/// `alpha = min(0.99, o g)`, counted when `0 <= power <= 4.5` and `o g >= 1/255`;
/// smooth `alpha = o g w(power)`, counted when positive.
#[inline(always)]
fn lane_alpha<T: SplatFloat>(
    cut: AlphaCutoff,
    w: &Wide<T::L>,
    p: T::L,
    in_support: <T::L as Lanes<T>>::Mask,
) -> Alpha<T::L, T> {
    let l = T::L::splat;
    let g = (-p).exp();
    match cut {
        AlphaCutoff::Hard => {
            let a = w.o * g;
            Alpha {
                ok: in_support & a.ge(l(T::of(ALPHA_MIN))),
                alpha: a.min(l(T::of(ALPHA_MAX))),
                g,
                p,
            }
        }
        AlphaCutoff::Smooth => {
            let (wt, _) = taper::<T>(p);
            let a = w.o * g * wt;
            Alpha {
                ok: in_support & a.gt(l(T::zero())),
                alpha: a,
                g,
                p,
            }
        }
    }
}

/// The C1 taper of [`AlphaCutoff::Smooth`], `w = (1 - q^2)^2` for
/// `q = (power - 2)/(4.5 - 2)` in `[0, 1]` (1 below, 0 above), and `dw/dpower`.
#[inline(always)]
fn taper<T: SplatFloat>(p: T::L) -> (T::L, T::L) {
    let l = T::L::splat;
    let span = T::of(SUPPORT_POWER - SMOOTH_TAPER_START);
    let q = (p - l(T::of(SMOOTH_TAPER_START))) / l(span);
    let s = l(T::one()) - q * q;
    let below = q.le(l(T::zero()));
    let above = q.ge(l(T::one()));
    let w = T::L::select(below, l(T::one()), T::L::select(above, l(T::zero()), s * s));
    let dw = T::L::select(
        below | above,
        l(T::zero()),
        l(T::of(-4.0)) * s * q / l(span),
    );
    (w, dw)
}

/// One lane group where the Gaussian counts at some lane: tile-local index `k` of
/// its first pixel, the offsets from the mean and alpha.
struct Group<L: Lanes<T>, T> {
    k: usize,
    dx: L,
    dy: L,
    al: Alpha<L, T>,
}

/// Walks the lane groups of `s`'s support inside `rect` (per row the columns of
/// [`Splat::spans`], lane groups from the first one) and calls `f` for each group
/// where some lane is in the support, open in `gate` (1 open, 0 closed) and counted
/// under `cut`; `f` gets the gate back to close lanes. Forward and backward both
/// walk through here, so they make the same decisions lane for lane.
#[inline(always)]
fn for_each_group<T: SplatFloat>(
    rect: TileRect,
    s: &Splat<'_, T>,
    cut: AlphaCutoff,
    gate: &mut [T],
    mut f: impl FnMut(&Wide<T::L>, Group<T::L, T>, &mut [T]),
) {
    let l = T::L::splat;
    let Some((r0, r1, c0, c1)) = rect.span(s) else {
        return;
    };
    let w = Wide::<T::L>::of(s);
    let first_row = rect.y0 + r0 - s.bbox[2] as usize;
    for (row, &[lo, hi]) in (r0..=r1).zip(&s.spans[first_row..]) {
        let lo = (lo as usize).max(rect.x0 + c0);
        let hi = (hi as usize).min(rect.x0 + c1);
        if lo > hi {
            continue;
        }
        let y = rect.y0 + row;
        let dy = l(T::of(y as f64) + T::of(0.5) - s.my);
        let mut x = lo;
        while x <= hi {
            let k = row * ROW + x - rect.x0;
            let dx = lane_dx::<T>(x, &w);
            x += T::L::N;
            let (p, in_support) = lane_power::<T>(&w, dx, dy);
            let in_support = in_support & T::L::load(&gate[k..]).gt(l(T::zero()));
            if T::L::bits(in_support) == 0 {
                continue;
            }
            let al = lane_alpha::<T>(cut, &w, p, in_support);
            if T::L::bits(al.ok) != 0 {
                f(&w, Group { k, dx, dy, al }, gate);
            }
        }
    }
}

/// Forward result of one tile, per tile pixel (stride [`ROW`]).
pub(crate) struct TileOut<T> {
    pub rgb: [Vec<T>; 3],
    pub t_final: Vec<T>,
    pub depth: Vec<T>,
    /// Index (in the tile list) of the last contributor, plus one.
    pub n: Vec<u32>,
}

/// Composites `splats` (sorted front to back) over one tile, background included.
pub(crate) fn forward_tile<T: SplatFloat>(
    splats: &[Splat<'_, T>],
    rect: TileRect,
    cut: AlphaCutoff,
    background: [T; 3],
) -> TileOut<T> {
    let l = T::L::splat;
    let (zero, one) = (T::zero(), T::one());
    let hard = cut == AlphaCutoff::Hard;
    let mut tr = vec![one; NP];
    let mut rgb = [vec![zero; NP], vec![zero; NP], vec![zero; NP]];
    let mut depth = vec![zero; NP];
    let mut n = vec![0u32; NP];
    // 1 while a pixel still takes contributions, 0 once saturated or off-image.
    let mut live: Vec<T> = (0..NP)
        .map(|k| {
            if rect.image_pixel(k, 0).is_some() {
                one
            } else {
                zero
            }
        })
        .collect();
    let mut n_live = (rect.x1 - rect.x0) * (rect.y1 - rect.y0);
    for (j, s) in splats.iter().enumerate() {
        if n_live == 0 {
            break;
        }
        for_each_group(rect, s, cut, &mut live, |w, g, live| {
            let (k, ok) = (g.k, g.al.ok);
            let t = T::L::load(&tr[k..]);
            let next = t * (l(one) - g.al.alpha);
            let blend = if hard {
                let stop = ok & next.lt(l(T::of(T_MIN)));
                let stopped = T::L::bits(stop);
                if stopped != 0 {
                    T::L::select(stop, l(zero), T::L::load(&live[k..])).store(&mut live[k..]);
                    n_live -= stopped.count_ones() as usize;
                }
                ok & !stop
            } else {
                ok
            };
            let wgt = T::L::select(blend, g.al.alpha * t, l(zero));
            for ch in 0..3 {
                (T::L::load(&rgb[ch][k..]) + w.col[ch] * wgt).store(&mut rgb[ch][k..]);
            }
            (T::L::load(&depth[k..]) + w.z * wgt).store(&mut depth[k..]);
            T::L::select(blend, next, t).store(&mut tr[k..]);
            let mut bits = T::L::bits(blend);
            while bits != 0 {
                n[k + bits.trailing_zeros() as usize] = j as u32 + 1;
                bits &= bits - 1;
            }
        });
    }
    for ch in 0..3 {
        for (v, &t) in rgb[ch].iter_mut().zip(&tr) {
            *v += t * background[ch];
        }
    }
    TileOut {
        rgb,
        t_final: tr,
        depth,
        n,
    }
}

/// Per-pixel inputs of the backward of one tile (stride [`ROW`]; off-image pixels
/// have `n_last = 0`).
pub(crate) struct TileGrads<'a, T> {
    /// Cotangent of the colour.
    pub g_rgb: [Vec<T>; 3],
    /// Cotangent of the accumulated alpha.
    pub g_alpha: Vec<T>,
    /// Cotangent of the depth.
    pub g_depth: Vec<T>,
    /// Final transmittance from the forward.
    pub t_final: &'a [T],
    /// Last contributor plus one, from the forward.
    pub n_last: &'a [u32],
}

/// Backward of [`forward_tile`]: walks each pixel back to front from its last
/// contributor, recovering `T_i = T_{i+1} / (1 - alpha_i)`, and returns one gradient
/// row per list entry: `d/d(mx, my, A, B, C, o, r, g, b, z)`.
pub(crate) fn backward_tile<T: SplatFloat>(
    splats: &[Splat<'_, T>],
    rect: TileRect,
    cut: AlphaCutoff,
    background: [T; 3],
    inp: &TileGrads<'_, T>,
) -> Vec<[T; 10]> {
    let l = T::L::splat;
    let (zero, one, half) = (T::zero(), T::one(), T::of(0.5));
    let mut grads = vec![[zero; 10]; splats.len()];
    let mut tr = inp.t_final.to_vec();
    let mut behind: [Vec<T>; 4] = [
        tr.iter().map(|&t| background[0] * t).collect(),
        tr.iter().map(|&t| background[1] * t).collect(),
        tr.iter().map(|&t| background[2] * t).collect(),
        vec![zero; NP],
    ];
    // Pixels join the walk at their last contributor: `active` turns 1 when
    // `j < n_last`. `order` lists pixels by decreasing `n_last`.
    let mut order: Vec<usize> = (0..NP).filter(|&k| inp.n_last[k] > 0).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(inp.n_last[k]));
    let mut active = [zero; NP];
    let mut next_in = 0;
    let jmax = order.first().map_or(0, |&k| inp.n_last[k] as usize);
    for j in (0..jmax).rev() {
        while next_in < order.len() && inp.n_last[order[next_in]] as usize > j {
            active[order[next_in]] = one;
            next_in += 1;
        }
        let mut acc = [l(zero); 10];
        for_each_group(rect, &splats[j], cut, &mut active, |w, g, _| {
            let Group { k, dx, dy, al } = g;
            let m = al.ok;
            let pick = |v: T::L| T::L::select(m, v, l(zero));
            let alpha = al.alpha;
            let inv = l(one) / (l(one) - alpha);
            let t_behind = T::L::load(&tr[k..]);
            let t = T::L::select(m, t_behind * inv, t_behind);
            t.store(&mut tr[k..]);
            let wgt = alpha * t;
            let gc = [0, 1, 2].map(|ch| T::L::load(&inp.g_rgb[ch][k..]));
            let gd = T::L::load(&inp.g_depth[k..]);
            let mut g_al = T::L::load(&inp.g_alpha[k..]) * T::L::load(&inp.t_final[k..]) * inv;
            for ch in 0..3 {
                acc[6 + ch] = acc[6 + ch] + pick(gc[ch] * wgt);
                let bh = T::L::load(&behind[ch][k..]);
                g_al = g_al + gc[ch] * (w.col[ch] * t - bh * inv);
                T::L::select(m, bh + w.col[ch] * wgt, bh).store(&mut behind[ch][k..]);
            }
            acc[9] = acc[9] + pick(gd * wgt);
            let bh = T::L::load(&behind[3][k..]);
            g_al = g_al + gd * (w.z * t - bh * inv);
            T::L::select(m, bh + w.z * wgt, bh).store(&mut behind[3][k..]);
            let og = w.o * al.g;
            let (g_o, g_p) = match cut {
                AlphaCutoff::Hard => {
                    // The 0.99 clamp is active: alpha does not depend on o or power.
                    let free = !og.gt(l(T::of(ALPHA_MAX)));
                    (
                        T::L::select(free, g_al * al.g, l(zero)),
                        T::L::select(free, -(g_al * og), l(zero)),
                    )
                }
                AlphaCutoff::Smooth => {
                    let (wt, dwt) = taper::<T>(al.p);
                    (g_al * al.g * wt, g_al * og * (dwt - wt))
                }
            };
            let g_p = pick(g_p);
            acc[5] = acc[5] + pick(g_o);
            acc[2] = acc[2] + g_p * l(half) * dx * dx;
            acc[3] = acc[3] + g_p * dx * dy;
            acc[4] = acc[4] + g_p * l(half) * dy * dy;
            acc[0] = acc[0] - g_p * (w.a * dx + w.b * dy);
            acc[1] = acc[1] - g_p * (w.b * dx + w.c * dy);
        });
        grads[j] = acc.map(|v| v.sum());
    }
    grads
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::binning::{bin_gaussians, support_limit};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    /// Conic of the covariance with standard deviations `(s1, s2)` along angle `th`.
    fn conic(s1: f64, s2: f64, th: f64) -> [f32; 3] {
        let (c, s) = (th.cos(), th.sin());
        let (v1, v2) = (s1 * s1, s2 * s2);
        let (xx, xy, yy) = (
            c * c * v1 + s * s * v2,
            c * s * (v1 - v2),
            s * s * v1 + c * c * v2,
        );
        let det = xx * yy - xy * xy;
        [(yy / det) as f32, (-xy / det) as f32, (xx / det) as f32]
    }

    /// Every pixel whose lane power (f32, computed by the blend loop's own
    /// `lane_dx`/`lane_power`) lies in `[0, 4.5]` is inside its row span, for round,
    /// thin, tilted and huge splats at pixel coordinates up to 8000; and the spans are
    /// tight: their end pixels have power at most the limit they were solved for
    /// ([`support_limit`], within 1e-3 of 4.5 unless the axis ratio is below 0.3), and
    /// a thin diagonal splat walks under a third of its box.
    #[test]
    fn row_spans_cover_the_support_and_are_tight() {
        let mut rng = Pcg64::seed_from_u64(5);
        let (w, h) = (8192u32, 64u32);
        let n = 400;
        let (mut m2, mut con) = (Vec::new(), Vec::new());
        for i in 0..n {
            let s1: f64 = [0.3, 1.0, 4.0, 40.0][i % 4] * rng.random_range(0.8..1.2);
            let s2: f64 = s1 * [1.0, 0.3, 0.02, 0.005][(i / 4) % 4];
            let th = rng.random_range(0.0..std::f64::consts::PI);
            m2.extend([
                rng.random_range(0.0..8000.0f32),
                rng.random_range(0.0..64.0f32),
            ]);
            con.extend(conic(s1.max(0.3), s2.max(0.3), th));
        }
        let radii = vec![10_000.0f32; n];
        let depths: Vec<f32> = (0..n).map(|i| 1.0 + i as f32).collect();
        let bins = bin_gaussians(&m2, &con, &radii, &depths, w, h);
        let (mut checked, mut ends, mut loose_limits) = (0usize, 0usize, 0usize);
        for g in 0..n {
            let [xl, xh, yl, yh] = bins.boxes[g];
            if xl > xh {
                continue;
            }
            let s = Splat {
                mx: m2[2 * g],
                my: m2[2 * g + 1],
                a: con[3 * g],
                b: con[3 * g + 1],
                c: con[3 * g + 2],
                o: 1.0f32,
                col: [0.0; 3],
                z: 1.0,
                bbox: bins.boxes[g],
                spans: bins.spans(g),
            };
            let f = f64::from;
            let limit = support_limit(f(s.mx), f(s.my), [f(s.a), f(s.b), f(s.c)], s.bbox);
            // Round and mildly elongated splats (axis ratio >= 0.3).
            if (g / 4) % 4 < 2 {
                loose_limits += usize::from(limit > SUPPORT_POWER + 1e-3);
            }
            let wide = Wide::<<f32 as SplatFloat>::L>::of(&s);
            let power = |x: u32, y: u32| {
                let dy = <f32 as SplatFloat>::L::splat(y as f32 + 0.5 - s.my);
                let (p, _) = lane_power::<f32>(&wide, lane_dx::<f32>(x as usize, &wide), dy);
                p.to_array()[0]
            };
            for (y, &[lo, hi]) in (yl..=yh).zip(s.spans) {
                for x in xl..=xh {
                    let p = power(x, y);
                    if (0.0..=4.5).contains(&p) {
                        checked += 1;
                        assert!(
                            lo <= x && x <= hi,
                            "splat {g}: pixel ({x}, {y}) has power {p} but the row span is [{lo}, {hi}]"
                        );
                    }
                }
                if lo <= hi {
                    ends += 2;
                    for x in [lo, hi] {
                        let p = power(x, y);
                        assert!(
                            f64::from(p) <= limit + 1e-4,
                            "splat {g}: span end ({x}, {y}) at power {p}, limit {limit}"
                        );
                    }
                }
            }
        }
        assert!(checked > 100_000, "only {checked} pixels checked");
        assert!(ends > 10_000, "only {ends} span ends checked");
        assert_eq!(loose_limits, 0, "limits above 4.501 for non-thin splats");
        // A thin splat along the diagonal: its box is square, its spans a band.
        let c = conic(20.0, 0.5, std::f64::consts::FRAC_PI_4);
        let bins = bin_gaussians(&[100.3, 100.7], &c, &[1000.0], &[1.0], 200, 200);
        let [xl, xh, yl, yh] = bins.boxes[0];
        let walked: u32 = bins
            .spans(0)
            .iter()
            .map(|&[lo, hi]| (hi + 1).saturating_sub(lo))
            .sum();
        let boxed = (xh - xl + 1) * (yh - yl + 1);
        assert!(
            walked * 3 < boxed,
            "spans cover {walked} of {boxed} box pixels"
        );
    }
}
