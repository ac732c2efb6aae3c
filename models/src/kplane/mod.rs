//! Scale-aware K-plane residual field (SaRO-GS `scene/hexplane.py::ScaleAwareResField`).
//!
//! Six feature planes over pairs of (x, y, z, t), in SaRO-GS's order
//! `itertools.combinations(range(4), 2)`: xy, xz, xt, yz, yt, zt. A query point is
//! the Gaussian's canonical centre normalised to \[0,1] by the scene bounds, its
//! temporal centre mu_t and its activated scale, all detached. The feature is the
//! **sum** over the six planes (SaRO-GS `concat_planes = False`; 4DGaussians' HexPlane
//! multiplies instead).
//!
//! Scale awareness ("Eq 18" in the SaRO-GS code): per spatial axis
//! `level_a = log2(2 s_a / base_a)`, `base_a = extent_a / res`, with `s_a` clamped to
//! `\[base_a / 2, base_a / 2 * res]` so that the level lies in `\[0, log2 res]`; a plane
//! uses the smaller level of its two axes; planes containing t use level 0. A spatial
//! plane is sampled trilinearly in a 2x2 box-filtered mip pyramid (bilinear within a
//! level, linear across levels), texel centres at `(i + 0.5) / res`, clamp at the
//! border: nvdiffrast `texture(..., mip_level_bias = level, boundary_mode = "clamp")`.
//!
//! [`PlaneSample`] is the differentiable op. Since the query is detached, the feature
//! is linear in the plane values and the backward is the transpose of the same taps
//! (scatter, then the adjoint of the box pyramid: each parent's cotangent is spread
//! as 1/4 to its four children).

mod reference;
mod sample;
#[cfg(test)]
mod tests;

use maaf_autodiff::{Float, Tensor};
use serde::{Deserialize, Serialize};

pub use self::reference::reference_sample;
pub use self::sample::{PlaneSample, build_pyramid};

/// The axes (0 = x, 1 = y, 2 = z, 3 = t) of the six planes, in SaRO-GS order.
pub const PLANE_AXES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// Names of the six planes, in [`PLANE_AXES`] order.
pub const PLANE_NAMES: [&str; 6] = ["xy", "xz", "xt", "yz", "yt", "zt"];

/// Sizes of the field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KPlaneConfig {
    /// Texels along each spatial axis (a power of two, for the box pyramid).
    /// SaRO-GS D-NeRF: 64.
    pub spatial_res: usize,
    /// Texels along t. SaRO-GS D-NeRF: 128.
    pub time_res: usize,
    /// Feature channels C. SaRO-GS D-NeRF: 32.
    pub channels: usize,
    /// Highest mip level of a spatial plane (nvdiffrast `max_mip_level = 7` in SaRO-GS;
    /// the pyramid of a 64-texel plane ends at level 6 anyway).
    pub max_mip_level: usize,
}

impl Default for KPlaneConfig {
    /// CPU defaults: 64 x 64 spatial planes, 64 time texels, 32 channels (see the
    /// SaRO config docs for the cost).
    fn default() -> Self {
        KPlaneConfig {
            spatial_res: 64,
            time_res: 64,
            channels: 32,
            max_mip_level: 7,
        }
    }
}

/// Layout of one plane and its mip pyramid (values stored \[height, width, channels],
/// width along the plane's first axis, as nvdiffrast's `\[H, W, C]` texture).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneGeom {
    /// Texels along the first axis (u).
    pub width: usize,
    /// Texels along the second axis (v).
    pub height: usize,
    /// Number of pyramid levels (1 = no pyramid).
    pub levels: usize,
}

impl PlaneGeom {
    /// `(width, height)` of level `l` (halved per level, at least 1).
    pub fn dims(&self, l: usize) -> (usize, usize) {
        ((self.width >> l).max(1), (self.height >> l).max(1))
    }

    /// Texel offset of level `l` in the concatenated pyramid.
    pub fn offset(&self, l: usize) -> usize {
        (0..l)
            .map(|i| {
                let (w, h) = self.dims(i);
                w * h
            })
            .sum()
    }

    /// Texels in the whole pyramid.
    pub fn pyramid_texels(&self) -> usize {
        self.offset(self.levels)
    }
}

