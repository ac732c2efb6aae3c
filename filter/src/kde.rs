//! The paper's estimator of the motion-aware sampling rate nu(t) (Sec. 4,
//! Algorithm 1), computed without materialising the `D x T` density; its output is
//! the argmax codes that [`crate::MotionCurves`] stores.
//!
//! Algorithm 1 per Gaussian: `x_max = max_j x_j`, `xbar_j = x_j / x_max` (line 3);
//! `rho[d, s] = 1/(2 h_x h_t) sum_j K_w((g_x[d] - xbar_j)/h_x) K_g((g_t[s] - t_j)/h_t)`
//! (line 7); at query time `t`, `s* = argmin_s |g_t[s] - t|` (line 11),
//! `d* = argmax_d rho[d, s*]` (line 12), `nu(t) = x_max g_x[d*]` (line 13).
//!
//! How the fast path computes the same numbers:
//! 1. Frames are grouped by time once per refresh (all cameras of a multi-view
//!    timestamp share one group), and the time weights
//!    `w[s, g] = K_g((g_t[s] - t_g)/h_t) / (2 h_x h_t)` are computed once for all
//!    Gaussians; the truncated Gaussian gives each bin `s` a contiguous group range.
//! 2. Per Gaussian, each group's Weibull column `H_g[d] = sum_{j in g} K_w(...)` is
//!    evaluated only on the band of grid points the truncated kernel reaches
//!    (~0.35 / grid step = 37 points at the defaults, not D), branch-free and
//!    vectorised.
//! 3. Per block of 20 time bins, `rho[s, .] = sum_g w[s, g] H_g` is one small GEMM
//!    over the block's groups (the workspace's SIMD GEMM), restricted to the
//!    columns that can hold the argmax: every kernel is unimodal with its mode at
//!    `xbar_j + h_x u_mode`, so the sum increases left of the leftmost mode and
//!    decreases right of the rightmost one. Only the argmax is kept (one byte).
//!    The D x T matrix of a Gaussian never exists; scratch is `G x D + 20 x D`
//!    floats per thread.
//!
//! Cost per Gaussian: `J x band` kernel evaluations plus `T x (groups in a block's
//! support) x (mode range)` multiply-adds, instead of Algorithm 1's `J x D x T`.
//!
//! Fallback: if `max_d rho[d, s] <= density_floor` (no observation within
//! `time_support h_t` of the bin, or all nearby observations at the top of the
//! grid where the one-sided kernel is zero) the bin takes the Gaussian's fallback
//! nu: its `x_max`, i.e. Mip-Splatting's Eq. 2 over all its (camera, time)
//! observations, or the smallest `x_max` seen for a Gaussian never observed.
//! nu is therefore always finite and positive.

use maaf_autodiff::{Float, PerGaussian};
use rayon::prelude::*;

use crate::config::FilterConfig;
use crate::curves::FALLBACK;
use crate::kernels::{Kernels, WeibullF32};
use crate::observations::{ObservationTable, TimeGroups};

/// Time grouping and time-kernel weights shared by every Gaussian of a refresh.
struct Plan {
    /// CameraTime indices sorted by time; group `g` is `frames[group_start[g]..group_start[g+1]]`.
    frames: Vec<u32>,
    group_start: Vec<usize>,
    /// Dense `T x G` time weights `w[s, g] = K_g((g_t[s] - t_g)/h_t) / (2 h_x h_t)`
    /// (zero outside the truncated support).
    w: Vec<f32>,
    /// Time blocks `(s0, s1, g0, g1)`: bins `s0..s1` only see groups `g0..g1`.
    blocks: Vec<(usize, usize, usize, usize)>,
    /// Grid g_x in f32.
    gx: Vec<f32>,
    inv_hx: f32,
    /// Weibull support and mode offsets in g_x units: `h_x u_lo`, `h_x u_hi`, `h_x u_mode`.
    lo_off: f32,
    hi_off: f32,
    mode_off: f32,
    weibull: WeibullF32,
    floor: f32,
}

/// Time bins per GEMM block: small enough that a block's group range stays close to
/// the kernel support, large enough to amortise the GEMM call.
const BLOCK_T: usize = 20;

