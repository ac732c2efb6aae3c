//! Tile binning, per-tile depth sort and alpha compositing, forward and backward
//! (DESIGN.md section 3; Inria `renderCUDA`, gsplat `RasterizeToPixels3DGS*`).
//!
//! The image is cut into 16x16 tiles. Every visible Gaussian is listed in each tile
//! its pixel box `[mean - r, mean + r]` touches; each tile's list is sorted front to
//! back by `(depth, index)`. Tiles are rendered in parallel (rayon); the backward
//! writes per-tile gradient buffers that are summed serially in tile order, so the
//! result is bit-identical on any number of threads.

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};
use rayon::prelude::*;

use crate::project::pixel_range;

/// Tile edge in pixels.
pub const TILE: usize = 16;
/// Minimum alpha for a Gaussian to count at a pixel (hard cutoff): `1/255`.
pub const ALPHA_MIN: f64 = 1.0 / 255.0;
/// Alpha clamp (hard cutoff): `alpha = min(0.99, o exp(-power))` (Inria, Mip-Splatting,
/// gsplat >= 2026-02).
pub const ALPHA_MAX: f64 = 0.99;
/// Transmittance floor: a pixel stops before blending a Gaussian that would take
/// `T` below `1e-4` (exclusive, as Inria and gsplat).
pub const T_MIN: f64 = 1e-4;
/// Support of a Gaussian: `power = d^T conic d / 2 <= 4.5`, the 3-sigma ellipse. It is
/// contained in the `ceil(3 sqrt(lambda_max))` radius used for binning, so the image
/// does not depend on the tile grid. Deliberate difference: Inria/gsplat blend a
/// Gaussian at every pixel of every tile its box touches, which keeps tails beyond
/// 3 sigma (alpha <= 0.011 o) at some pixels and not at others.
pub const SUPPORT_POWER: f64 = 4.5;
/// Start of the smooth taper of [`AlphaCutoff::Smooth`] in power units.
pub const SMOOTH_TAPER_START: f64 = 2.0;

/// How alpha is cut off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AlphaCutoff {
    /// 3DGS behaviour: `alpha = min(0.99, o exp(-power))` for `power <= 4.5`, skipped
    /// when below `1/255`, a pixel stops before `T` would fall under `1e-4`. The
    /// gradient is zero where the 0.99 clamp is active (the true derivative; gsplat
    /// masks it too, Inria does not).
    #[default]
    Hard,
    /// A C1 variant for finite-difference tests: `alpha = o exp(-power) w(power)`
    /// with the taper `w = (1 - q^2)^2` for `q = (power - 2)/(4.5 - 2)` in `[0,1]`,
    /// `w = 1` below and `0` above; no 1/255 skip, no clamp, no early stop.
    Smooth,
}

/// The C1 taper of [`AlphaCutoff::Smooth`] and its derivative in `power`.
#[inline(always)]
fn taper<T: Float>(p: T) -> (T, T) {
    let p0 = T::of(SMOOTH_TAPER_START);
    let span = T::of(SUPPORT_POWER - SMOOTH_TAPER_START);
    let q = (p - p0) / span;
    if q <= T::zero() {
        (T::one(), T::zero())
    } else if q >= T::one() {
        (T::zero(), T::zero())
    } else {
        let s = T::one() - q * q;
        (s * s, T::of(-4.0) * s * q / span)
    }
}

/// One Gaussian as the blend loop reads it.
#[derive(Clone, Copy, Debug)]
struct Splat<T> {
    mx: T,
    my: T,
    a: T,
    b: T,
    c: T,
    o: T,
    col: [T; 3],
    z: T,
}

