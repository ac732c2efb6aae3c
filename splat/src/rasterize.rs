//! The rasterizer op: alpha compositing over 16x16 tiles, forward and backward
//! (docs/conventions.md; Inria `renderCUDA`, gsplat `RasterizeToPixels3DGS*`).
//!
//! Binning and the per-tile depth sort are in [`crate::binning`], the blend loop of
//! one tile in `blend.rs`. Tiles are rendered in parallel (rayon); the backward
//! writes per-tile gradient buffers that are summed serially in tile order, so the
//! result is bit-identical on any number of threads.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};
use rayon::prelude::*;

use crate::binning::{Binning, bin_gaussians};
use crate::blend::{
    NP, Splat, TileBackward, TileEnd, TileGrads, TileOut, TileRect, backward_tile, forward_tile,
};
use crate::compositing::{AlphaCutoff, TILE, support_power};
use crate::lanes::SplatFloat;

/// The rasterizer op: alpha compositing of projected Gaussians, front to back.
///
/// For each pixel with centre `q = (x + 0.5, y + 0.5)` and its Gaussians `i` in depth
/// order, with `d = q - mean2d_i` and `power_i = (A dx^2 + C dy^2)/2 + B dx dy`:
///
/// ```text
/// alpha_i = min(0.99, o_i exp(-power_i))     (see AlphaCutoff for the skip rules;
///                                             the support is power_i <= ln(255 o_i))
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
    /// Where the backward leaves the absolute screen-mean gradient when asked.
    pub abs_means2d: AbsMeans2dGrad<T>,
}

/// AbsGS's densification statistic of one rasterization, filled by its backward
/// when [`request`](Self::request)ed before the tape's backward pass:
///
/// ```text
/// abs_i = ( sum_p |dL_p/d mx_i| , sum_p |dL_p/d my_i| )     [N, 2], pixels
/// ```
///
/// where `L_p` is the part of the loss that reaches pixel `p` (its colour, alpha and
/// depth cotangents). `dL/d means2d` is the same sum without the absolute values, so
/// opposite pulls from two sides of a Gaussian cancel there and not here (AbsGS,
/// Ye et al. 2024; the `dL_dmean2D_densify` buffer of the MAAF release's rasterizer).
/// Not a gradient: no op consumes it, so it has no finite-difference check; its test
/// compares it with per-pixel gradients of the reference compositor.
#[derive(Clone, Default)]
pub struct AbsMeans2dGrad<T>(Arc<AbsSlot<T>>);

#[derive(Default)]
struct AbsSlot<T> {
    wanted: AtomicBool,
    value: Mutex<Option<Tensor<T>>>,
}

impl<T: Float> AbsMeans2dGrad<T> {
    /// Asks the rasterizer's backward to compute the statistic (it costs two more
    /// accumulations per pixel and Gaussian, so it is off unless asked).
    pub fn request(&self) {
        self.0.wanted.store(true, Ordering::Relaxed);
    }

    /// The statistic `[N, 2]`, once the backward has run after a
    /// [`request`](Self::request); `None` before, or if it was not requested.
    pub fn take(&self) -> Option<Tensor<T>> {
        self.0.value.lock().ok().and_then(|mut v| v.take())
    }

    fn wanted(&self) -> bool {
        self.0.wanted.load(Ordering::Relaxed)
    }

    fn put(&self, t: Tensor<T>) {
        if let Ok(mut v) = self.0.value.lock() {
            *v = Some(t);
        }
    }
}

/// What the rasterizer forward keeps for its backward.
pub struct RasterSaved<T> {
    bins: Binning,
    /// Per tile, in the tile's own pixel layout: the final transmittance and the
    /// last contributor.
    tiles: Vec<TileEnd<T>>,
    finite: bool,
}

impl<T: Float> RasterSaved<T> {
    /// The tile binning used by the forward.
    pub fn binning(&self) -> &Binning {
        &self.bins
    }
}

fn gather_splats<T: Float>(list: &[u32], inputs: &[&Tensor<T>], bins: &Binning) -> Vec<Splat<T>> {
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
                lim: support_power(op[g]),
                col: [col[3 * g], col[3 * g + 1], col[3 * g + 2]],
                z: dep[g],
                bbox: bins.boxes[g],
            }
        })
        .collect()
}

/// Pixel rectangle of tile `t`.
fn tile_pixels(t: usize, tiles_x: usize, w: u32, h: u32) -> TileRect {
    let (tx, ty) = (t % tiles_x, t / tiles_x);
    let (x0, y0) = (tx * TILE, ty * TILE);
    TileRect {
        x0,
        y0,
        x1: (x0 + TILE).min(w as usize),
        y1: (y0 + TILE).min(h as usize),
    }
}

