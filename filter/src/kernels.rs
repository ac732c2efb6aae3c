//! The two Parzen kernels of Algorithm 1, shared by the fast refresh and the
//! brute-force oracle so that both evaluate exactly the same density.
//!
//! * Weibull (Alg. 1 line 1): `K_w(u) = (k/lambda) (u/lambda)^(k-1) exp(-(u/lambda)^k) 1[u >= 0]`,
//!   evaluated at `u = (g_x[d] - xbar_j) / h_x` (Alg. 1 line 7). The indicator makes
//!   the kernel one-sided: an observation only adds density at grid points *above*
//!   it, and (for k > 1) nothing at `u = 0` itself. With k = 10 it peaks at
//!   `u = lambda ((k-1)/k)^(1/k) = 0.99 lambda`.
//! * Gaussian (Alg. 1 line 1): `K_g(u) = exp(-u^2/2) / sqrt(2 pi)` at
//!   `u = (g_t[s] - t_j) / h_t`.
//!
//! Both are truncated (configurable, [`FilterConfig::weibull_cutoff`] and
//! [`FilterConfig::time_support`]) so that the fast path can visit only the grid
//! points an observation reaches.

use crate::config::FilterConfig;

/// Pre-computed kernel constants for one configuration.
#[derive(Clone, Debug)]
pub struct Kernels {
    /// Weibull shape k.
    pub k: f64,
    /// Weibull scale lambda.
    pub lambda: f64,
    /// Bandwidth in f/d.
    pub h_x: f64,
    /// Bandwidth in time.
    pub h_t: f64,
    /// Weibull support in `u`: the kernel is zero outside `[u_lo, u_hi]`.
    pub u_lo: f64,
    /// Upper end of the Weibull support in `u`.
    pub u_hi: f64,
    /// Mode of the Weibull kernel in `u`: `lambda ((k-1)/k)^(1/k)`.
    pub u_mode: f64,
    /// Gaussian support in `u`: zero for `|u| > t_support`.
    pub t_support: f64,
    /// Exponent `k - 1` as a small integer when it is one (faster `powi`).
    km1_int: Option<i32>,
}

impl Kernels {
    /// Constants for `cfg` (assumed validated). The Weibull support is where
    /// `K_w(u) >= weibull_cutoff * max K_w`, found by bisection on each monotone side
    /// of the mode `v_m = ((k-1)/k)^(1/k)` (in `v = u/lambda`).
    pub fn new(cfg: &FilterConfig) -> Kernels {
        let k = cfg.weibull_k as f64;
        let lambda = cfg.weibull_lambda as f64;
        let eps = cfg.weibull_cutoff as f64;
        // Shape of the kernel in v = u / lambda, without constant factors.
        let shape = |v: f64| v.powf(k - 1.0) * (-v.powf(k)).exp();
        let v_mode = ((k - 1.0) / k).powf(1.0 / k);
        let target = eps * shape(v_mode);
        let bisect = |mut lo: f64, mut hi: f64, rising: bool| {
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                let above = shape(mid) >= target;
                if above == rising {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            if rising { lo } else { hi }
        };
        let v_lo = if k > 1.0 {
            bisect(0.0, v_mode, true)
        } else {
            0.0
        };
        let mut v_top = v_mode.max(1.0) * 2.0;
        while shape(v_top) >= target {
            v_top *= 2.0;
        }
        let v_hi = bisect(v_mode, v_top, false);
        let km1 = k - 1.0;
        let km1_int = (km1.fract() == 0.0 && km1 <= 64.0).then_some(km1 as i32);
        Kernels {
            k,
            lambda,
            h_x: cfg.h_x as f64,
            h_t: cfg.h_t as f64,
            u_lo: v_lo * lambda,
            u_hi: v_hi * lambda,
            u_mode: v_mode * lambda,
            t_support: cfg.time_support as f64,
            km1_int,
        }
    }

    /// Truncated Weibull kernel in f64 (oracle): `K_w(u)` on `[u_lo, u_hi]`, else 0.
    pub fn weibull(&self, u: f64) -> f64 {
        if !(u >= self.u_lo && u <= self.u_hi) || u < 0.0 {
            return 0.0;
        }
        let v = u / self.lambda;
        let p = v.powf(self.k - 1.0);
        self.k / self.lambda * p * (-(p * v)).exp()
    }

    /// Truncated Gaussian kernel in f64 (oracle): `K_g(u)` for `|u| <= t_support`, else 0.
    pub fn gauss(&self, u: f64) -> f64 {
        if u.abs() > self.t_support {
            return 0.0;
        }
        (-0.5 * u * u).exp() / (2.0 * std::f64::consts::PI).sqrt()
    }

    /// The same Weibull kernel in f32 (fast path).
    pub(crate) fn weibull_f32(&self) -> WeibullF32 {
        WeibullF32 {
            u_lo: self.u_lo as f32,
            u_hi: self.u_hi as f32,
            inv_lambda: (1.0 / self.lambda) as f32,
            coef: (self.k / self.lambda) as f32,
            km1: (self.k - 1.0) as f32,
            km1_int: self.km1_int,
        }
    }
}

/// f32 copy of the Weibull kernel constants, for the inner loop.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WeibullF32 {
    pub u_lo: f32,
    pub u_hi: f32,
    inv_lambda: f32,
    coef: f32,
    km1: f32,
    km1_int: Option<i32>,
}