/// Alpha of `s` at offset `(dx, dy)` = pixel centre minus mean, or `None` when the
/// Gaussian does not count at this pixel. Shared by forward and backward so both make
/// the same decisions bit for bit.
#[inline(always)]
fn alpha_of<T: Float>(cut: AlphaCutoff, s: &Splat<T>, dx: T, dy: T) -> Option<(T, T)> {
    let half = T::of(0.5);
    let p = half * (s.a * dx * dx + s.c * dy * dy) + s.b * dx * dy;
    if !(p >= T::zero() && p <= T::of(SUPPORT_POWER)) {
        return None;
    }
    let g = (-p).exp();
    match cut {
        AlphaCutoff::Hard => {
            let a = s.o * g;
            if a < T::of(ALPHA_MIN) {
                None
            } else {
                Some((a.min(T::of(ALPHA_MAX)), g))
            }
        }
        AlphaCutoff::Smooth => {
            let (w, _) = taper(p);
            let a = s.o * g * w;
            (a > T::zero()).then_some((a, g))
        }
    }
}

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

/// Tile ranges `(x0..=x1, y0..=y1)` touched by a Gaussian's box of half-extents
/// `(rx, ry)`, or `None`.
fn tile_rect(
    mx: f64,
    my: f64,
    rx: f64,
    ry: f64,
    w: u32,
    h: u32,
) -> Option<(usize, usize, usize, usize)> {
    let (xl, xh) = pixel_range(mx, rx, w)?;
    let (yl, yh) = pixel_range(my, ry, h)?;
    Some((
        xl as usize / TILE,
        xh as usize / TILE,
        yl as usize / TILE,
        yh as usize / TILE,
    ))
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
    let rects: Vec<Option<(usize, usize, usize, usize)>> = (0..n)
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
                tile_rect(
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
    }
}

/// The rasterizer op: alpha compositing of projected Gaussians, front to back.
///
/// For each pixel with centre `q = (x + 0.5, y + 0.5)` and its Gaussians `i` in depth
/// order, with `d = q - mean2d_i` and `power_i = (A dx^2 + C dy^2)/2 + B dx dy`:
///
/// ```text
/// alpha_i = min(0.99, o_i exp(-power_i))     (see AlphaCutoff for the skip rules)
/// T_i     = prod_{j<i} (1 - alpha_j)
/// image   = sum_i c_i alpha_i T_i + T_final * background
/// alpha   = 1 - T_final
/// depth   = sum_i z_i alpha_i T_i            (expected depth = depth / alpha)
/// ```
///
/// Inputs `means2d [N,2]`, `conics [N,3]`, `colors [N,3]`, `opacity [N]`,
/// `depths [N]`, `radii [N]` (binning only, no gradient). Outputs `image [H,W,3]`,
/// `alpha [H,W]`, `depth [H,W]`. The backward walks each pixel back to front from its
/// last contributor, recovering `T_i = T_{i+1} / (1 - alpha_i)` from the stored final
/// transmittance (Inria `renderCUDA` backward). If any input is non-finite every
/// output is NaN, so a bad value is never rendered silently.
pub struct Rasterize<T: Float> {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Background colour added with weight `T_final`.
    pub background: [T; 3],
    /// Cutoff rules.
    pub cutoff: AlphaCutoff,
}

/// What the rasterizer forward keeps for its backward.
pub struct RasterSaved<T> {
    bins: Binning,
    /// Final transmittance per pixel.
    final_t: Vec<T>,
    /// Per pixel: index (in its tile list) of the last contributor, plus one.
    n_contrib: Vec<u32>,
    finite: bool,
}

impl<T: Float> RasterSaved<T> {
    /// The tile binning used by the forward.
    pub fn binning(&self) -> &Binning {
        &self.bins
    }
}

fn gather_splats<T: Float>(list: &[u32], inputs: &[&Tensor<T>]) -> Vec<Splat<T>> {
    let (m, con, col, op, dep) = (
        inputs[0].data(),
        inputs[1].data(),
        inputs[2].data(),
        inputs[3].data(),
        inputs[4].data(),
    );
    list.iter()
        .map(|&g| {
            let g = g as usize;
            Splat {
                mx: m[2 * g],
                my: m[2 * g + 1],
                a: con[3 * g],
                b: con[3 * g + 1],
                c: con[3 * g + 2],
                o: op[g],
                col: [col[3 * g], col[3 * g + 1], col[3 * g + 2]],
                z: dep[g],
            }
        })
        .collect()
}