/// The layout of the six planes plus the bounds used to normalise positions. The
/// plane values themselves are parameters and live in the representation's
/// [`crate::params::ParamStore`] ([`KPlaneField::zero_planes`] makes the initial ones).
#[derive(Clone, Debug, PartialEq)]
pub struct KPlaneField {
    /// Sizes.
    pub config: KPlaneConfig,
    /// Lower corner of the normalisation box (SaRO-GS: the AABB of the initial cloud).
    pub aabb_min: [f64; 3],
    /// Upper corner of the normalisation box.
    pub aabb_max: [f64; 3],
}

/// Detached per-Gaussian query of the field: normalised coordinates and mip levels.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldQuery {
    /// (x, y, z, t) per Gaussian, positions normalised to \[0, 1] by the bounds.
    pub coords: Vec<[f64; 4]>,
    /// Mip level per spatial axis, in \[0, log2 res].
    pub levels: Vec<[f64; 3]>,
}

impl KPlaneField {
    /// The field over the box `[aabb_min, aabb_max]`. Panics unless `spatial_res` is a
    /// power of two and `time_res`, `channels` are positive (the model config is
    /// validated before a field is built).
    pub fn new(config: KPlaneConfig, aabb_min: [f64; 3], aabb_max: [f64; 3]) -> Self {
        assert!(
            config.spatial_res.is_power_of_two(),
            "KPlaneField: spatial_res {} must be a power of two",
            config.spatial_res
        );
        assert!(config.time_res >= 1 && config.channels >= 1);
        KPlaneField {
            config,
            aabb_min,
            aabb_max,
        }
    }

    /// Zero planes in [`PLANE_NAMES`] order, each \[height, width, channels] (SaRO-GS
    /// `init_grid_param` zero-initialises spatial and time planes alike).
    pub fn zero_planes<T: Float>(&self) -> Vec<Tensor<T>> {
        (0..6)
            .map(|p| {
                let g = self.geom(p);
                Tensor::zeros(&[g.height, g.width, self.config.channels])
            })
            .collect()
    }

    fn geom_of(config: &KPlaneConfig, p: usize) -> PlaneGeom {
        let (a, b) = PLANE_AXES[p];
        let res = |axis: usize| {
            if axis == 3 {
                config.time_res
            } else {
                config.spatial_res
            }
        };
        let levels = if b == 3 {
            1
        } else {
            (config.spatial_res.trailing_zeros() as usize).min(config.max_mip_level) + 1
        };
        PlaneGeom {
            width: res(a),
            height: res(b),
            levels,
        }
    }

    /// Layout of plane `p`.
    pub fn geom(&self, p: usize) -> PlaneGeom {
        Self::geom_of(&self.config, p)
    }

    /// Builds the detached query for `N` Gaussians from canonical centres \[N*3],
    /// temporal centres \[N] (already in the field's time unit, \[0, 1]) and activated
    /// scales \[N*3] (SaRO-GS `ScaleAwareResField.get_density` + `get_level`).
    pub fn query<T: Float>(&self, means: &[T], t_centre: &[T], scales: &[T]) -> FieldQuery {
        let n = t_centre.len();
        assert_eq!(means.len(), 3 * n);
        assert_eq!(scales.len(), 3 * n);
        let res = self.config.spatial_res as f64;
        let extent: [f64; 3] = std::array::from_fn(|a| self.aabb_max[a] - self.aabb_min[a]);
        let base: [f64; 3] = std::array::from_fn(|a| extent[a] / res);
        let mut coords = Vec::with_capacity(n);
        let mut levels = Vec::with_capacity(n);
        for i in 0..n {
            let c: [f64; 4] = std::array::from_fn(|a| {
                if a == 3 {
                    Float::to_f64(t_centre[i])
                } else {
                    (Float::to_f64(means[3 * i + a]) - self.aabb_min[a]) / extent[a]
                }
            });
            let l: [f64; 3] = std::array::from_fn(|a| {
                let s = Float::to_f64(scales[3 * i + a]).clamp(base[a] / 2.0, base[a] / 2.0 * res);
                (2.0 * s / base[a]).log2().clamp(0.0, res.log2())
            });
            coords.push(c);
            levels.push(l);
        }
        FieldQuery { coords, levels }
    }

    /// Number of scalars in the six planes.
    pub fn num_scalars(&self) -> usize {
        (0..6)
            .map(|p| {
                let g = self.geom(p);
                g.height * g.width * self.config.channels
            })
            .sum()
    }
}