impl WeibullF32 {
    /// `K_w(u)` in f32; zero outside the support (same rule as [`Kernels::weibull`]).
    #[inline]
    pub fn eval(&self, u: f32) -> f32 {
        if !(u >= self.u_lo && u <= self.u_hi) || u < 0.0 {
            return 0.0;
        }
        let v = u * self.inv_lambda;
        let p = match self.km1_int {
            Some(n) => v.powi(n),
            None => v.powf(self.km1),
        };
        self.coef * p * (-(p * v)).exp()
    }

    /// Adds `K_w((gx[i] - xb) * inv_hx)` to `out[i]` for every `i` (Alg. 1 line 7's
    /// Weibull factor over a band of grid points). Branch-free and vectorisable when
    /// `k - 1` is an integer up to 15 (the exponent is then a compile-time constant
    /// and `exp` is [`exp_fast`]); other shapes take the scalar [`Self::eval`].
    pub fn add_band(&self, xb: f32, inv_hx: f32, gx: &[f32], out: &mut [f32]) {
        macro_rules! dispatch {
            ($($n:literal)*) => {
                match self.km1_int {
                    $(Some($n) => self.add_band_int::<$n>(xb, inv_hx, gx, out),)*
                    _ => {
                        for (o, &g) in out.iter_mut().zip(gx) {
                            *o += self.eval((g - xb) * inv_hx);
                        }
                    }
                }
            };
        }
        dispatch!(0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15);
    }

    #[inline(always)]
    fn add_band_int<const N: i32>(&self, xb: f32, inv_hx: f32, gx: &[f32], out: &mut [f32]) {
        for (o, &g) in out.iter_mut().zip(gx) {
            let u = (g - xb) * inv_hx;
            let v = u * self.inv_lambda;
            // v^N by squaring; N is a constant, so this unrolls to ~log2(N) multiplies.
            let (mut p, mut base, mut e) = (1.0f32, v, N);
            while e > 0 {
                if e & 1 == 1 {
                    p *= base;
                }
                base *= base;
                e >>= 1;
            }
            let val = self.coef * p * exp_fast(-(p * v));
            // u_lo >= 0, so this also applies the indicator 1[u >= 0].
            let inside = (u >= self.u_lo) & (u <= self.u_hi);
            *o += if inside { val } else { 0.0 };
        }
    }
}

