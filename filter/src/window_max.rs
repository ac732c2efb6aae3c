//! maaf's windowed-maximum estimator of nu(t) ([`crate::MotionEstimator::WindowMax`];
//! not the paper's): Mip-Splatting's Eq. 2 restricted to the views near t,
//!
//! `nu(t) = max { x_j : |t_j - t| <= h_t }`, `x_j = f_j / d_j`, normalised times,
//!
//! evaluated at the T time bins `g_t[s] = s / (T - 1)` and stored in the KDE's
//! format: code `ceil(nu / x_max * (D - 1))`, so the stored nu lies in
//! `[nu, nu + x_max / (D - 1))` (rounded up: the filter is never wider than the
//! windowed maximum asks). A bin with no observation in its window is
//! [`FALLBACK`] (the static `x_max`), as for the KDE.
//!
//! Why: with the paper's kernels the KDE mode sits about `lambda h_x x_max` above
//! the observations and is capped at `x_max`, so nu(t) only leaves `x_max` for a
//! Gaussian whose f/d varies by more than about 30 %. The windowed maximum follows
//! f/d at any amplitude and keeps Mip-Splatting's guarantee at every time: no
//! training view near t samples the Gaussian finer than nu(t).
//!
//! Cost per Gaussian: one pass over its F slots (the per-time-group maxima) plus
//! `T x (groups per window)` comparisons.

use maaf_autodiff::PerGaussian;
use rayon::prelude::*;

use crate::config::FilterConfig;
use crate::curves::FALLBACK;
use crate::observations::{ObservationTable, TimeGroups};

/// Each time bin `s`'s window: the groups `[a, b)` with `|g_t[s] - t_g| <= h_t`
/// (empty: `a >= b`).
fn windows(groups: &TimeGroups, cfg: &FilterConfig) -> Vec<(usize, usize)> {
    let h = f64::from(cfg.h_t);
    (0..cfg.grid_t)
        .map(|s| {
            let gs = s as f64 / (cfg.grid_t - 1) as f64;
            let inside = |g: &usize| (gs - f64::from(groups.times[*g])).abs() <= h;
            let mut within = (0..groups.len()).filter(inside);
            match within.next() {
                Some(a) => (a, within.next_back().unwrap_or(a) + 1),
                None => (0, 0),
            }
        })
        .collect()
}

/// The windowed maximum for every Gaussian of `table` (parallel over Gaussians):
/// `T` codes per row and each row's `x_max` (0 for a Gaussian never observed).
/// `cfg` must be valid.
pub(crate) fn codes(table: &ObservationTable, cfg: &FilterConfig) -> (Vec<u8>, Vec<f32>) {
    let groups = TimeGroups::new(table.times(), cfg);
    let window = windows(&groups, cfg);
    let (rows, t) = (table.rows(), cfg.grid_t);
    let steps = (cfg.grid_x - 1) as f32;
    let mut codes = vec![FALLBACK; rows * t];
    let mut x_max = vec![0.0f32; rows];
    codes
        .par_chunks_mut(t)
        .zip(x_max.par_iter_mut())
        .enumerate()
        .for_each_init(
            || vec![0.0f32; groups.len()],
            |group_max, (n, (codes, xm))| {
                let row = table.row(n);
                for (g, m) in group_max.iter_mut().enumerate() {
                    *m = groups
                        .group(g)
                        .iter()
                        .map(|&f| row[f as usize])
                        .fold(0.0f32, f32::max);
                }
                *xm = group_max.iter().copied().fold(0.0f32, f32::max);
                if *xm <= 0.0 {
                    return;
                }
                for (code, &(a, b)) in codes.iter_mut().zip(&window) {
                    let nu = group_max[a.min(b)..b]
                        .iter()
                        .copied()
                        .fold(0.0f32, f32::max);
                    if nu > 0.0 {
                        *code = (nu / *xm * steps).ceil().min(steps) as u8;
                    }
                }
            },
        );
    (codes, x_max)
}
