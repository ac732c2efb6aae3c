//! The render entry point: activated Gaussian parameters on a tape -> image, alpha,
//! depth and the screen-space means (docs/conventions.md).

use maaf_autodiff::{Float, Tape, Tensor, Var};

use crate::Camera;
use crate::compositing::AlphaCutoff;
use crate::cov3d::quat_scale_to_cov;
use crate::lanes::SplatFloat;
use crate::project::{Filter2d, NEAR_PLANE, project_ewa};
use crate::rasterize::{AbsMeans2dGrad, rasterize};
use crate::sh::sh_color;

/// Activated per-Gaussian parameters on a tape (the trainer applies `exp` to log-scales
/// and `sigmoid` to raw opacities, and [`crate::apply_3d_filter`] if it filters, before
/// calling [`render`]).
#[derive(Clone, Copy)]
pub struct GaussianVars<'t, T: Float> {
    /// Centres `[N,3]`, world units.
    pub means: Var<'t, T>,
    /// Activated (positive) scales `[N,3]`.
    pub scales: Var<'t, T>,
    /// Rotations `[N,4]` as `(w, x, y, z)`, unnormalised (normalised inside).
    pub quats: Var<'t, T>,
    /// Activated opacities `[N]` in `(0, 1)`.
    pub opacity: Var<'t, T>,
    /// SH coefficients `[N,K,3]`, `K >= (sh_degree+1)^2`; coefficient 0 is the DC term.
    pub sh: Var<'t, T>,
}

/// Rendering options. `Default`: black background, Mip 2D filter, SH degree 3, hard
/// cutoff, near plane 0.2.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Background colour (linear RGB) composited with weight `T_final`.
    pub background: [f64; 3],
    /// Screen-space filter (3DGS dilation or Mip-Splatting 2D Mip filter).
    pub filter2d: Filter2d,
    /// SH degree evaluated (0..=3), capped at the degree `sh` holds (as 3DGS's active
    /// degree grows during training while `K` stays `(max_degree+1)^2`).
    pub sh_degree: usize,
    /// Alpha cutoff rules ([`AlphaCutoff::Smooth`] only for finite-difference tests).
    pub alpha_cutoff: AlphaCutoff,
    /// Near plane: Gaussians with camera depth `<= near` are culled.
    pub near: f64,
    /// Render only this rectangle of the camera's image ([`Window`]; `None`: all of
    /// it).
    pub window: Option<Window>,
}

/// A rectangle of a camera's pixels, columns `x0..x0 + width` and rows
/// `y0..y0 + height`. The Gaussians are projected and culled with the whole camera
/// and blended on the rectangle's pixels only (screen means shifted by `(-x0, -y0)`),
/// so with `x0`, `y0` on the tile grid ([`crate::compositing::TILE`]) the render is
/// exactly those pixels of the whole image, at the cost of the rectangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            background: [0.0; 3],
            filter2d: Filter2d::Mip,
            sh_degree: 3,
            alpha_cutoff: AlphaCutoff::Hard,
            near: NEAR_PLANE,
            window: None,
        }
    }
}

/// What [`render`] returns.
pub struct RenderOutput<'t, T: Float> {
    /// Colour `[H,W,3]` (linear, background included).
    pub image: Var<'t, T>,
    /// Accumulated opacity `1 - T_final`, `[H,W]`.
    pub alpha: Var<'t, T>,
    /// Alpha-weighted camera depth `sum z_i alpha_i T_i`, `[H,W]`.
    pub depth: Var<'t, T>,
    /// Screen-space means `[N,2]` in pixels, a tape node: `grads.wrt(out.means2d)` is
    /// the view-space positional gradient used by densification.
    pub means2d: Var<'t, T>,
    /// Screen-space radius per Gaussian in pixels (0 = culled); not differentiable.
    pub radii: Vec<u32>,
    /// AbsGS's densification statistic, filled by the backward when requested
    /// before it ([`crate::rasterize::AbsMeans2dGrad`]).
    pub abs_means2d: AbsMeans2dGrad<T>,
}

impl<T: Float> RenderOutput<'_, T> {
    /// `radii[i] > 0`: Gaussian `i` was in view and binned.
    pub fn visible(&self) -> Vec<bool> {
        self.radii.iter().map(|&r| r > 0).collect()
    }
}