/// Pixel rectangle of tile `t`: `(x0, y0, x1, y1)` exclusive ends.
fn tile_pixels(t: usize, tiles_x: usize, w: u32, h: u32) -> (usize, usize, usize, usize) {
    let (tx, ty) = (t % tiles_x, t / tiles_x);
    let (x0, y0) = (tx * TILE, ty * TILE);
    (
        x0,
        y0,
        (x0 + TILE).min(w as usize),
        (y0 + TILE).min(h as usize),
    )
}

/// Forward output of one tile, row-major inside the tile rectangle.
struct TileOut<T> {
    rgb: Vec<[T; 3]>,
    t_final: Vec<T>,
    depth: Vec<T>,
    n: Vec<u32>,
}

impl<T: Float> Rasterize<T> {
    /// Composites one tile. The loop runs Gaussian-major (each Gaussian, front to
    /// back, visits only the pixels of its support box inside the tile) with per-pixel
    /// state, which performs exactly the per-pixel operations of the textbook
    /// pixel-major loop in the same order, so results are identical; it just never
    /// touches pixel-Gaussian pairs that cannot overlap.
    fn render_tile(&self, splats: &[Splat<T>], rect: (usize, usize, usize, usize)) -> TileOut<T> {
        let (x0, y0, x1, y1) = rect;
        let tw = x1 - x0;
        let np = tw * (y1 - y0);
        let half = T::of(0.5);
        let t_min = T::of(T_MIN);
        let hard = self.cutoff == AlphaCutoff::Hard;
        let mut tr = vec![T::one(); np];
        let mut rgb = vec![[T::zero(); 3]; np];
        let mut depth = vec![T::zero(); np];
        let mut n = vec![0u32; np];
        let mut done = vec![false; np];
        let mut n_done = 0;
        for (j, s) in splats.iter().enumerate() {
            if n_done == np {
                break;
            }
            let Some((bx0, bx1, by0, by1)) = splat_box(s, rect) else {
                continue;
            };
            for y in by0..=by1 {
                let py = T::of(y as f64) + half;
                let dy = py - s.my;
                for x in bx0..=bx1 {
                    let k = (y - y0) * tw + (x - x0);
                    if done[k] {
                        continue;
                    }
                    let px = T::of(x as f64) + half;
                    let Some((alpha, _)) = alpha_of(self.cutoff, s, px - s.mx, dy) else {
                        continue;
                    };
                    let next = tr[k] * (T::one() - alpha);
                    if hard && next < t_min {
                        done[k] = true;
                        n_done += 1;
                        continue;
                    }
                    let w = alpha * tr[k];
                    let c = &mut rgb[k];
                    c[0] += s.col[0] * w;
                    c[1] += s.col[1] * w;
                    c[2] += s.col[2] * w;
                    depth[k] += s.z * w;
                    tr[k] = next;
                    n[k] = j as u32 + 1;
                }
            }
        }
        for (c, &t) in rgb.iter_mut().zip(&tr) {
            for (v, bg) in c.iter_mut().zip(self.background) {
                *v += t * bg;
            }
        }
        TileOut {
            rgb,
            t_final: tr,
            depth,
            n,
        }
    }
}