/// `exp(x)` in f32 without branches, so loops over it vectorise: Cody-Waite range
/// reduction `x = n ln2 + r`, `|r| <= ln2/2`, a degree-7 Taylor polynomial for
/// `e^r` (truncation error `r^8/8! < 5e-9`), and `2^n` built from its exponent
/// bits. Relative error a few ulp (tested against f64 `exp`); `x` is clamped to
/// `[-87, 88]` (the f32 normal range).
#[inline(always)]
pub(crate) fn exp_fast(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    // ln 2 split so that n * LN2_HI is exact for |n| < 2^10 (Cephes constants).
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    // Adding then subtracting 1.5 * 2^23 rounds to the nearest integer.
    const MAGIC: f32 = 12_582_912.0;
    let x = x.clamp(-87.0, 88.0);
    let shifted = x * LOG2E + MAGIC;
    let n = shifted - MAGIC;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))));
    // The integer n sits in the low mantissa bits of `shifted`; taking it from
    // there (instead of a saturating `as i32`, which is scalar) keeps the loop SIMD.
    let n_bits = shifted.to_bits().wrapping_sub(MAGIC.to_bits());
    let scale = f32::from_bits(n_bits.wrapping_add(127) << 23);
    p * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weibull_support_brackets_the_mode_and_cuts_at_eps() {
        let cfg = FilterConfig::default();
        let kern = Kernels::new(&cfg);
        let mode = 0.9f64.powf(0.1);
        assert!(kern.u_lo < mode && mode < kern.u_hi);
        let peak = kern.weibull(mode);
        // Just inside the support the kernel is at the cutoff (relative 1e-7 up to
        // bisection precision, hence the factor-2 bracket).
        let inside_lo = kern.weibull(kern.u_lo * (1.0 + 1e-9)) / peak;
        let inside_hi = kern.weibull(kern.u_hi * (1.0 - 1e-9)) / peak;
        assert!((0.5e-7..2e-7).contains(&inside_lo), "{inside_lo}");
        assert!((0.5e-7..2e-7).contains(&inside_hi), "{inside_hi}");
        assert_eq!(kern.weibull(kern.u_lo * 0.99), 0.0);
        assert_eq!(kern.weibull(kern.u_hi * 1.01), 0.0);
        assert_eq!(kern.weibull(-0.1), 0.0);
        // f32 and f64 agree to f32 precision inside the support (a few ulp of
        // exp/pow times the k-fold amplification of the argument's rounding).
        let w = kern.weibull_f32();
        for i in 0..1000 {
            let u = kern.u_lo + (kern.u_hi - kern.u_lo) * (i as f64 + 0.5) / 1000.0;
            let a = kern.weibull(u);
            let b = w.eval(u as f32) as f64;
            assert!((a - b).abs() <= 1e-5 * a, "u {u}: {a} vs {b}");
        }
    }

    #[test]
    fn exp_fast_matches_f64_exp() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -87.0 + 97.0 * i as f64 / 200_000.0;
            let want = (x as f32 as f64).exp();
            let got = exp_fast(x as f32) as f64;
            worst = worst.max((got - want).abs() / want);
        }
        // A few ulp (f32 ulp = 1.2e-7 relative): far inside the 1e-5 tie tolerance
        // of the oracle comparison.
        assert!(worst < 5e-7, "worst relative error {worst}");
    }

    #[test]
    fn add_band_equals_eval() {
        for k in [10.0f32, 2.0, 1.0, 3.5] {
            let cfg = FilterConfig {
                weibull_k: k,
                ..FilterConfig::default()
            };
            let w = Kernels::new(&cfg).weibull_f32();
            let gx: Vec<f32> = (0..101).map(|i| i as f32 / 100.0).collect();
            let mut out = vec![0.0f32; 101];
            w.add_band(0.37, 1.0 / 0.3, &gx, &mut out);
            for (i, &o) in out.iter().enumerate() {
                let want = w.eval((gx[i] - 0.37) / 0.3);
                // 2e-6 relative (exp_fast and the reciprocal bandwidth), plus 1e-6 absolute
                // (~3e-7 of the peak, the truncation level) at the support edges where the
                // two roundings can put a point inside vs outside.
                assert!(
                    (o - want).abs() <= 2e-6 * want + 1e-6,
                    "k {k} i {i}: {o} vs {want}"
                );
            }
        }
    }

    #[test]
    fn k_one_is_exponential_from_zero() {
        let cfg = FilterConfig {
            weibull_k: 1.0,
            ..FilterConfig::default()
        };
        let kern = Kernels::new(&cfg);
        assert_eq!(kern.u_lo, 0.0);
        assert!((kern.weibull(0.0) - 1.0).abs() < 1e-12);
        assert!((kern.u_hi - (1e7f64).ln()).abs() < 1e-3);
    }
}
