//! The per-Gaussian filter state the trainer and renderer use: one variance per
//! Gaussian at a time t, for the renderer's `apply_3d_filter` (docs/conventions.md, "3D filter fold").

use maaf_autodiff::PerGaussian;
use serde::{Deserialize, Serialize};

use crate::config::FilterKind;
use crate::curves::MotionCurves;

/// Current 3D filter of every Gaussian. Resized with the Gaussians through
/// [`PerGaussian`] (clone/split copy the row, prune drops it) and recomputed on
/// the [`crate::RefreshSchedule`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum FilterState {
    /// No 3D filter: variance 0.
    None {
        /// Number of Gaussians.
        rows: usize,
    },
    /// Mip-Splatting's static filter: one nu per Gaussian (paper Eq. 2).
    Mip3d {
        /// Filter size s (variance `s / nu^2`).
        s3d: f32,
        /// Static nu per Gaussian.
        nu: Vec<f32>,
    },
    /// The motion-aware filter: nu_k(t) per Gaussian (paper Alg. 1).
    Motion {
        /// Filter size s (variance `s / nu(t)^2`).
        s3d: f32,
        /// Curves nu_k(t).
        curves: MotionCurves,
    },
}

/// The 3D filter variance `s3d / nu^2` (world units squared) of a sampling rate `nu`:
/// what `apply_3d_filter` adds to a Gaussian's covariance (docs/conventions.md).
fn variance(s3d: f32, nu: f32) -> f32 {
    s3d / (nu * nu)
}

impl FilterState {
    /// Which filter this is.
    pub fn kind(&self) -> FilterKind {
        match self {
            FilterState::None { .. } => FilterKind::None,
            FilterState::Mip3d { .. } => FilterKind::Mip3d,
            FilterState::Motion { .. } => FilterKind::Motion,
        }
    }

    /// The variance tensor `var[N]` (world units^2) that `apply_3d_filter` adds as
    /// `Sigma' = Sigma + var I` at time `t`: `s3d / nu_k^2` (Mip3d, constant in t),
    /// `s3d / nu_k(t)^2` with the nearest time bin (Motion; Alg. 1 line 11, no
    /// interpolation, as in the paper), or 0 (None). Always finite and >= 0.
    pub fn variance_at(&self, t: f32) -> Vec<f32> {
        match self {
            FilterState::None { rows } => vec![0.0; *rows],
            FilterState::Mip3d { s3d, nu } => nu.iter().map(|&n| variance(*s3d, n)).collect(),
            FilterState::Motion { s3d, curves } => {
                let s = curves.bin_of(t);
                (0..curves.rows())
                    .map(|n| variance(*s3d, curves.nu(n, s)))
                    .collect()
            }
        }
    }

    /// The largest variance each Gaussian gets at any time, `max_t var_k(t)`:
    /// `s3d / nu_k^2` (Mip3d), `s3d / (min_s nu_k(s))^2` over the T time bins of its
    /// curve (Motion: the widest filter, i.e. the smallest opacity compensation
    /// `sqrt(det Sigma / det(Sigma + var I))` it is drawn with), or 0 (None).
    pub fn max_variance(&self) -> Vec<f32> {
        match self {
            FilterState::Motion { s3d, curves } => (0..curves.rows())
                .map(|n| {
                    let nu = (0..curves.grid_t())
                        .map(|s| curves.nu(n, s))
                        .fold(f32::INFINITY, f32::min);
                    variance(*s3d, nu)
                })
                .collect(),
            FilterState::None { .. } | FilterState::Mip3d { .. } => self.variance_at(0.0),
        }
    }

    /// Bytes of filter state per Gaussian (0, 4, or `T + 8`), for `eval.json`'s
    /// `filter_bytes` (times the number of Gaussians).
    pub fn bytes_per_gaussian(&self) -> usize {
        match self {
            FilterState::None { .. } => 0,
            FilterState::Mip3d { .. } => std::mem::size_of::<f32>(),
            FilterState::Motion { curves, .. } => curves.bytes_per_gaussian(),
        }
    }
}

impl PerGaussian for FilterState {
    fn rows(&self) -> usize {
        match self {
            FilterState::None { rows } => *rows,
            FilterState::Mip3d { nu, .. } => nu.len(),
            FilterState::Motion { curves, .. } => curves.rows(),
        }
    }

    fn select_rows(&mut self, index: &[usize]) {
        match self {
            FilterState::None { rows } => *rows = index.len(),
            FilterState::Mip3d { nu, .. } => nu.select_rows(index),
            FilterState::Motion { curves, .. } => curves.select_rows(index),
        }
    }
}
