//! Storage of the motion-aware sampling rate nu_k(t) (paper Sec. 4): per Gaussian
//! one code per time bin plus `x_max` and a fallback nu, whatever estimator filled
//! the codes (the paper's KDE, `kde.rs`, or maaf's windowed maximum, `window_max.rs`).
//!
//! Fallback: a bin where the estimator found no support (the KDE's density at
//! most `density_floor`, no observation in the window maximum's window) holds
//! [`FALLBACK`] and takes the Gaussian's fallback nu: its `x_max`, i.e.
//! Mip-Splatting's Eq. 2 over all its (camera, time) observations, or the smallest
//! `x_max` seen for a Gaussian never observed. nu is therefore always finite and
//! positive.

use maaf_autodiff::PerGaussian;
use serde::{Deserialize, Serialize};

use crate::config::{FilterConfig, FilterError};
use crate::mip::fill_unseen;

/// Curve code meaning "use the fallback nu" (density ~ 0 in this time bin).
pub const FALLBACK: u8 = u8::MAX;

/// Per-Gaussian motion-aware sampling-rate curves nu_k(t) on the T time bins.
///
/// Storage per Gaussian: `T` bytes (the argmax index `d*` per time bin, or
/// [`FALLBACK`]) plus `x_max` and the fallback nu (f32 each): `T + 8` bytes
/// (108 at T = 100), against the paper's `4 D T` bytes for the density matrix.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionCurves {
    grid_x: usize,
    grid_t: usize,
    time_range: [f32; 2],
    x_max: Vec<f32>,
    fallback: Vec<f32>,
    codes: Vec<u8>,
}

impl MotionCurves {
    /// Curves from an estimator's output: `codes` (`T` per Gaussian, [`FALLBACK`]
    /// where the density is ~0) and each Gaussian's `x_max`; the fallback nu is
    /// `x_max`, or the smallest `x_max` seen for a Gaussian never observed.
    pub(crate) fn from_codes(
        cfg: &FilterConfig,
        codes: Vec<u8>,
        x_max: Vec<f32>,
    ) -> Result<Self, FilterError> {
        let mut fallback = x_max.clone();
        fill_unseen(&mut fallback)?;
        Ok(MotionCurves {
            grid_x: cfg.grid_x,
            grid_t: cfg.grid_t,
            time_range: cfg.time_range,
            x_max,
            fallback,
            codes,
        })
    }

    /// Number of time bins T.
    pub fn grid_t(&self) -> usize {
        self.grid_t
    }

    /// Number of f/d grid points D.
    pub fn grid_x(&self) -> usize {
        self.grid_x
    }

    /// Per-Gaussian `x_max` (Alg. 1 line 3); 0 for a Gaussian never observed.
    pub fn x_max(&self) -> &[f32] {
        &self.x_max
    }

    /// Per-Gaussian fallback nu used where the density is ~0.
    pub fn fallback(&self) -> &[f32] {
        &self.fallback
    }

    /// Replaces the fallback nu (e.g. by the Mip static nu on canonical centres);
    /// values must be finite and positive.
    pub fn set_fallback(&mut self, nu: &[f32]) -> Result<(), FilterError> {
        if nu.len() != self.x_max.len() {
            return Err(FilterError::Shape(format!(
                "set_fallback: {} values for {} Gaussians",
                nu.len(),
                self.x_max.len()
            )));
        }
        if let Some(v) = nu.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(FilterError::Shape(format!(
                "set_fallback: nu {v} must be finite and > 0"
            )));
        }
        self.fallback.copy_from_slice(nu);
        Ok(())
    }

    /// Argmax codes `d*` of Gaussian `n` per time bin ([`FALLBACK`] where density ~ 0).
    pub fn codes(&self, n: usize) -> &[u8] {
        &self.codes[n * self.grid_t..(n + 1) * self.grid_t]
    }

    /// `nu_n` at time bin `s`: `x_max g_x[d*]` (Alg. 1 line 13) or the fallback.
    #[inline]
    pub fn nu(&self, n: usize, s: usize) -> f32 {
        match self.codes[n * self.grid_t + s] {
            FALLBACK => self.fallback[n],
            c => self.x_max[n] * (c as f32 / (self.grid_x - 1) as f32),
        }
    }

    /// The whole curve `nu_n(g_t[s])` of Gaussian `n`, length T.
    pub fn curve(&self, n: usize) -> Vec<f32> {
        (0..self.grid_t).map(|s| self.nu(n, s)).collect()
    }

    /// Time of grid bin `s` in the config's time range.
    pub fn bin_time(&self, s: usize) -> f32 {
        let [t0, t1] = self.time_range;
        t0 + (t1 - t0) * s as f32 / (self.grid_t - 1) as f32
    }

    /// Nearest time bin `s* = argmin_s |g_t[s] - t|` of `t` (Alg. 1 line 11), clamped
    /// to the grid; exact half-way ties go to the lower bin, as a first-index argmin
    /// would. No interpolation between bins, as in the paper.
    pub fn bin_of(&self, t: f32) -> usize {
        let [t0, t1] = self.time_range;
        let pos = (t - t0) / (t1 - t0) * (self.grid_t - 1) as f32;
        if pos.is_nan() || pos <= 0.0 {
            return 0;
        }
        (((pos - 0.5).ceil()) as usize).min(self.grid_t - 1)
    }

    /// Bytes of state per Gaussian: `T` codes + `x_max` + fallback.
    pub fn bytes_per_gaussian(&self) -> usize {
        self.grid_t + 2 * std::mem::size_of::<f32>()
    }
}

impl PerGaussian for MotionCurves {
    fn rows(&self) -> usize {
        self.x_max.len()
    }

    /// Clone/split copy the curve, prune drops it.
    fn select_rows(&mut self, index: &[usize]) {
        let t = self.grid_t;
        let mut codes = Vec::with_capacity(index.len() * t);
        for &i in index {
            codes.extend_from_slice(&self.codes[i * t..(i + 1) * t]);
        }
        self.codes = codes;
        self.x_max.select_rows(index);
        self.fallback.select_rows(index);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bin_of_is_the_nearest_bin() {
        let cfg = FilterConfig::default();
        let curves = MotionCurves::from_codes(&cfg, vec![FALLBACK; cfg.grid_t], vec![1.0])
            .expect("one observed Gaussian");
        for i in 0..=1000 {
            let t = i as f32 / 1000.0 * 1.2 - 0.1;
            let s = curves.bin_of(t);
            let tn = cfg.normalise_time(t);
            let best = (0..cfg.grid_t)
                .map(|s| ((s as f32 / 99.0 - tn).abs(), s))
                .fold((f32::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a });
            // Equal distance within f32 rounding may pick either neighbour.
            let ds = (s as f32 / 99.0 - tn).abs();
            assert!(
                s == best.1 || (ds - best.0).abs() < 1e-6,
                "t {t}: {s} vs {best:?}"
            );
        }
    }
}
