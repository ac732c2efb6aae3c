//! The rules of the tiled compositor that binning, the blend loop, the rasterizer op
//! and the reference all follow: the tile size, the alpha thresholds and clamp, the
//! transmittance floor and the [`AlphaCutoff`] modes. Kept in one module so that
//! `binning`, `blend` and `rasterize` import it and not each other.

use maaf_autodiff::Float;

/// Tile edge in pixels.
pub const TILE: usize = 16;
/// Minimum alpha for a Gaussian to count at a pixel (hard cutoff): `1/255`.
pub const ALPHA_MIN: f64 = 1.0 / 255.0;
/// Alpha clamp (hard cutoff): `alpha = min(0.99, o exp(-power))` (Inria, Mip-Splatting,
/// gsplat >= 2026-02).
pub const ALPHA_MAX: f64 = 0.99;
/// Transmittance floor: a pixel stops before blending a Gaussian that would take
/// `T` below `1e-4` (Inria `test_T < 0.0001`: the alpha skip is tested first, then
/// the floor, and `T` is updated only after blending; gsplat stops at `<=`, which
/// differs only at equality).
pub const T_MIN: f64 = 1e-4;
/// Width of the smooth taper of [`AlphaCutoff::Smooth`], in power units before the
/// Gaussian's own support edge ([`support_power`]).
pub const SMOOTH_TAPER_WIDTH: f64 = 2.5;

/// Support of a Gaussian of (2D-filtered) opacity `o`: the pixels where its raw alpha
/// reaches the threshold, `o exp(-power) >= 1/255`, i.e. `power <= ln(255 o)`
/// (gsplat's opacity-aware extent, after arXiv 2402.00525 sec. B.2). Negative (no
/// support) when `o < 1/255`. Binning, the blend loop and both cutoffs use this edge,
/// so the image does not depend on the tile grid and equals a dense compositor
/// that tries every Gaussian at every pixel.
pub fn support_power<T: Float>(o: T) -> T {
    (o * T::of(255.0)).ln()
}

/// Support radius in standard deviations, `sqrt(2 ln(255 o))` (at most
/// `sqrt(2 ln 255) = 3.33`), or 0 when `o <= 1/255` or `o` is not a number.
pub fn support_sigmas(o: f64) -> f64 {
    let p = support_power(o);
    if p > 0.0 { (2.0 * p).sqrt() } else { 0.0 }
}

/// Per Gaussian of (deformed) opacity `opacity`, whether the renderer can draw it:
/// its support [`support_sigmas`] is positive (`255 o > 1`). The 2D and 3D filters
/// only lower opacity, so a Gaussian flagged false is never drawn, whatever the
/// camera.
pub fn drawable<T: Float>(opacity: &[T]) -> Vec<bool> {
    opacity
        .iter()
        .map(|&o| support_sigmas(o.to_f64()) > 0.0)
        .collect()
}

/// How alpha is cut off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AlphaCutoff {
    /// 3DGS behaviour (Inria `renderCUDA`): `alpha = min(0.99, o exp(-power))`,
    /// skipped when `power < 0` or `alpha < 1/255`; a pixel stops (without blending
    /// it) at the first Gaussian that would take `T` below `1e-4`. The gradient is
    /// zero where the 0.99 clamp is active (the true derivative; gsplat masks it too,
    /// Inria does not).
    #[default]
    Hard,
    /// A C1 variant for finite-difference tests, with the same support: for the raw
    /// alpha `a = o exp(-power)` and its headroom `r = ln(255 a) = ln(255 o) - power`,
    /// `alpha = a w(r)` with the taper `w = (1 - q^2)^2`, `q = 1 - r / 2.5` clamped to
    /// `[0, 1]` (`w = 1` for `r >= 2.5`, `0` at the edge `r = 0`); no clamp, no early
    /// stop.
    Smooth,
}