/// Renders Gaussians on `tape`: covariance ([`crate::cov3d::QuatScaleToCov`]), EWA
/// projection with the frustum clamp and 2D filter ([`crate::project::ProjectEwa`]),
/// SH colour ([`crate::sh::ShColor`]) and tile rasterization
/// ([`crate::rasterize::Rasterize`]), each an op with a hand-written backward.
///
/// Panics (naming the parameter) if shapes disagree.
pub fn render<'t, T: SplatFloat>(
    tape: &'t Tape<T>,
    g: &GaussianVars<'t, T>,
    camera: &Camera,
    settings: &RenderSettings,
) -> RenderOutput<'t, T> {
    let n = g.means.shape()[0];
    for (name, v, want) in [
        ("means", g.means, vec![n, 3]),
        ("scales", g.scales, vec![n, 3]),
        ("quats", g.quats, vec![n, 4]),
        ("opacity", g.opacity, vec![n]),
    ] {
        assert!(
            std::ptr::eq(v.tape(), tape),
            "render: {name} is on another tape"
        );
        assert_eq!(
            v.shape().as_slice(),
            want.as_slice(),
            "render: {name} has the wrong shape"
        );
    }
    let cov = quat_scale_to_cov(g.quats, g.scales);
    let proj = project_ewa(
        g.means,
        cov,
        g.opacity,
        camera,
        settings.filter2d,
        settings.near,
    );
    let c = camera.center();
    let colors = sh_color(
        g.means,
        g.sh,
        [c.x, c.y, c.z],
        effective_sh_degree(g.sh, settings),
    );
    let radii: Vec<u32> = proj
        .radii
        .value()
        .data()
        .iter()
        .map(|&r| Float::to_f64(r) as u32)
        .collect();
    let (means2d, width, height) = match settings.window {
        None => (proj.means2d, camera.width, camera.height),
        Some(w) => {
            let shift =
                Tensor::from_vec(vec![T::of(-f64::from(w.x0)), T::of(-f64::from(w.y0))], &[2]);
            (proj.means2d + tape.constant(shift), w.width, w.height)
        }
    };
    let out = rasterize(
        means2d,
        proj.conics,
        colors,
        proj.opacity,
        proj.depths,
        proj.radii,
        width,
        height,
        settings.background,
        settings.alpha_cutoff,
    );
    RenderOutput {
        image: out.image,
        alpha: out.alpha,
        depth: out.depth,
        means2d: proj.means2d,
        radii,
        abs_means2d: out.abs_means2d,
    }
}

/// `min(settings.sh_degree, largest degree d with (d+1)^2 <= K)`; panics if `sh` is
/// not `[N,K,3]` with `K >= 1`.
fn effective_sh_degree<T: Float>(sh: Var<'_, T>, settings: &RenderSettings) -> usize {
    let shape = sh.shape();
    assert!(
        shape.len() == 3 && shape[1] >= 1 && shape[2] == 3,
        "render: sh must be [N,K,3], got {shape:?}"
    );
    let mut d = 0;
    while d < 3 && (d + 2) * (d + 2) <= shape[1] {
        d += 1;
    }
    d.min(settings.sh_degree)
}

/// A rendered frame as plain tensors (no tape).
#[derive(Clone, Debug)]
pub struct RenderedFrame<T> {
    /// Colour `[H,W,3]`.
    pub image: Tensor<T>,
    /// Accumulated opacity `[H,W]`.
    pub alpha: Tensor<T>,
    /// Alpha-weighted depth `[H,W]`.
    pub depth: Tensor<T>,
    /// Screen-space radii (0 = culled).
    pub radii: Vec<u32>,
}

/// Renders activated parameters given as plain tensors (constants on a throw-away tape).
pub fn render_tensors<T: SplatFloat>(
    means: &Tensor<T>,
    scales: &Tensor<T>,
    quats: &Tensor<T>,
    opacity: &Tensor<T>,
    sh: &Tensor<T>,
    camera: &Camera,
    settings: &RenderSettings,
) -> RenderedFrame<T> {
    let tape = Tape::new();
    let g = GaussianVars {
        means: tape.constant(means.clone()),
        scales: tape.constant(scales.clone()),
        quats: tape.constant(quats.clone()),
        opacity: tape.constant(opacity.clone()),
        sh: tape.constant(sh.clone()),
    };
    let out = render(&tape, &g, camera, settings);
    let image = out.image.value().clone();
    let alpha = out.alpha.value().clone();
    let depth = out.depth.value().clone();
    RenderedFrame {
        image,
        alpha,
        depth,
        radii: out.radii,
    }
}