/// Pixel box `(x0, x1, y0, y1)` (inclusive, image indices) of the support ellipse
/// `power <= 4.5` of `s` inside the tile `rect`, or `None` when they do not meet.
/// Half-extents are `3 sqrt(Sigma_xx)`, `3 sqrt(Sigma_yy)` of `Sigma = conic^-1` with
/// a 1e-4 relative margin against rounding; a non-positive-definite conic gets the
/// whole tile (the per-pixel test then decides).
fn splat_box<T: Float>(
    s: &Splat<T>,
    rect: (usize, usize, usize, usize),
) -> Option<(usize, usize, usize, usize)> {
    let (x0, y0, x1, y1) = rect;
    let (a, b, c) = (Float::to_f64(s.a), Float::to_f64(s.b), Float::to_f64(s.c));
    let det = a * c - b * b;
    let ext = |v: f64| (9.0 * v / det).sqrt() * (1.0 + 1e-4) + 1e-4;
    let (ex, ey) = (ext(c), ext(a));
    if !(det > 0.0 && ex.is_finite() && ey.is_finite()) {
        return Some((x0, x1 - 1, y0, y1 - 1));
    }
    let (mx, my) = (Float::to_f64(s.mx), Float::to_f64(s.my));
    let lo_x = (mx - ex - 0.5).ceil().max(x0 as f64);
    let hi_x = (mx + ex - 0.5).floor().min((x1 - 1) as f64);
    let lo_y = (my - ey - 0.5).ceil().max(y0 as f64);
    let hi_y = (my + ey - 0.5).floor().min((y1 - 1) as f64);
    (lo_x <= hi_x && lo_y <= hi_y).then_some((
        lo_x as usize,
        hi_x as usize,
        lo_y as usize,
        hi_y as usize,
    ))
}

impl<T: Float> Op<T> for Rasterize<T> {
    type Saved = RasterSaved<T>;

