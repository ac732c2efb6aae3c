//! Checks of the fused SSIM op: forward against a direct windowed loop, gradcheck and
//! VJP against a composition of tape primitives, negative controls with wrong backwards.

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
                        let (ii, jj) = (i as isize + a as isize - 5, j as isize + b as isize - 5);
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
fn blur_ref<'t>(t: &'t Tape<f64>, v: Var<'t, f64>, h: usize, w: usize, c: usize) -> Var<'t, f64> {
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
