//! Plain (tape-free) Gaussians in the standard 3DGS parameterisation, for PLY I/O,
//! baking and static rendering.

use maaf_autodiff::Tensor;
use maaf_autodiff::scalar::{logit, sigmoid};

use crate::Camera;
use crate::render::{RenderSettings, RenderedFrame, render_tensors};
use crate::sh::num_coeffs;

/// A static 3DGS scene in storage parameterisation (docs/conventions.md; Inria PLY):
/// `means [N,3]`, `log_scales [N,3]` (scale = exp), `quats [N,4]` (w,x,y,z,
/// unnormalised), `raw_opacity [N]` (opacity = sigmoid), `sh [N,K,3]` with
/// `K = (sh_degree+1)^2`, coefficient-major then channel (`sh[i][k][c]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Gaussians {
    /// Centres `[N,3]`.
    pub means: Tensor<f32>,
    /// Log scales `[N,3]`.
    pub log_scales: Tensor<f32>,
    /// Rotations `[N,4]` (w, x, y, z).
    pub quats: Tensor<f32>,
    /// Opacity logits `[N]`.
    pub raw_opacity: Tensor<f32>,
    /// SH coefficients `[N,K,3]`.
    pub sh: Tensor<f32>,
    /// SH degree stored (0..=3).
    pub sh_degree: usize,
}

impl Gaussians {
    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.raw_opacity.len()
    }

    /// True when there is no Gaussian.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// An empty scene with SH degree `sh_degree`.
    pub fn empty(sh_degree: usize) -> Self {
        let k = num_coeffs(sh_degree);
        Gaussians {
            means: Tensor::zeros(&[0, 3]),
            log_scales: Tensor::zeros(&[0, 3]),
            quats: Tensor::zeros(&[0, 4]),
            raw_opacity: Tensor::zeros(&[0]),
            sh: Tensor::zeros(&[0, k, 3]),
            sh_degree,
        }
    }

    /// Activated scales `exp(log_scales)`.
    pub fn scales(&self) -> Tensor<f32> {
        self.log_scales.map(f32::exp)
    }

    /// Activated opacities `sigmoid(raw_opacity)`.
    pub fn opacities(&self) -> Tensor<f32> {
        self.raw_opacity.map(sigmoid)
    }

    /// A copy with the 3D filter of variance `var[i]` folded in (see
    /// [`crate::apply_3d_filter`]): `scale' = sqrt(scale^2 + var)`,
    /// `opacity' = opacity sqrt(prod scale^2 / prod(scale^2 + var))`, stored back as
    /// log and logit. Used for the "baked" PLY export (Mip-Splatting
    /// `save_fused_ply`) so that ordinary viewers show the filtered scene.
    pub fn with_3d_filter(&self, var: &[f32]) -> Gaussians {
        assert_eq!(
            var.len(),
            self.len(),
            "with_3d_filter: one variance per Gaussian"
        );
        let mut out = self.clone();
        let s = self.scales();
        let o = self.opacities();
        for (i, &v) in var.iter().enumerate() {
            let mut ratio = 1.0f64;
            for j in 0..3 {
                let s2 = (s.data()[3 * i + j] as f64).powi(2);
                out.log_scales.data_mut()[3 * i + j] = (0.5 * (s2 + v as f64).ln()) as f32;
                ratio *= s2 / (s2 + v as f64);
            }
            out.raw_opacity.data_mut()[i] = logit((o.data()[i] as f64 * ratio.sqrt()) as f32);
        }
        out
    }

    /// Renders the scene with `camera` (no tape); `settings.sh_degree` is capped at the
    /// stored degree.
    pub fn render(&self, camera: &Camera, settings: &RenderSettings) -> RenderedFrame<f32> {
        let mut s = settings.clone();
        s.sh_degree = s.sh_degree.min(self.sh_degree);
        render_tensors(
            &self.means,
            &self.scales(),
            &self.quats,
            &self.opacities(),
            &self.sh,
            camera,
            &s,
        )
    }
}

/// Renders a static scene without a tape; see [`Gaussians::render`].
pub fn render_gaussians(
    g: &Gaussians,
    camera: &Camera,
    settings: &RenderSettings,
) -> RenderedFrame<f32> {
    g.render(camera, settings)
}
