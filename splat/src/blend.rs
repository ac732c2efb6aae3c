//! The blend loop of one 16x16 tile, forward and backward, over pixel lanes
//! ([`Lanes`]: 4 pixels of a tile row for f32, one for f64).
//!
//! Each Gaussian of the tile's sorted list visits only the rows of its pixel box and,
//! in each row, the lane groups the box touches; lanes outside its support ellipse
//! (`power > ln(255 o)`, where alpha < 1/255), already saturated or outside the image
//! are masked. The per-pixel
//! operations and their order along the list are those of the textbook per-pixel loop
//! ([`crate::rasterize::Rasterize`]), so the forward and the backward make the same
//! decisions lane for lane: both evaluate alpha through [`lane_alpha`] on identical
//! inputs.

use maaf_autodiff::Float;

use crate::compositing::{ALPHA_MAX, ALPHA_MIN, AlphaCutoff, SMOOTH_TAPER_WIDTH, T_MIN, TILE};
use crate::lanes::{Lanes, SplatFloat};

/// Pixels of a tile; per-pixel state is stored row-major with stride [`TILE`].
pub(crate) const NP: usize = TILE * TILE;

/// One Gaussian as the blend loop reads it, with its support edge
/// `lim = ln(255 o)` ([`crate::compositing::support_power`]) and its inclusive pixel
/// box `[x_lo, x_hi] x [y_lo, y_hi]` in image coordinates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Splat<T> {
    pub mx: T,
    pub my: T,
    pub a: T,
    pub b: T,
    pub c: T,
    pub o: T,
    pub lim: T,
    pub col: [T; 3],
    pub z: T,
    pub bbox: [u32; 4],
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
    /// The part of `s`'s pixel box inside the tile as tile-local
    /// `(row range, lane-group range)`, or `None`.
    fn span<T, L: Lanes<T>>(&self, s: &Splat<T>) -> Option<(usize, usize, usize, usize)> {
        let [xl, xh, yl, yh] = s.bbox.map(|v| v as usize);
        let (lx0, lx1) = (xl.max(self.x0), xh.min(self.x1 - 1));
        let (ly0, ly1) = (yl.max(self.y0), yh.min(self.y1 - 1));
        (lx0 <= lx1 && ly0 <= ly1).then(|| {
            (
                ly0 - self.y0,
                ly1 - self.y0,
                (lx0 - self.x0) / L::N,
                (lx1 - self.x0) / L::N,
            )
        })
    }

    /// The tile's pixels inside the image as `(k, p)`: tile-local index `k` (stride
    /// [`TILE`]) and image index `p = y * width + x`.
    pub fn pixels(self, width: usize) -> impl Iterator<Item = (usize, usize)> {
        (self.y0..self.y1).flat_map(move |y| {
            (self.x0..self.x1).map(move |x| ((y - self.y0) * TILE + x - self.x0, y * width + x))
        })
    }
}

/// A Gaussian's parameters broadcast to every lane.
struct Wide<L> {
    mx: L,
    a: L,
    b: L,
    c: L,
    o: L,
    lim: L,
    col: [L; 3],
    z: L,
}

impl<L> Wide<L> {
    fn of<T: Copy>(s: &Splat<T>) -> Self
    where
        L: Lanes<T>,
    {
        Wide {
            mx: L::splat(s.mx),
            a: L::splat(s.a),
            b: L::splat(s.b),
            c: L::splat(s.c),
            o: L::splat(s.o),
            lim: L::splat(s.lim),
            col: s.col.map(L::splat),
            z: L::splat(s.z),
        }
    }
}

/// Lane offsets `dx` of the pixel centres `x + 0.5` of lane group `group` of a tile
/// starting at column `x0` from the mean: computed the same way in forward and
/// backward so that both see identical bits.
#[inline(always)]
fn lane_dx<T: SplatFloat>(x0: usize, group: usize, w: &Wide<T::L>) -> T::L {
    let first = T::of((x0 + group * T::L::N) as f64);
    T::L::splat(first) + T::L::ramp() + T::L::splat(T::of(0.5)) - w.mx
}

/// `power = (A dx^2 + C dy^2)/2 + B dx dy` per lane and whether it lies in the
/// support `[0, ln(255 o)]`; groups where no live lane is in the support are skipped
/// before the exponential.
#[inline(always)]
fn lane_power<T: SplatFloat>(
    w: &Wide<T::L>,
    dx: T::L,
    dy: T::L,
) -> (T::L, <T::L as Lanes<T>>::Mask) {
    let l = T::L::splat;
    let p = l(T::of(0.5)) * (w.a * dx * dx + w.c * dy * dy) + w.b * dx * dy;
    (p, p.ge(l(T::zero())) & p.le(w.lim))
}

/// What [`lane_alpha`] returns per lane.
struct Alpha<L: Lanes<T>, T> {
    /// Whether the Gaussian counts at the pixel.
    ok: L::Mask,
    /// Its alpha there (meaningful where `ok`).
    alpha: L,
    /// `exp(-power)`.
    g: L,
    /// `d alpha / d(o exp(-power))`: 1 for the hard cutoff (where unclamped),
    /// `w + dw/dr` for the smooth one.
    da: L,
}