    fn name(&self) -> String {
        "rasterize".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, RasterSaved<T>) {
        let n = inputs[3].len();
        let shapes: [&[usize]; 6] = [&[n, 2], &[n, 3], &[n, 3], &[n], &[n], &[n]];
        for (k, s) in shapes.iter().enumerate() {
            assert_eq!(
                inputs[k].shape(),
                *s,
                "rasterize: input {k} has shape {:?}, expected {s:?}",
                inputs[k].shape()
            );
        }
        let (w, h) = (self.width as usize, self.height as usize);
        let finite = inputs[..5].iter().all(|t| t.first_non_finite().is_none());
        if !finite {
            let nan = T::nan();
            return (
                vec![
                    Tensor::full(&[h, w, 3], nan),
                    Tensor::full(&[h, w], nan),
                    Tensor::full(&[h, w], nan),
                ],
                RasterSaved {
                    bins: Binning::default(),
                    final_t: Vec::new(),
                    n_contrib: Vec::new(),
                    finite,
                },
            );
        }
        let bins = bin_gaussians(
            inputs[0].data(),
            inputs[1].data(),
            inputs[5].data(),
            inputs[4].data(),
            self.width,
            self.height,
        );
        let ntiles = bins.tiles_x * bins.tiles_y;
        let tiles: Vec<TileOut<T>> = (0..ntiles)
            .into_par_iter()
            .map(|t| {
                let splats = gather_splats(bins.tile(t), inputs);
                let rect = tile_pixels(t, bins.tiles_x, self.width, self.height);
                self.render_tile(&splats, rect)
            })
            .collect();
        let mut image = vec![T::zero(); h * w * 3];
        let mut alpha = vec![T::zero(); h * w];
        let mut depth = vec![T::zero(); h * w];
        let mut final_t = vec![T::one(); h * w];
        let mut n_contrib = vec![0u32; h * w];
        for (t, out) in tiles.iter().enumerate() {
            let (x0, y0, x1, y1) = tile_pixels(t, bins.tiles_x, self.width, self.height);
            let mut k = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    let p = y * w + x;
                    image[3 * p..3 * p + 3].copy_from_slice(&out.rgb[k]);
                    alpha[p] = T::one() - out.t_final[k];
                    depth[p] = out.depth[k];
                    final_t[p] = out.t_final[k];
                    n_contrib[p] = out.n[k];
                    k += 1;
                }
            }
        }
        (
            vec![
                Tensor::from_vec(image, &[h, w, 3]),
                Tensor::from_vec(alpha, &[h, w]),
                Tensor::from_vec(depth, &[h, w]),
            ],
            RasterSaved {
                bins,
                final_t,
                n_contrib,
                finite,
            },
        )
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, RasterSaved<T>>) -> Vec<Option<Tensor<T>>> {
        let n = ctx.inputs[3].len();
        let saved = ctx.saved;
        let shapes: [&[usize]; 5] = [&[n, 2], &[n, 3], &[n, 3], &[n], &[n]];
        if !saved.finite {
            let mut out: Vec<Option<Tensor<T>>> = shapes
                .iter()
                .map(|s| Some(Tensor::full(s, T::nan())))
                .collect();
            out.push(None);
            return out;
        }
        let bins = &saved.bins;
        let ntiles = bins.tiles_x * bins.tiles_y;
        let (g_img, g_alpha, g_depth) = (
            ctx.grad_outputs[0].data(),
            ctx.grad_outputs[1].data(),
            ctx.grad_outputs[2].data(),
        );
        let w = self.width as usize;
        let half = T::of(0.5);
        let one = T::one();
        // Per tile: one gradient row per list entry,
        // (mx, my, A, B, C, o, r, g, b, z).
        let per_tile: Vec<Vec<[T; 10]>> = (0..ntiles)
            .into_par_iter()
            .map(|t| {
                let list = bins.tile(t);
                let splats = gather_splats(list, ctx.inputs);
                let mut grads = vec![[T::zero(); 10]; list.len()];
                let rect = tile_pixels(t, bins.tiles_x, self.width, self.height);
                let (x0, y0, x1, y1) = rect;
                let tw = x1 - x0;
                let np = tw * (y1 - y0);
                // Per-pixel state of the back-to-front walk.
                let mut tr = vec![T::zero(); np];
                let mut behind = vec![[T::zero(); 4]; np];
                let mut n_last = vec![0usize; np];
                let mut jmax = 0;
                for y in y0..y1 {
                    for x in x0..x1 {
                        let (k, p) = ((y - y0) * tw + (x - x0), y * w + x);
                        let tf = saved.final_t[p];
                        tr[k] = tf;
                        behind[k] = [
                            self.background[0] * tf,
                            self.background[1] * tf,
                            self.background[2] * tf,
                            T::zero(),
                        ];
                        n_last[k] = saved.n_contrib[p] as usize;
                        jmax = jmax.max(n_last[k]);
                    }
                }
                for j in (0..jmax).rev() {
                    let s = &splats[j];
                    let Some((bx0, bx1, by0, by1)) = splat_box(s, rect) else {
                        continue;
                    };
                    let mut acc = [T::zero(); 10];
                    for y in by0..=by1 {
                        let py = T::of(y as f64) + half;
                        let dy = py - s.my;
                        for x in bx0..=bx1 {
                            let k = (y - y0) * tw + (x - x0);
                            if j >= n_last[k] {
                                continue;
                            }
                            let px = T::of(x as f64) + half;
                            let dx = px - s.mx;
                            let Some((alpha, g)) = alpha_of(self.cutoff, s, dx, dy) else {
                                continue;
                            };
                            let p = y * w + x;
                            let t_final = saved.final_t[p];
                            let gc = [g_img[3 * p], g_img[3 * p + 1], g_img[3 * p + 2]];
                            let (ga, gd) = (g_alpha[p], g_depth[p]);
                            let inv = one / (one - alpha);
                            tr[k] *= inv;
                            let trk = tr[k];
                            let wgt = alpha * trk;
                            acc[6] += gc[0] * wgt;
                            acc[7] += gc[1] * wgt;
                            acc[8] += gc[2] * wgt;
                            acc[9] += gd * wgt;
                            let bh = &mut behind[k];
                            let mut g_al = ga * t_final * inv;
                            for ch in 0..3 {
                                g_al += gc[ch] * (s.col[ch] * trk - bh[ch] * inv);
                                bh[ch] += s.col[ch] * wgt;
                            }
                            g_al += gd * (s.z * trk - bh[3] * inv);
                            bh[3] += s.z * wgt;
                            // alpha(o, power)
                            let (g_o, g_p) = match self.cutoff {
                                AlphaCutoff::Hard => {
                                    if s.o * g > T::of(ALPHA_MAX) {
                                        (T::zero(), T::zero())
                                    } else {
                                        (g_al * g, -g_al * s.o * g)
                                    }
                                }
                                AlphaCutoff::Smooth => {
                                    let pw = half * (s.a * dx * dx + s.c * dy * dy) + s.b * dx * dy;
                                    let (wt, dtw) = taper(pw);
                                    (g_al * g * wt, g_al * s.o * g * (dtw - wt))
                                }
                            };
                            acc[5] += g_o;
                            acc[2] += g_p * half * dx * dx;
                            acc[3] += g_p * dx * dy;
                            acc[4] += g_p * half * dy * dy;
                            acc[0] -= g_p * (s.a * dx + s.b * dy);
                            acc[1] -= g_p * (s.b * dx + s.c * dy);
                        }
                    }
                    grads[j] = acc;
                }
                grads
            })
            .collect();
        let mut dm = vec![T::zero(); 2 * n];
        let mut dcon = vec![T::zero(); 3 * n];
        let mut dcol = vec![T::zero(); 3 * n];
        let mut dop = vec![T::zero(); n];
        let mut ddep = vec![T::zero(); n];
        // Serial reduction in tile order: bit-identical for any thread count.
        for (t, grads) in per_tile.iter().enumerate() {
            for (&g, gr) in bins.tile(t).iter().zip(grads) {
                let g = g as usize;
                dm[2 * g] += gr[0];
                dm[2 * g + 1] += gr[1];
                dcon[3 * g] += gr[2];
                dcon[3 * g + 1] += gr[3];
                dcon[3 * g + 2] += gr[4];
                dop[g] += gr[5];
                dcol[3 * g] += gr[6];
                dcol[3 * g + 1] += gr[7];
                dcol[3 * g + 2] += gr[8];
                ddep[g] += gr[9];
            }
        }
        vec![
            Some(Tensor::from_vec(dm, &[n, 2])),
            Some(Tensor::from_vec(dcon, &[n, 3])),
            Some(Tensor::from_vec(dcol, &[n, 3])),
            Some(Tensor::from_vec(dop, &[n])),
            Some(Tensor::from_vec(ddep, &[n])),
            None,
        ]
    }
}

/// Outputs of [`rasterize`].
pub struct Rasterized<'t, T: Float> {
    /// Colour `[H,W,3]`, background included.
    pub image: Var<'t, T>,
    /// Accumulated opacity `1 - T_final`, `[H,W]`.
    pub alpha: Var<'t, T>,
    /// Alpha-weighted depth `sum z_i alpha_i T_i`, `[H,W]`.
    pub depth: Var<'t, T>,
}

/// Rasterizes on the tape, see [`Rasterize`].
#[allow(clippy::too_many_arguments)]
pub fn rasterize<'t, T: Float>(
    means2d: Var<'t, T>,
    conics: Var<'t, T>,
    colors: Var<'t, T>,
    opacity: Var<'t, T>,
    depths: Var<'t, T>,
    radii: Var<'t, T>,
    width: u32,
    height: u32,
    background: [f64; 3],
    cutoff: AlphaCutoff,
) -> Rasterized<'t, T> {
    let out = means2d.tape().apply(
        Rasterize {
            width,
            height,
            background: background.map(T::of),
            cutoff,
        },
        &[means2d, conics, colors, opacity, depths, radii],
    );
    Rasterized {
        image: out[0],
        alpha: out[1],
        depth: out[2],
    }
}
