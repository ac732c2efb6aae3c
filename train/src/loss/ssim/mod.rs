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

mod blur;

pub use blur::{blur_same, gaussian_taps};
use maaf_autodiff::{BackwardCtx, Float, Op, Tensor, Var};

/// Side of the SSIM window (11 taps).
pub const SSIM_WINDOW: usize = 11;
/// Standard deviation of the SSIM Gaussian window, in pixels.
pub const SSIM_SIGMA: f64 = 1.5;
/// `C1 = (K1 L)^2` with `K1 = 0.01` and data range `L = 1` (Wang et al. 2004).
pub const SSIM_C1: f64 = 0.01 * 0.01;
/// `C2 = (K2 L)^2` with `K2 = 0.03` and data range `L = 1` (Wang et al. 2004).
pub const SSIM_C2: f64 = 0.03 * 0.03;

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
mod tests;
