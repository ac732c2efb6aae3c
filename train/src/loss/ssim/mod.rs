//! Differentiable SSIM as one fused op with a hand-written backward.
//!
//! Convention (the 3DGS / 4DGS / SaRO-GS training loss, `utils/loss_utils.py::ssim`;
//! docs/conventions.md, "Metrics"): images `[H, W, C]` with values in [0, 1], an 11 x 11
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
//! ([`maaf_scene::metrics::ssim`]) follows scikit-image and crops the border instead.

use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};
pub use maaf_scene::metrics::ssim_window::{
    SSIM_C1, SSIM_C2, SSIM_SIGMA, SSIM_WINDOW, blur_same, gaussian_taps,
};
use rayon::prelude::*;

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

/// The per-pixel terms of the SSIM map that the backward reuses (module docs).
#[derive(Clone, Copy, Debug)]
pub struct PixelTerms<T> {
    mu_x: T,
    mu_y: T,
    a1: T,
    a2: T,
    b1: T,
    b2: T,
    s: T,
}

/// What the forward keeps for the backward: one [`PixelTerms`] per map entry.
pub struct SsimSaved<T> {
    terms: Vec<PixelTerms<T>>,
}

/// Map entries per rayon task of the elementwise passes.
const ENTRIES_PER_TASK: usize = 4096;

fn image_dims(t: &[usize], what: &str) -> (usize, usize, usize) {
    assert!(
        t.len() == 3 && t.iter().all(|&d| d > 0),
        "ssim: {what} must be a non-empty [H, W, C] image, got shape {t:?}"
    );
    (t[0], t[1], t[2])
}

/// `f(k)` for every `k < n`, in parallel blocks; each entry is computed alone, so the
/// result does not depend on the thread count.
fn par_map<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync + Send) -> Vec<T> {
    (0..n)
        .into_par_iter()
        .with_min_len(ENTRIES_PER_TASK)
        .map(f)
        .collect()
}

/// Forward of SSIM: the per-pixel terms, whose `s` is the map.
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
    let n = xd.len();
    let blur = |v: &[T]| blur_same(v, h, w, c, &taps);
    let mu_x = blur(xd);
    let mu_y = blur(yd);
    let e_xx = blur(&par_map(n, |k| xd[k] * xd[k]));
    let e_yy = blur(&par_map(n, |k| yd[k] * yd[k]));
    let e_xy = blur(&par_map(n, |k| xd[k] * yd[k]));
    let (c1, c2, two) = (T::of(op.c1), T::of(op.c2), T::of(2.0));
    let terms = par_map(n, |k| {
        let (mx, my) = (mu_x[k], mu_y[k]);
        let sxx = e_xx[k] - mx * mx;
        let syy = e_yy[k] - my * my;
        let sxy = e_xy[k] - mx * my;
        let a1 = two * mx * my + c1;
        let a2 = two * sxy + c2;
        let b1 = mx * mx + my * my + c1;
        let b2 = sxx + syy + c2;
        PixelTerms {
            mu_x: mx,
            mu_y: my,
            a1,
            a2,
            b1,
            b2,
            s: a1 * a2 / (b1 * b2),
        }
    });
    SsimSaved { terms }
}

/// Adjoint blur used by the backward; a parameter so the tests can inject a wrong one.
type AdjointBlur<'a, T> = &'a (dyn Fn(&[T]) -> Vec<T> + Sync);

/// VJP of the SSIM map: `g` is the cotangent of every map entry. Returns
/// `(dL/dx, dL/dy)`, each only when asked for. Generic in `g` so that the
/// per-entry cotangent inlines into the elementwise passes.
fn ssim_backward<T: Float, G: Fn(usize) -> T + Sync>(
    x: &[T],
    y: &[T],
    st: &SsimSaved<T>,
    g: &G,
    need: (bool, bool),
    blur_t: AdjointBlur<'_, T>,
) -> (Option<Vec<T>>, Option<Vec<T>>) {
    let n = x.len();
    let two = T::of(2.0);
    let terms = &st.terms;
    // dS/dA1 = A2/D, dS/dA2 = A1/D, dS/dB1 = -S/B1, dS/dB2 = -S/B2 with D = B1 B2; no
    // division by A1 or A2, which may vanish. Cotangents of G(x^2) (= that of G(y^2))
    // and of G(xy):
    let b_sq = blur_t(&par_map(n, |k| {
        let t = &terms[k];
        g(k) * (-t.s / t.b2)
    }));
    let b_xy = blur_t(&par_map(n, |k| {
        let t = &terms[k];
        g(k) * two * (t.a1 / (t.b1 * t.b2))
    }));
    // mu_x enters A1 (2 mu_y), A2 (-2 mu_y), B1 (2 mu_x), B2 (-2 mu_x); mu_y likewise.
    let g_mu = |k: usize, mine: T, other: T| {
        let t = &terms[k];
        let d = t.b1 * t.b2;
        let (da1, da2) = (t.a2 / d, t.a1 / d);
        let (db1, db2) = (-t.s / t.b1, -t.s / t.b2);
        g(k) * two * (other * (da1 - da2) + mine * (db1 - db2))
    };
    let dx = need.0.then(|| {
        let b_mx = blur_t(&par_map(n, |k| g_mu(k, terms[k].mu_x, terms[k].mu_y)));
        par_map(n, |k| b_mx[k] + two * x[k] * b_sq[k] + y[k] * b_xy[k])
    });
    let dy = need.1.then(|| {
        let b_my = blur_t(&par_map(n, |k| g_mu(k, terms[k].mu_y, terms[k].mu_x)));
        par_map(n, |k| b_my[k] + two * y[k] * b_sq[k] + x[k] * b_xy[k])
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
                let total: f64 = saved.terms.iter().map(|t| Float::to_f64(t.s)).sum();
                Tensor::scalar(T::of(total / saved.terms.len() as f64))
            }
            SsimOutput::Map => {
                let map = saved.terms.iter().map(|t| t.s).collect();
                Tensor::from_vec(map, inputs[0].shape())
            }
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
mod tests;