impl Plan {
    fn new(times: &[f32], cfg: &FilterConfig, kern: &Kernels) -> Plan {
        let TimeGroups {
            frames,
            start: group_start,
            times: group_time,
        } = TimeGroups::new(times, cfg);
        let norm = 1.0 / (2.0 * kern.h_x * kern.h_t);
        let (t_grid, groups) = (cfg.grid_t, group_time.len());
        let mut w = vec![0.0f32; t_grid * groups];
        let mut support = Vec::with_capacity(t_grid);
        for s in 0..t_grid {
            let gs = s as f64 / (t_grid - 1) as f64;
            let (mut first, mut end) = (groups, 0);
            for (g, &t) in group_time.iter().enumerate() {
                let v = norm * kern.gauss((gs - t as f64) / kern.h_t);
                if v > 0.0 {
                    w[s * groups + g] = v as f32;
                    first = first.min(g);
                    end = end.max(g + 1);
                }
            }
            support.push((first, end));
        }
        let blocks = (0..t_grid)
            .step_by(BLOCK_T)
            .map(|s0| {
                let s1 = (s0 + BLOCK_T).min(t_grid);
                let g0 = support[s0..s1].iter().map(|r| r.0).min().unwrap_or(0);
                let g1 = support[s0..s1].iter().map(|r| r.1).max().unwrap_or(0);
                (s0, s1, g0, g1.max(g0))
            })
            .collect();
        let d = cfg.grid_x;
        let h_x = cfg.h_x;
        Plan {
            frames,
            group_start,
            w,
            blocks,
            gx: (0..d).map(|i| (i as f64 / (d - 1) as f64) as f32).collect(),
            inv_hx: 1.0 / h_x,
            lo_off: (kern.h_x * kern.u_lo) as f32,
            hi_off: (kern.h_x * kern.u_hi) as f32,
            mode_off: (kern.h_x * kern.u_mode) as f32,
            weibull: kern.weibull_f32(),
            floor: cfg.density_floor,
        }
    }

    fn num_groups(&self) -> usize {
        self.group_start.len() - 1
    }
}

/// Per-thread scratch of the fast refresh.
struct Scratch {
    /// `G x D` Weibull columns, kept all-zero between Gaussians.
    h: Vec<f32>,
    /// Per group: used band `[lo, hi)` of its column (`lo >= hi`: unobserved) and
    /// the min / max of its normalised observations.
    band: Vec<(usize, usize)>,
    xb_range: Vec<(f32, f32)>,
    /// `BLOCK_T x D` density block.
    acc: Vec<f32>,
    /// Band cache per position within a group: x, band and values (`max group x D`).
    cache_x: Vec<f32>,
    cache_band: Vec<(usize, usize)>,
    cache_vals: Vec<f32>,
}
/// The paper's estimator for every Gaussian (fast Algorithm 1, parallel over
/// Gaussians): the `T` argmax codes per row and each row's `x_max`.
pub(crate) fn codes(table: &ObservationTable, cfg: &FilterConfig) -> (Vec<u8>, Vec<f32>) {
    let kern = Kernels::new(cfg);
    let plan = Plan::new(table.times(), cfg, &kern);
    let rows = table.rows();
    let (d, t) = (cfg.grid_x, cfg.grid_t);
    let mut codes = vec![FALLBACK; rows * t];
    let mut x_max = vec![0.0f32; rows];
    let groups = plan.num_groups();
    let max_group = plan
        .group_start
        .windows(2)
        .map(|w| w[1] - w[0])
        .max()
        .unwrap_or(0);
    codes
        .par_chunks_mut(t)
        .zip(x_max.par_iter_mut())
        .enumerate()
        .for_each_init(
            || Scratch {
                h: vec![0.0; groups * d],
                band: vec![(0, 0); groups],
                xb_range: vec![(0.0, 0.0); groups],
                acc: vec![0.0; BLOCK_T * d],
                cache_x: vec![f32::NAN; max_group],
                cache_band: vec![(0, 0); max_group],
                cache_vals: vec![0.0; max_group * d],
            },
            |scratch, (n, (codes, xm))| {
                *xm = curve_one(table.row(n), &plan, scratch, codes);
            },
        );
    (codes, x_max)
}