/// `g = exp(-power)` and alpha with the [`AlphaCutoff`] rules: hard
/// `alpha = min(0.99, o g)`, counted when `0 <= power <= ln(255 o)` and
/// `o g >= 1/255`; smooth `alpha = o g w(ln(255 o) - power)`, counted when positive.
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
                da: T::L::select(a.gt(l(T::of(ALPHA_MAX))), l(T::zero()), l(T::one())),
            }
        }
        AlphaCutoff::Smooth => {
            let (wt, dwt) = taper::<T>(w.lim - p);
            let a = w.o * g * wt;
            Alpha {
                ok: in_support & a.gt(l(T::zero())),
                alpha: a,
                g,
                da: wt + dwt,
            }
        }
    }
}

/// The C1 taper of [`AlphaCutoff::Smooth`] as a function of the headroom
/// `r = ln(255 o) - power` above the support edge: `w = (1 - q^2)^2` for
/// `q = 1 - r / 2.5` in `[0, 1]` (1 for `r >= 2.5`, 0 for `r <= 0`), and `dw/dr`.
#[inline(always)]
fn taper<T: SplatFloat>(r: T::L) -> (T::L, T::L) {
    let l = T::L::splat;
    let width = l(T::of(SMOOTH_TAPER_WIDTH));
    let q = l(T::one()) - r / width;
    let s = l(T::one()) - q * q;
    let inside = l(T::one());
    let below = q.le(l(T::zero()));
    let above = q.ge(inside);
    let w = T::L::select(below, inside, T::L::select(above, l(T::zero()), s * s));
    let dw = T::L::select(below | above, l(T::zero()), l(T::of(4.0)) * q * s / width);
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

/// Walks the lane groups of `s`'s pixel box inside `rect` and calls `f` for each
/// group where some lane is in the support, open in `gate` (1 open, 0 closed) and
/// counted under `cut`; `f` gets the gate back to close lanes. Forward and backward
/// both walk through here, so they make the same decisions lane for lane.
#[inline(always)]
fn for_each_group<T: SplatFloat>(
    rect: TileRect,
    s: &Splat<T>,
    cut: AlphaCutoff,
    gate: &mut [T],
    mut f: impl FnMut(&Wide<T::L>, Group<T::L, T>, &mut [T]),
) {
    let l = T::L::splat;
    let Some((r0, r1, g0, g1)) = rect.span::<T, T::L>(s) else {
        return;
    };
    let w = Wide::<T::L>::of(s);
    for row in r0..=r1 {
        let dy = l(T::of((rect.y0 + row) as f64) + T::of(0.5) - s.my);
        for group in g0..=g1 {
            let k = row * TILE + group * T::L::N;
            let dx = lane_dx::<T>(rect.x0, group, &w);
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

/// What the backward of a tile needs from its forward, per tile pixel (stride
/// [`TILE`]; off-image pixels have `n_last = 0`).
pub(crate) struct TileEnd<T> {
    /// Final transmittance.
    pub t_final: Vec<T>,
    /// Index (in the tile list) of the last contributor, plus one.
    pub n_last: Vec<u32>,
}

/// Forward result of one tile, per tile pixel (stride [`TILE`]).
pub(crate) struct TileOut<T> {
    pub rgb: [Vec<T>; 3],
    pub depth: Vec<T>,
    pub end: TileEnd<T>,
}

/// Composites `splats` (sorted front to back) over one tile, background included.
pub(crate) fn forward_tile<T: SplatFloat>(
    splats: &[Splat<T>],
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
    // Last contributor plus one, as a float per lane so that it updates with one
    // select (exact: lists are shorter than 2^24).
    assert!(splats.len() < 1 << 24, "forward_tile: tile list too long");
    let mut n_lanes = [zero; NP];
    // 1 while a pixel still takes contributions, 0 once saturated or off-image.
    let mut live = vec![zero; NP];
    for (k, _) in rect.pixels(0) {
        live[k] = one;
    }
    let mut n_live = (rect.x1 - rect.x0) * (rect.y1 - rect.y0);
    for (j, s) in splats.iter().enumerate() {
        if n_live == 0 {
            break;
        }
        let index = l(T::of((j + 1) as f64));
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
            T::L::select(blend, index, T::L::load(&n_lanes[k..])).store(&mut n_lanes[k..]);
        });
    }
    for ch in 0..3 {
        for (v, &t) in rgb[ch].iter_mut().zip(&tr) {
            *v += t * background[ch];
        }
    }
    TileOut {
        rgb,
        depth,
        end: TileEnd {
            t_final: tr,
            n_last: n_lanes.iter().map(|&v| Float::to_f64(v) as u32).collect(),
        },
    }
}

/// Per-pixel inputs of the backward of one tile (stride [`TILE`]).
pub(crate) struct TileGrads<'a, T> {
    /// Cotangent of the colour.
    pub v_render_colors: [Vec<T>; 3],
    /// Cotangent of the accumulated alpha.
    pub v_render_alphas: Vec<T>,
    /// Cotangent of the depth.
    pub v_render_depths: Vec<T>,
    /// What the forward left.
    pub end: &'a TileEnd<T>,
}

/// What [`backward_tile`] returns: per list entry `d/d(mx, my, A, B, C, o, r, g, b, z)`,
/// and per entry `(sum |d/dmx|, sum |d/dmy|)` when asked (else empty).
pub(crate) type TileBackward<T> = (Vec<[T; 10]>, Vec<[T; 2]>);

/// Backward of [`forward_tile`]: walks each pixel back to front from its last
/// contributor, recovering `T_i = T_{i+1} / (1 - alpha_i)`, and returns one gradient
/// row per list entry, `d/d(mx, my, A, B, C, o, r, g, b, z)`, and, when `ABS_MEANS`
/// (a compile-time switch, so the plain backward is unchanged), one row per entry of
/// the sums over pixels of `|d/dmx|` and `|d/dmy|` (AbsGS's statistic; else empty).
pub(crate) fn backward_tile<T: SplatFloat, const ABS_MEANS: bool>(
    splats: &[Splat<T>],
    rect: TileRect,
    cut: AlphaCutoff,
    background: [T; 3],
    inp: &TileGrads<'_, T>,
) -> TileBackward<T> {
    let l = T::L::splat;
    let (zero, one, half) = (T::zero(), T::one(), T::of(0.5));
    let mut grads = vec![[zero; 10]; splats.len()];
    let mut abs_grads = vec![[zero; 2]; if ABS_MEANS { splats.len() } else { 0 }];
    let (t_final, n_last) = (&inp.end.t_final, &inp.end.n_last);
    let mut tr = t_final.clone();
    let mut behind: [Vec<T>; 4] = [
        tr.iter().map(|&t| background[0] * t).collect(),
        tr.iter().map(|&t| background[1] * t).collect(),
        tr.iter().map(|&t| background[2] * t).collect(),
        vec![zero; NP],
    ];
    // Pixels join the walk at their last contributor: `active` turns 1 when
    // `j < n_last`. `order` lists pixels by decreasing `n_last`.
    let mut order: Vec<usize> = (0..NP).filter(|&k| n_last[k] > 0).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(n_last[k]));
    let mut active = [zero; NP];
    let mut next_in = 0;
    let jmax = order.first().map_or(0, |&k| n_last[k] as usize);
    for j in (0..jmax).rev() {
        while next_in < order.len() && n_last[order[next_in]] as usize > j {
            active[order[next_in]] = one;
            next_in += 1;
        }
        let mut acc = [l(zero); 10];
        let mut abs_acc = [l(zero); 2];
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
            let v_color_px = [0, 1, 2].map(|ch| T::L::load(&inp.v_render_colors[ch][k..]));
            let v_depth_px = T::L::load(&inp.v_render_depths[k..]);
            let mut v_alpha =
                T::L::load(&inp.v_render_alphas[k..]) * T::L::load(&t_final[k..]) * inv;
            for ch in 0..3 {
                acc[6 + ch] = acc[6 + ch] + pick(v_color_px[ch] * wgt);
                let bh = T::L::load(&behind[ch][k..]);
                v_alpha = v_alpha + v_color_px[ch] * (w.col[ch] * t - bh * inv);
                T::L::select(m, bh + w.col[ch] * wgt, bh).store(&mut behind[ch][k..]);
            }
            acc[9] = acc[9] + pick(v_depth_px * wgt);
            let bh = T::L::load(&behind[3][k..]);
            v_alpha = v_alpha + v_depth_px * (w.z * t - bh * inv);
            T::L::select(m, bh + w.z * wgt, bh).store(&mut behind[3][k..]);
            // alpha = f(a) with a = o exp(-power): d/do = f'(a) g, d/dpower = -f'(a) a;
            // f'(a) = al.da (0 where the 0.99 clamp holds, w + dw/dr when smooth).
            let v_a = v_alpha * al.da;
            let v_opacity = v_a * al.g;
            let v_power = -(v_a * w.o * al.g);
            let v_power = pick(v_power);
            acc[5] = acc[5] + pick(v_opacity);
            acc[2] = acc[2] + v_power * l(half) * dx * dx;
            acc[3] = acc[3] + v_power * dx * dy;
            acc[4] = acc[4] + v_power * l(half) * dy * dy;
            // d/dmx = -v_power * (A dx + B dy); |.| drops the sign, so the plain
            // backward subtracts exactly as before.
            let v_mx = v_power * (w.a * dx + w.b * dy);
            let v_my = v_power * (w.b * dx + w.c * dy);
            acc[0] = acc[0] - v_mx;
            acc[1] = acc[1] - v_my;
            if ABS_MEANS {
                abs_acc[0] = abs_acc[0] + v_mx.abs();
                abs_acc[1] = abs_acc[1] + v_my.abs();
            }
        });
        grads[j] = acc.map(|v| v.sum());
        if ABS_MEANS {
            abs_grads[j] = abs_acc.map(|v| v.sum());
        }
    }
    (grads, abs_grads)
}