impl<T: SplatFloat> Op<T> for Rasterize<T> {
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
                    tiles: Vec::new(),
                    finite,
                },
            );
        }
        let bins = bin_gaussians(
            inputs[0].data(),
            inputs[1].data(),
            inputs[3].data(),
            inputs[5].data(),
            inputs[4].data(),
            self.width,
            self.height,
        );
        let ntiles = bins.tiles_x * bins.tiles_y;
        let tiles: Vec<TileOut<T>> = (0..ntiles)
            .into_par_iter()
            .map(|t| {
                let splats = gather_splats(bins.tile(t), inputs, &bins);
                let rect = tile_pixels(t, bins.tiles_x, self.width, self.height);
                forward_tile(&splats, rect, self.cutoff, self.background)
            })
            .collect();
        let mut image = vec![T::zero(); h * w * 3];
        let mut alpha = vec![T::zero(); h * w];
        let mut depth = vec![T::zero(); h * w];
        for (t, out) in tiles.iter().enumerate() {
            let rect = tile_pixels(t, bins.tiles_x, self.width, self.height);
            for (k, p) in rect.pixels(w) {
                for ch in 0..3 {
                    image[3 * p + ch] = out.rgb[ch][k];
                }
                alpha[p] = T::one() - out.end.t_final[k];
                depth[p] = out.depth[k];
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
                tiles: tiles.into_iter().map(|o| o.end).collect(),
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
        let (v_render_colors, v_render_alphas, v_render_depths) = (
            ctx.grad_outputs[0].data(),
            ctx.grad_outputs[1].data(),
            ctx.grad_outputs[2].data(),
        );
        let w = self.width as usize;
        let abs_means = self.abs_means2d.wanted();
        // Per tile: one gradient row per list entry,
        // (mx, my, A, B, C, o, r, g, b, z), and (|mx|, |my|) when asked.
        let per_tile: Vec<TileBackward<T>> = (0..ntiles)
            .into_par_iter()
            .map(|t| {
                let splats = gather_splats(bins.tile(t), ctx.inputs, bins);
                let rect = tile_pixels(t, bins.tiles_x, self.width, self.height);
                let mut inp = TileGrads {
                    v_render_colors: [
                        vec![T::zero(); NP],
                        vec![T::zero(); NP],
                        vec![T::zero(); NP],
                    ],
                    v_render_alphas: vec![T::zero(); NP],
                    v_render_depths: vec![T::zero(); NP],
                    end: &saved.tiles[t],
                };
                for (k, p) in rect.pixels(w) {
                    for ch in 0..3 {
                        inp.v_render_colors[ch][k] = v_render_colors[3 * p + ch];
                    }
                    inp.v_render_alphas[k] = v_render_alphas[p];
                    inp.v_render_depths[k] = v_render_depths[p];
                }
                if abs_means {
                    backward_tile::<T, true>(&splats, rect, self.cutoff, self.background, &inp)
                } else {
                    backward_tile::<T, false>(&splats, rect, self.cutoff, self.background, &inp)
                }
            })
            .collect();
        let mut v_means2d = vec![T::zero(); 2 * n];
        let mut v_conics = vec![T::zero(); 3 * n];
        let mut v_colors = vec![T::zero(); 3 * n];
        let mut v_opacities = vec![T::zero(); n];
        let mut v_depths = vec![T::zero(); n];
        let mut abs_m = vec![T::zero(); if abs_means { 2 * n } else { 0 }];
        // Serial reduction in tile order: bit-identical for any thread count.
        for (t, (grads, abs_grads)) in per_tile.iter().enumerate() {
            for (&g, gr) in bins.tile(t).iter().zip(grads) {
                let g = g as usize;
                v_means2d[2 * g] += gr[0];
                v_means2d[2 * g + 1] += gr[1];
                v_conics[3 * g] += gr[2];
                v_conics[3 * g + 1] += gr[3];
                v_conics[3 * g + 2] += gr[4];
                v_opacities[g] += gr[5];
                v_colors[3 * g] += gr[6];
                v_colors[3 * g + 1] += gr[7];
                v_colors[3 * g + 2] += gr[8];
                v_depths[g] += gr[9];
            }
            for (&g, gr) in bins.tile(t).iter().zip(abs_grads) {
                let g = g as usize;
                abs_m[2 * g] += gr[0];
                abs_m[2 * g + 1] += gr[1];
            }
        }
        if abs_means {
            self.abs_means2d.put(Tensor::from_vec(abs_m, &[n, 2]));
        }
        vec![
            Some(Tensor::from_vec(v_means2d, &[n, 2])),
            Some(Tensor::from_vec(v_conics, &[n, 3])),
            Some(Tensor::from_vec(v_colors, &[n, 3])),
            Some(Tensor::from_vec(v_opacities, &[n])),
            Some(Tensor::from_vec(v_depths, &[n])),
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
    /// The absolute screen-mean gradient, filled by the backward when requested.
    pub abs_means2d: AbsMeans2dGrad<T>,
}

/// Rasterizes on the tape, see [`Rasterize`].
#[allow(clippy::too_many_arguments)]
pub fn rasterize<'t, T: SplatFloat>(
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
    let abs_means2d = AbsMeans2dGrad::default();
    let out = means2d.tape().apply(
        Rasterize {
            width,
            height,
            background: background.map(T::of),
            cutoff,
            abs_means2d: abs_means2d.clone(),
        },
        &[means2d, conics, colors, opacity, depths, radii],
    );
    Rasterized {
        image: out[0],
        alpha: out[1],
        depth: out[2],
        abs_means2d,
    }
}
