//! Differentiable SSIM as one fused op with a hand-written backward.
//!
//! Convention (the 3DGS / 4DGS / SaRO-GS training loss, `utils/loss_utils.py::ssim`;
//! domain-notes section 6): images `[H, W, C]` with values in [0, 1], an 11 x 11
//! Gaussian window with sigma 1.5 applied as a separable blur with **zero-padded
//! "same"** borders, `C1 = 0.01^2`, `C2 = 0.03^2`, and the mean of the SSIM map over
//! every pixel and channel. With `G` the blur, per channel:
//!
//! ```text
//! mu_x = G x            mu_y = G y
//! s_xx = G(x^2) - mu_x^2   s_yy = G(y^2) - mu_y^2   s_xy = G(xy) - mu_x mu_y
//! A1 = 2 mu_x mu_y + C1    A2 = 2 s_xy + C2
//! B1 = mu_x^2 + mu_y^2 + C1   B2 = s_xx + s_yy + C2
//! S  = A1 A2 / (B1 B2)      SSIM = mean(S)
//! ```
//!
//! Backward: with `g` the cotangent of `S` (per pixel, or `dL/dSSIM / N` everywhere
//! for the mean) and `D = B1 B2`,
//!
//! ```text
//! dS/dmu_x = 2 mu_y (A2 - A1) / D - 2 mu_x S (1/B1 - 1/B2)
//! dS/dG(x^2) = -S / B2      dS/dG(xy) = 2 A1 / D
//! dL/dx = G^T(g dS/dmu_x) + 2 x G^T(g dS/dG(x^2)) + y G^T(g dS/dG(xy))
//! ```
//!
//! and the same for `y` with the roles of `x` and `y` swapped. The 1D Gaussian is
//! symmetric, so under zero "same" padding the blur is its own adjoint (`G^T = G`):
//! the VJP is a few elementwise terms plus three blurs of gradient maps (four when
//! both inputs need a gradient). See crates.md section 3.
//!
//! Note this is the *training* convention. The evaluation metric
//! ([`crate::metrics::ssim`]) follows scikit-image and crops the border instead.

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};

/// Side of the SSIM window (11 taps).
pub const SSIM_WINDOW: usize = 11;
/// Standard deviation of the SSIM Gaussian window, in pixels.
pub const SSIM_SIGMA: f64 = 1.5;
/// `C1 = (K1 L)^2` with `K1 = 0.01` and data range `L = 1` (Wang et al. 2004).
pub const SSIM_C1: f64 = 0.01 * 0.01;
/// `C2 = (K2 L)^2` with `K2 = 0.03` and data range `L = 1` (Wang et al. 2004).
pub const SSIM_C2: f64 = 0.03 * 0.03;