/// Fast Algorithm 1 for one Gaussian: fills `codes` (length T) and returns x_max.
fn curve_one(row: &[f32], plan: &Plan, scratch: &mut Scratch, codes: &mut [u8]) -> f32 {
    codes.fill(FALLBACK);
    // Line 3: x_max over the valid slots (empty slots hold 0).
    let x_max = row.iter().copied().fold(0.0f32, f32::max);
    if x_max <= 0.0 {
        return 0.0;
    }
    let d = plan.gx.len();
    let groups = plan.num_groups();
    let inv_max = 1.0 / x_max;
    let dm1 = (d - 1) as f32;
    // Step 2: Weibull columns H_g per time group, on each observation's band only.
    // The band of the i-th frame of a group is cached and reused when the i-th
    // frame of the next group has bitwise the same x (in a multi-view layout the
    // i-th frame of every time is the same camera, so a static Gaussian repeats
    // its x): same input, same values, and a copy instead of ~40 kernel evaluations.
    scratch.cache_x.fill(f32::NAN);
    for g in 0..groups {
        let (mut glo, mut ghi) = (d, 0);
        let (mut xmin, mut xmax) = (f32::INFINITY, f32::NEG_INFINITY);
        let col = &mut scratch.h[g * d..(g + 1) * d];
        let frames = &plan.frames[plan.group_start[g]..plan.group_start[g + 1]];
        for (i, &f) in frames.iter().enumerate() {
            let x = row[f as usize];
            if x <= 0.0 {
                continue;
            }
            let xb = x * inv_max;
            let cached = &mut scratch.cache_vals[i * d..(i + 1) * d];
            let (lo, hi) = if scratch.cache_x[i].to_bits() == x.to_bits() {
                scratch.cache_band[i]
            } else {
                // Grid points with u in [u_lo, u_hi], widened by one on each side
                // against rounding (the kernel itself is zero outside its support),
                // then padded to a multiple of 4 lanes so no scalar tail remains.
                let lo = (((xb + plan.lo_off) * dm1).ceil() as usize).saturating_sub(1);
                let hi = ((((xb + plan.hi_off) * dm1).floor() as usize) + 2).min(d);
                let (lo, hi) = if lo < hi {
                    let len = (hi - lo).next_multiple_of(4).min(d);
                    let hi = (lo + len).min(d);
                    (hi - len, hi)
                } else {
                    (0, 0)
                };
                cached[lo..hi].fill(0.0);
                plan.weibull
                    .add_band(xb, plan.inv_hx, &plan.gx[lo..hi], &mut cached[lo..hi]);
                scratch.cache_x[i] = x;
                scratch.cache_band[i] = (lo, hi);
                (lo, hi)
            };
            if lo >= hi {
                continue;
            }
            for (c, &v) in col[lo..hi].iter_mut().zip(&cached[lo..hi]) {
                *c += v;
            }
            glo = glo.min(lo);
            ghi = ghi.max(hi);
            xmin = xmin.min(xb);
            xmax = xmax.max(xb);
        }
        scratch.band[g] = (glo, ghi);
        scratch.xb_range[g] = (xmin, xmax);
    }
    // Step 3: per block of time bins, rho[s, d] = sum_g w[s, g] H_g[d] as a GEMM
    // over the block's groups, restricted to the columns that can hold the argmax:
    // every kernel is unimodal (mode at xbar + h_x u_mode), so the sum increases
    // left of the leftmost mode and decreases right of the rightmost one.
    for &(s0, s1, g0, g1) in &plan.blocks {
        let (mut lo, mut hi) = (d, 0);
        let (mut xmin, mut xmax) = (f32::INFINITY, f32::NEG_INFINITY);
        for g in g0..g1 {
            let (a, b) = scratch.band[g];
            if a < b {
                lo = lo.min(a);
                hi = hi.max(b);
                xmin = xmin.min(scratch.xb_range[g].0);
                xmax = xmax.max(scratch.xb_range[g].1);
            }
        }
        // Modes above the grid (xbar + h_x u_mode > 1) leave the top point as candidate.
        let c_lo = ((((xmin + plan.mode_off) * dm1).floor() as usize).saturating_sub(1)).min(d - 1);
        let c_hi = ((((xmax + plan.mode_off) * dm1).ceil() as usize) + 2).min(d);
        let (lo, hi) = (lo.max(c_lo), hi.min(c_hi));
        if lo >= hi {
            continue;
        }
        let (m, n) = (s1 - s0, hi - lo);
        let acc = &mut scratch.acc[..m * n];
        gemm_chunked(
            m,
            g1 - g0,
            n,
            &plan.w[s0 * groups + g0..],
            groups,
            &scratch.h[g0 * d + lo..],
            d,
            acc,
        );
        for (i, code) in codes[s0..s1].iter_mut().enumerate() {
            // First maximum, as Alg. 1 line 12's argmax.
            let (mut best, mut best_d) = (f32::NEG_INFINITY, 0);
            for (j, &v) in acc[i * n..(i + 1) * n].iter().enumerate() {
                if v > best {
                    best = v;
                    best_d = j;
                }
            }
            if best > plan.floor {
                *code = (lo + best_d) as u8;
            }
        }
    }
    // Restore the all-zero invariant of the column scratch.
    for g in 0..groups {
        let (a, b) = scratch.band[g];
        if a < b {
            scratch.h[g * d + a..g * d + b].fill(0.0);
        }
    }
    x_max
}

/// `C (m x n) = A (m x k, row stride lda) B (k x n, row stride ldb)` through the
/// workspace GEMM (runtime-dispatched SIMD). `k` is split so that every call has
/// `(m + n) k < 2^15`, below `matrixmultiply`'s threading threshold: each rayon
/// worker's GEMM stays single-threaded.
#[allow(clippy::too_many_arguments)]
fn gemm_chunked(
    m: usize,
    k: usize,
    n: usize,
    a: &[f32],
    lda: usize,
    b: &[f32],
    ldb: usize,
    c: &mut [f32],
) {
    if k == 0 {
        c.fill(0.0);
        return;
    }
    let chunk = (((1usize << 15) - 1) / (m + n)).max(1);
    let mut k0 = 0;
    while k0 < k {
        let kc = chunk.min(k - k0);
        let beta = if k0 == 0 { 0.0 } else { 1.0 };
        <f32 as Float>::gemm(
            m,
            kc,
            n,
            1.0,
            &a[k0..],
            lda as isize,
            1,
            &b[k0 * ldb..],
            ldb as isize,
            1,
            beta,
            c,
            n as isize,
            1,
        );
        k0 += kc;
    }
}
