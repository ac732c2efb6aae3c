//! The rules of the tiled compositor that binning, the blend loop, the rasterizer op
//! and the reference all follow: the tile size, the alpha thresholds and clamp, the
//! transmittance floor and the [`AlphaCutoff`] modes. Kept in one module so that
//! `binning`, `blend` and `rasterize` import it and not each other.

/// Tile edge in pixels.
pub const TILE: usize = 16;
/// Minimum alpha for a Gaussian to count at a pixel (hard cutoff): `1/255`.
pub const ALPHA_MIN: f64 = 1.0 / 255.0;
/// Alpha clamp (hard cutoff): `alpha = min(0.99, o exp(-power))` (Inria, Mip-Splatting,
/// gsplat >= 2026-02).
pub const ALPHA_MAX: f64 = 0.99;
/// Transmittance floor: a pixel stops before blending a Gaussian that would take
/// `T` below `1e-4` (exclusive, as Inria and gsplat).
pub const T_MIN: f64 = 1e-4;
/// Support of a Gaussian: `power = d^T conic d / 2 <= 4.5`, the 3-sigma ellipse. It is
/// contained in the `ceil(3 sqrt(lambda_max))` radius used for binning, so the image
/// does not depend on the tile grid. Deliberate difference: Inria/gsplat blend a
/// Gaussian at every pixel of every tile its box touches, which keeps tails beyond
/// 3 sigma (alpha <= 0.011 o) at some pixels and not at others.
pub const SUPPORT_POWER: f64 = 4.5;
/// Start of the smooth taper of [`AlphaCutoff::Smooth`] in power units.
pub const SMOOTH_TAPER_START: f64 = 2.0;

/// How alpha is cut off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AlphaCutoff {
    /// 3DGS behaviour: `alpha = min(0.99, o exp(-power))` for `power <= 4.5`, skipped
    /// when below `1/255`, a pixel stops before `T` would fall under `1e-4`. The
    /// gradient is zero where the 0.99 clamp is active (the true derivative; gsplat
    /// masks it too, Inria does not).
    #[default]
    Hard,
    /// A C1 variant for finite-difference tests: `alpha = o exp(-power) w(power)`
    /// with the taper `w = (1 - q^2)^2` for `q = (power - 2)/(4.5 - 2)` in `[0,1]`,
    /// `w = 1` below and `0` above; no 1/255 skip, no clamp, no early stop.
    Smooth,
}