/// Normalised 1D Gaussian taps `w_k = exp(-(k - r)^2 / (2 sigma^2)) / sum`,
/// `k = 0..size`, `r = size / 2` (the 3DGS `gaussian(window_size, sigma)`; the same as
/// scipy's `_gaussian_kernel1d` for `size = 2r + 1`).
pub fn gaussian_taps(size: usize, sigma: f64) -> Vec<f64> {
    assert!(size % 2 == 1, "gaussian_taps: size {size} must be odd");
    let r = (size / 2) as f64;
    let raw: Vec<f64> = (0..size)
        .map(|k| {
            let d = k as f64 - r;
            (-d * d / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let total: f64 = raw.iter().sum();
    raw.into_iter().map(|w| w / total).collect()
}

/// Separable blur of an interleaved `[h, w, c]` image with symmetric odd-length taps
/// and zero-padded "same" borders:
/// `out[i, j] = sum_{a, b} taps[a] taps[b] img[i + a - r, j + b - r]`, out-of-range
/// samples read as 0 (weights are not renormalised at the border). Because `taps` is
/// symmetric this linear map is self-adjoint, so it also computes its own transpose.
pub fn blur_same<T: Float>(img: &[T], h: usize, w: usize, c: usize, taps: &[T]) -> Vec<T> {
    assert_eq!(
        img.len(),
        h * w * c,
        "blur_same: {} values for [{h}, {w}, {c}]",
        img.len()
    );
    let r = taps.len() / 2;
    let row = w * c;
    // Horizontal pass, one tap at a time: for tap `k` (offset `k - r`), every output
    // pixel `j` whose source `j + k - r` is in range gets `taps[k] * src[j + k - r]`;
    // both ranges are contiguous in the interleaved row, so this is a plain axpy.
    let mut tmp = vec![T::zero(); img.len()];
    for i in 0..h {
        let src = &img[i * row..(i + 1) * row];
        let dst = &mut tmp[i * row..(i + 1) * row];
        for (k, &wt) in taps.iter().enumerate() {
            // Output pixels j in [j0, j1) read source pixels j + k - r in [0, w).
            let j0 = r.saturating_sub(k);
            let j1 = (w + r).saturating_sub(k).min(w);
            if j0 >= j1 {
                continue;
            }
            let s0 = j0 + k - r;
            let len = (j1 - j0) * c;
            for (d, &v) in dst[j0 * c..j0 * c + len]
                .iter_mut()
                .zip(&src[s0 * c..s0 * c + len])
            {
                *d += wt * v;
            }
        }
    }
    // Vertical pass: whole rows at a time, contiguous in memory.
    let mut out = vec![T::zero(); img.len()];
    for i in 0..h {
        let lo = i.saturating_sub(r);
        let hi = (i + r).min(h - 1);
        let dst = &mut out[i * row..(i + 1) * row];
        for ii in lo..=hi {
            let wt = taps[ii + r - i];
            for (d, &v) in dst.iter_mut().zip(&tmp[ii * row..(ii + 1) * row]) {
                *d += wt * v;
            }
        }
    }
    out
}

/// What the [`Ssim`] op returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SsimOutput {
    /// The mean of the SSIM map over pixels and channels (rank-0): the training loss path.
    Mean,
    /// The SSIM map itself, `[H, W, C]` (for per-pixel weighting and for VJP tests with
    /// arbitrary cotangents).
    Map,
}

/// SSIM of two images `x`, `y` of shape `[H, W, C]` (module docs for the formula), as
/// one op with a hand-written backward. Both inputs may receive gradients; in training
/// `y` is the ground truth, a constant.
#[derive(Clone, Debug)]
pub struct Ssim {
    /// Mean or map output.
    pub output: SsimOutput,
    /// 1D window taps (default [`gaussian_taps`]`(11, 1.5)`).
    pub taps: Vec<f64>,
    /// Stabiliser of the luminance term.
    pub c1: f64,
    /// Stabiliser of the contrast-structure term.
    pub c2: f64,
}

impl Ssim {
    /// The standard 3DGS SSIM: 11 x 11 window, sigma 1.5, `C1 = 0.01^2`, `C2 = 0.03^2`.
    pub fn new(output: SsimOutput) -> Self {
        Ssim {
            output,
            taps: gaussian_taps(SSIM_WINDOW, SSIM_SIGMA),
            c1: SSIM_C1,
            c2: SSIM_C2,
        }
    }
}

/// Per-pixel maps the backward needs, kept from the forward.
pub struct SsimSaved<T> {
    mu_x: Vec<T>,
    mu_y: Vec<T>,
    a1: Vec<T>,
    a2: Vec<T>,
    b1: Vec<T>,
    b2: Vec<T>,
    s: Vec<T>,
}

fn image_dims(t: &[usize], what: &str) -> (usize, usize, usize) {
    assert!(
        t.len() == 3 && t.iter().all(|&d| d > 0),
        "ssim: {what} must be a non-empty [H, W, C] image, got shape {t:?}"
    );
    (t[0], t[1], t[2])
}

/// Elementwise product of two equal-length slices.
fn mul<T: Float>(a: &[T], b: &[T]) -> Vec<T> {
    a.iter().zip(b).map(|(&p, &q)| p * q).collect()
}

/// Forward of SSIM: the per-pixel map plus everything the backward reuses.
fn ssim_forward<T: Float>(op: &Ssim, x: &Tensor<T>, y: &Tensor<T>) -> SsimSaved<T> {
    let (h, w, c) = image_dims(x.shape(), "x");
    assert_eq!(
        x.shape(),
        y.shape(),
        "ssim: image shapes {:?} and {:?} differ",
        x.shape(),
        y.shape()
    );
    let taps: Vec<T> = op.taps.iter().map(|&t| T::of(t)).collect();
    let (xd, yd) = (x.data(), y.data());
    let blur = |v: &[T]| blur_same(v, h, w, c, &taps);
    let mu_x = blur(xd);
    let mu_y = blur(yd);
    let e_xx = blur(&mul(xd, xd));
    let e_yy = blur(&mul(yd, yd));
    let e_xy = blur(&mul(xd, yd));
    let (c1, c2, two) = (T::of(op.c1), T::of(op.c2), T::of(2.0));
    let n = xd.len();
    let mut saved = SsimSaved {
        mu_x: Vec::with_capacity(n),
        mu_y: Vec::with_capacity(n),
        a1: Vec::with_capacity(n),
        a2: Vec::with_capacity(n),
        b1: Vec::with_capacity(n),
        b2: Vec::with_capacity(n),
        s: Vec::with_capacity(n),
    };
    for k in 0..n {
        let (mx, my) = (mu_x[k], mu_y[k]);
        let sxx = e_xx[k] - mx * mx;
        let syy = e_yy[k] - my * my;
        let sxy = e_xy[k] - mx * my;
        let a1 = two * mx * my + c1;
        let a2 = two * sxy + c2;
        let b1 = mx * mx + my * my + c1;
        let b2 = sxx + syy + c2;
        saved.s.push(a1 * a2 / (b1 * b2));
        saved.a1.push(a1);
        saved.a2.push(a2);
        saved.b1.push(b1);
        saved.b2.push(b2);
    }
    saved.mu_x = mu_x;
    saved.mu_y = mu_y;
    saved
}

/// Adjoint blur used by the backward; a parameter so the tests can inject a wrong one.
type AdjointBlur<'a, T> = &'a dyn Fn(&[T]) -> Vec<T>;

/// VJP of the SSIM map: `g` is the cotangent of every map entry. Returns
/// `(dL/dx, dL/dy)`, each only when asked for.
fn ssim_backward<T: Float>(
    x: &[T],
    y: &[T],
    st: &SsimSaved<T>,
    g: &dyn Fn(usize) -> T,
    need: (bool, bool),
    blur_t: AdjointBlur<'_, T>,
) -> (Option<Vec<T>>, Option<Vec<T>>) {
    let n = x.len();
    let two = T::of(2.0);
    // Shared maps: cotangents of G(x^2) (= that of G(y^2)) and of G(xy).
    let mut g_sq = Vec::with_capacity(n);
    let mut g_xy = Vec::with_capacity(n);
    let mut g_mx = Vec::with_capacity(if need.0 { n } else { 0 });
    let mut g_my = Vec::with_capacity(if need.1 { n } else { 0 });
    for k in 0..n {
        let (a1, a2, b1, b2, s) = (st.a1[k], st.a2[k], st.b1[k], st.b2[k], st.s[k]);
        let gk = g(k);
        let d = b1 * b2;
        // dS/dA1 = A2/D, dS/dA2 = A1/D, dS/dB1 = -S/B1, dS/dB2 = -S/B2; no division by
        // A1 or A2, which may vanish.
        let da1 = a2 / d;
        let da2 = a1 / d;
        let db1 = -s / b1;
        let db2 = -s / b2;
        g_sq.push(gk * db2);
        g_xy.push(gk * two * da2);
        // mu_x enters A1 (2 mu_y), A2 (-2 mu_y), B1 (2 mu_x), B2 (-2 mu_x).
        let (mx, my) = (st.mu_x[k], st.mu_y[k]);
        if need.0 {
            g_mx.push(gk * two * (my * (da1 - da2) + mx * (db1 - db2)));
        }
        if need.1 {
            g_my.push(gk * two * (mx * (da1 - da2) + my * (db1 - db2)));
        }
    }
    let b_sq = blur_t(&g_sq);
    let b_xy = blur_t(&g_xy);
    let dx = need.0.then(|| {
        let b_mx = blur_t(&g_mx);
        (0..n)
            .map(|k| b_mx[k] + two * x[k] * b_sq[k] + y[k] * b_xy[k])
            .collect()
    });
    let dy = need.1.then(|| {
        let b_my = blur_t(&g_my);
        (0..n)
            .map(|k| b_my[k] + two * y[k] * b_sq[k] + x[k] * b_xy[k])
            .collect()
    });
    (dx, dy)
}

impl<T: Float> Op<T> for Ssim {
    type Saved = SsimSaved<T>;

    fn name(&self) -> String {
        match self.output {
            SsimOutput::Mean => "ssim".into(),
            SsimOutput::Map => "ssim_map".into(),
        }
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, SsimSaved<T>) {
        assert_eq!(inputs.len(), 2, "ssim: expects 2 inputs (x, y)");
        let saved = ssim_forward(self, inputs[0], inputs[1]);
        let out = match self.output {
            SsimOutput::Mean => {
                // Accumulate in f64: 1.2e5 f32 terms summed naively lose ~1e-3 relative.
                let total: f64 = saved.s.iter().map(|&v| Float::to_f64(v)).sum();
                Tensor::scalar(T::of(total / saved.s.len() as f64))
            }
            SsimOutput::Map => Tensor::from_vec(saved.s.clone(), inputs[0].shape()),
        };
        (vec![out], saved)
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, SsimSaved<T>>) -> Vec<Option<Tensor<T>>> {
        let (x, y) = (ctx.inputs[0], ctx.inputs[1]);
        let (h, w, c) = image_dims(x.shape(), "x");
        let taps: Vec<T> = self.taps.iter().map(|&t| T::of(t)).collect();
        let blur = |v: &[T]| blur_same(v, h, w, c, &taps);
        let go = &ctx.grad_outputs[0];
        let need = (ctx.needs_grad[0], ctx.needs_grad[1]);
        let (dx, dy) = match self.output {
            SsimOutput::Mean => {
                let gm = go.item() / T::of(x.len() as f64);
                ssim_backward(x.data(), y.data(), ctx.saved, &|_| gm, need, &blur)
            }
            SsimOutput::Map => {
                let gd = go.data();
                ssim_backward(x.data(), y.data(), ctx.saved, &|k| gd[k], need, &blur)
            }
        };
        vec![
            dx.map(|d| Tensor::from_vec(d, x.shape())),
            dy.map(|d| Tensor::from_vec(d, y.shape())),
        ]
    }
}

/// Mean SSIM of `x` and `y` (`[H, W, C]`, 3DGS training convention; module docs), as
/// a rank-0 `Var`. Differentiable in both arguments.
pub fn ssim<'t, T: Float>(x: Var<'t, T>, y: Var<'t, T>) -> Var<'t, T> {
    x.tape().apply1(Ssim::new(SsimOutput::Mean), &[x, y])
}

/// The SSIM map of `x` and `y`, shape `[H, W, C]` (module docs).
pub fn ssim_map<'t, T: Float>(x: Var<'t, T>, y: Var<'t, T>) -> Var<'t, T> {
    x.tape().apply1(Ssim::new(SsimOutput::Map), &[x, y])
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::Tape;
    use maaf_autodiff::check::{
        GradcheckConfig, check_vjp, compare, gradcheck, tests_support::random_tensor,
    };

    /// Slow, independent reference: for every pixel and channel, the weighted moments
    /// over the 11 x 11 window with the 2D weight `w_a w_b`, skipping out-of-range
    /// samples (zero padding), all in f64.
    fn reference_map(x: &Tensor<f64>, y: &Tensor<f64>) -> Vec<f64> {
        let (h, w, c) = (x.shape()[0], x.shape()[1], x.shape()[2]);
        let taps = gaussian_taps(11, 1.5);
        let at = |t: &Tensor<f64>, i: usize, j: usize, ch: usize| t.data()[(i * w + j) * c + ch];
        let mut out = Vec::new();
        for i in 0..h {
            for j in 0..w {
                for ch in 0..c {
                    let (mut mx, mut my, mut xx, mut yy, mut xy) = (0.0, 0.0, 0.0, 0.0, 0.0);
                    for a in 0..11 {
                        for b in 0..11 {
                            let (ii, jj) =
                                (i as isize + a as isize - 5, j as isize + b as isize - 5);
                            if ii < 0 || jj < 0 || ii >= h as isize || jj >= w as isize {
                                continue;
                            }
                            let wt = taps[a] * taps[b];
                            let (p, q) = (
                                at(x, ii as usize, jj as usize, ch),
                                at(y, ii as usize, jj as usize, ch),
                            );
                            mx += wt * p;
                            my += wt * q;
                            xx += wt * p * p;
                            yy += wt * q * q;
                            xy += wt * p * q;
                        }
                    }
                    let (c1, c2) = (1e-4, 9e-4);
                    let num = (2.0 * mx * my + c1) * (2.0 * (xy - mx * my) + c2);
                    let den = (mx * mx + my * my + c1) * (xx - mx * mx + yy - my * my + c2);
                    out.push(num / den);
                }
            }
        }
        out
    }

    /// A pair of images: `x` random in [0, 1], `y` a correlated noisy copy, so that the
    /// SSIM is neither ~0 nor ~1 and every term of the backward matters.
    fn pair(shape: &[usize], seed: u64) -> (Tensor<f64>, Tensor<f64>) {
        let x: Tensor<f64> = random_tensor(shape, 0.0, 1.0, seed);
        let noise: Tensor<f64> = random_tensor(shape, -0.3, 0.3, seed + 100);
        let y = x.zip_map(&noise, |a, n| (0.7 * a + 0.15 + n).clamp(0.0, 1.0));
        (x, y)
    }

    /// Banded matrix `M[i, j] = taps[j - i + r]` (zero outside the band): `M v` is the
    /// zero-padded "same" 1D blur of `v`.
    fn band(n: usize, taps: &[f64]) -> Tensor<f64> {
        let r = taps.len() / 2;
        let mut m = Tensor::zeros(&[n, n]);
        for i in 0..n {
            for j in 0..n {
                let d = j as isize - i as isize + r as isize;
                if d >= 0 && (d as usize) < taps.len() {
                    m.data_mut()[i * n + j] = taps[d as usize];
                }
            }
        }
        m
    }

    /// The blur from tape primitives: `X [H, W*C] -> B_H X K` with
    /// `K[(w, c), (w', c')] = B_W[w', w] delta(c, c')`, both constants.
    fn blur_ref<'t>(
        t: &'t Tape<f64>,
        v: Var<'t, f64>,
        h: usize,
        w: usize,
        c: usize,
    ) -> Var<'t, f64> {
        let taps = gaussian_taps(11, 1.5);
        let bh = t.constant(band(h, &taps));
        let bw = band(w, &taps);
        let mut k = Tensor::zeros(&[w * c, w * c]);
        for wo in 0..w {
            for wi in 0..w {
                for ch in 0..c {
                    k.data_mut()[(wi * c + ch) * (w * c) + wo * c + ch] = bw.data()[wo * w + wi];
                }
            }
        }
        let k = t.constant(k);
        bh.matmul(v.reshape(&[h, w * c]))
            .matmul(k)
            .reshape(&[h, w, c])
    }

    /// The SSIM map from tape primitives only (no fused op).
    fn ssim_map_ref<'t>(t: &'t Tape<f64>, x: Var<'t, f64>, y: Var<'t, f64>) -> Var<'t, f64> {
        let s = x.shape();
        let (h, w, c) = (s[0], s[1], s[2]);
        let g = |v| blur_ref(t, v, h, w, c);
        let (mx, my) = (g(x), g(y));
        let sxx = g(x * x) - mx * mx;
        let syy = g(y * y) - my * my;
        let sxy = g(x * y) - mx * my;
        let a1 = (mx * my).scale(2.0).add_scalar(SSIM_C1);
        let a2 = sxy.scale(2.0).add_scalar(SSIM_C2);
        let b1 = (mx * mx + my * my).add_scalar(SSIM_C1);
        let b2 = (sxx + syy).add_scalar(SSIM_C2);
        (a1 * a2) / (b1 * b2)
    }

    #[test]
    fn taps_match_the_closed_form() {
        let t = gaussian_taps(11, 1.5);
        assert!((t.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        // Centre tap: 1 / sum_k exp(-k^2 / 4.5), k = -5..=5.
        let z: f64 = (-5..=5).map(|k: i32| (-(k * k) as f64 / 4.5).exp()).sum();
        assert!((t[5] - 1.0 / z).abs() < 1e-15);
        assert_eq!(t[0], t[10]);
    }

    #[test]
    fn forward_matches_direct_windowed_reference() {
        for (shape, seed) in [([13usize, 11, 3], 1u64), ([7, 16, 3], 2), ([24, 20, 1], 3)] {
            let (x, y) = pair(&shape, seed);
            let expect = reference_map(&x, &y);
            let t = Tape::new();
            let (xv, yv) = (t.constant(x.clone()), t.constant(y.clone()));
            // f64: separable vs direct summation differ only by rounding (~1e-15 on
            // O(1) values, amplified by the 1/(B1 B2) division by at most ~1e2).
            let map = ssim_map(xv, yv);
            let c = compare(
                &map.value(),
                &Tensor::from_vec(expect.clone(), &shape),
                1e-12,
                0.0,
            );
            assert!(c.passed(), "{shape:?}: max err {:e}", c.max_abs_err);
            let mean = ssim(xv, yv).value().item();
            let expect_mean = expect.iter().sum::<f64>() / expect.len() as f64;
            assert!(
                (mean - expect_mean).abs() < 1e-12,
                "{mean} vs {expect_mean}"
            );
            // f32: the moments carry ~1e-7 relative error; s_xy = E[xy] - mu_x mu_y
            // cancels O(1) terms to O(1e-2) and B2 can be as small as C2 ~ 1e-3, so the
            // map agrees to ~1e-4 absolute; the mean, averaging independent errors, to 1e-5.
            let t32 = Tape::<f32>::new();
            let m32 = ssim(t32.constant(x.cast()), t32.constant(y.cast()))
                .value()
                .item();
            assert!(
                (m32 as f64 - expect_mean).abs() < 1e-5,
                "{m32} vs {expect_mean}"
            );
        }
    }

    #[test]
    fn identical_images_give_one() {
        let x: Tensor<f64> = random_tensor(&[9, 12, 3], 0.0, 1.0, 5);
        let t = Tape::new();
        let v = t.constant(x);
        assert!((ssim(v, v).value().item() - 1.0).abs() < 1e-14);
    }

    #[test]
    fn mean_ssim_passes_gradcheck_in_both_inputs() {
        // Gradients of the mean are O(1/N) ~ 1e-3 (N = 429), so the default atol 1e-7
        // would hide a wrong term. Central differences with eps 1e-6 on an O(1) output
        // carry ~1e-16 / 1e-6 = 1e-10 of roundoff (observed max 4e-10), hence
        // atol 2e-9: ~1e-6 of a typical entry, 5x above the roundoff.
        let (x, y) = pair(&[13, 11, 3], 7);
        let cfg = GradcheckConfig::default().with_tol(2e-9, 1e-5);
        let r = gradcheck(|_, v| ssim(v[0], v[1]), &[x, y], &cfg);
        assert!(r.passed(), "{r}");
    }

    #[test]
    fn ssim_map_passes_gradcheck() {
        // Random cotangent over the whole map: exercises per-pixel g, not just its mean.
        let (x, y) = pair(&[9, 8, 2], 8);
        let r = gradcheck(
            |_, v| ssim_map(v[0], v[1]),
            &[x, y],
            &GradcheckConfig::default(),
        );
        assert!(r.passed(), "{r}");
    }

    #[test]
    fn vjp_matches_the_primitive_reference() {
        // Same function two ways in f64: the only differences are summation order, so
        // 1e-11 absolute (values are O(1), map gradients O(10)) with rtol 1e-9.
        let (x, y) = pair(&[13, 11, 3], 9);
        let cfg = GradcheckConfig::default().with_tol(1e-11, 1e-9);
        let r = check_vjp(
            |_, v| vec![ssim_map(v[0], v[1]), ssim(v[0], v[1])],
            |t, v| {
                let m = ssim_map_ref(t, v[0], v[1]);
                vec![m, m.mean()]
            },
            &[x, y],
            3,
            &cfg,
        );
        assert!(r.passed(), "{r}");
    }

    #[test]
    fn constant_ground_truth_gets_no_gradient() {
        let (x, y) = pair(&[6, 7, 3], 10);
        let t = Tape::new();
        let (xv, yv) = (t.var(x), t.constant(y));
        let g = t.backward(ssim(xv, yv)).expect("finite");
        assert!(g.wrt(xv).is_some());
        assert!(g.wrt(yv).is_none());
    }

    /// Wraps the real forward with a deliberately wrong backward.
    struct Faulty {
        inner: Ssim,
        fault: Fault,
    }
    #[derive(Clone, Copy)]
    enum Fault {
        /// The classic border bug: an adjoint blur that renormalises the weights at
        /// the image edge (right only for "valid"/renormalised padding, not zero "same").
        RenormalisedBorderAdjoint,
        /// Treating the blur as pointwise in the chain rule (no adjoint blur of the
        /// gradient maps).
        MissingAdjointBlur,
    }
    impl Op<f64> for Faulty {
        type Saved = SsimSaved<f64>;
        fn name(&self) -> String {
            "faulty_ssim".into()
        }
        fn forward(&self, i: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, SsimSaved<f64>) {
            self.inner.forward(i)
        }
        fn backward(&self, ctx: &BackwardCtx<'_, f64, SsimSaved<f64>>) -> Vec<Option<Tensor<f64>>> {
            let (x, y) = (ctx.inputs[0], ctx.inputs[1]);
            let s = x.shape();
            let (h, w, c) = (s[0], s[1], s[2]);
            let taps = gaussian_taps(11, 1.5);
            let gm = ctx.grad_outputs[0].item() / x.len() as f64;
            let need = (ctx.needs_grad[0], ctx.needs_grad[1]);
            let (dx, _) = match self.fault {
                Fault::RenormalisedBorderAdjoint => {
                    let ones = vec![1.0; h * w * c];
                    let norm = blur_same(&ones, h, w, c, &taps);
                    let bad = |v: &[f64]| {
                        blur_same(v, h, w, c, &taps)
                            .iter()
                            .zip(&norm)
                            .map(|(a, n)| a / n)
                            .collect()
                    };
                    ssim_backward(x.data(), y.data(), ctx.saved, &|_| gm, need, &bad)
                }
                Fault::MissingAdjointBlur => {
                    let identity = |v: &[f64]| v.to_vec();
                    ssim_backward(x.data(), y.data(), ctx.saved, &|_| gm, need, &identity)
                }
            };
            vec![dx.map(|d| Tensor::from_vec(d, s)), None]
        }
    }

    #[test]
    fn negative_controls_wrong_backwards_are_rejected() {
        let (x, y) = pair(&[13, 11, 3], 11);
        // Same tolerances as the passing check above; the faults give errors ~5e-3.
        let cfg = GradcheckConfig::default().with_tol(2e-9, 1e-5);
        for fault in [Fault::RenormalisedBorderAdjoint, Fault::MissingAdjointBlur] {
            let r = gradcheck(
                |t, v| {
                    let gt = t.constant(y.clone());
                    t.apply1(
                        Faulty {
                            inner: Ssim::new(SsimOutput::Mean),
                            fault,
                        },
                        &[v[0], gt],
                    )
                },
                std::slice::from_ref(&x),
                &cfg,
            );
            assert!(!r.passed(), "a wrong backward passed gradcheck");
            // Both faults are caught at most coordinates (13 x 11 is mostly border).
            assert!(!r.failures().is_empty());
        }
    }
}
