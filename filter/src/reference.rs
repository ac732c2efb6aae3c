//! Brute-force Algorithm 1, literally (the double loop over `d` and `s` with the
//! sum over every observation slot inside), in f64. Slow (`O(J D T)` per
//! Gaussian) and kept as the test oracle for [`crate::MotionCurves::refresh`];
//! it materialises the full `D x T` density, as the paper does.
//!
//! It evaluates the same (truncated) kernels as the fast path ([`Kernels`]); the
//! truncation itself is measured against untruncated kernels in the tests.
//!
//! [`window_max`] is the same kind of oracle for maaf's windowed-maximum estimator.

use crate::config::FilterConfig;
use crate::curves::FALLBACK;
use crate::kernels::Kernels;

/// The paper's per-Gaussian output: `x_max` and the full density `rho[d * T + s]`.
#[derive(Clone, Debug)]
pub struct Algorithm1 {
    /// `x_max = max_j v_j x_j` (line 3); 0 if no slot is valid.
    pub x_max: f64,
    /// `rho[d, s]`, row-major `D x T` (line 7).
    pub rho: Vec<f64>,
    /// D.
    pub grid_x: usize,
    /// T.
    pub grid_t: usize,
}

/// Runs Algorithm 1 lines 1-9 for one Gaussian. `times[j]` are *normalised* times
/// (the paper's [0, 1] axis) with empty slots flagged by `t_j < 0` (line 2);
/// `xs[j] = f_j / d_j`.
pub fn algorithm1(times: &[f64], xs: &[f64], cfg: &FilterConfig, kern: &Kernels) -> Algorithm1 {
    let (dn, tn) = (cfg.grid_x, cfg.grid_t);
    // Line 2: v_j = 1[t_j >= 0].
    let v: Vec<f64> = times
        .iter()
        .map(|&t| if t >= 0.0 { 1.0 } else { 0.0 })
        .collect();
    // Line 3: x_max and normalisation.
    let x_max = xs.iter().zip(&v).map(|(x, v)| v * x).fold(0.0f64, f64::max);
    let xbar: Vec<f64> = xs.iter().map(|x| x / x_max).collect();
    // Line 4: Linspace grids.
    let gx: Vec<f64> = (0..dn).map(|d| d as f64 / (dn - 1) as f64).collect();
    let gt: Vec<f64> = (0..tn).map(|s| s as f64 / (tn - 1) as f64).collect();
    let mut rho = vec![0.0; dn * tn];
    if x_max > 0.0 {
        // Lines 5-9.
        for d in 0..dn {
            for s in 0..tn {
                let mut sum = 0.0;
                for j in 0..xs.len() {
                    if v[j] == 0.0 {
                        continue;
                    }
                    sum += kern.weibull((gx[d] - xbar[j]) / kern.h_x)
                        * kern.gauss((gt[s] - times[j]) / kern.h_t);
                }
                rho[d * tn + s] = sum / (2.0 * kern.h_x * kern.h_t);
            }
        }
    }
    Algorithm1 {
        x_max,
        rho,
        grid_x: dn,
        grid_t: tn,
    }
}

impl Algorithm1 {
    /// Lines 11-12 for every time bin: `d* = argmax_d rho[d, s]` (first maximum),
    /// or [`FALLBACK`] when `max_d rho[d, s] <= floor`.
    pub fn codes(&self, floor: f64) -> Vec<u8> {
        (0..self.grid_t)
            .map(|s| {
                let (mut best, mut best_d) = (f64::NEG_INFINITY, 0);
                for d in 0..self.grid_x {
                    let v = self.rho[d * self.grid_t + s];
                    if v > best {
                        best = v;
                        best_d = d;
                    }
                }
                if best > floor { best_d as u8 } else { FALLBACK }
            })
            .collect()
    }

    /// `rho[d, s]`.
    pub fn at(&self, d: usize, s: usize) -> f64 {
        self.rho[d * self.grid_t + s]
    }
}

/// maaf's windowed maximum ([`crate::MotionEstimator::WindowMax`]), literally: for
/// each time bin `g_t[s] = s / (T - 1)`, the largest `x_j` of a valid slot with
/// `|g_t[s] - t_j| <= h_t`, or `None` when the window holds no observation.
/// `times` are normalised, empty slots flagged by `t_j < 0` (as [`algorithm1`]).
pub fn window_max(times: &[f64], xs: &[f64], cfg: &FilterConfig) -> Vec<Option<f64>> {
    (0..cfg.grid_t)
        .map(|s| {
            let gs = s as f64 / (cfg.grid_t - 1) as f64;
            let mut best: Option<f64> = None;
            for (&t, &x) in times.iter().zip(xs) {
                if t >= 0.0 && (gs - t).abs() <= f64::from(cfg.h_t) {
                    best = Some(best.map_or(x, |b| b.max(x)));
                }
            }
            best
        })
        .collect()
}
