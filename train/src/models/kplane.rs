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

use std::sync::Arc;

use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::{Float, Tensor};
use serde::{Deserialize, Serialize};

/// The axes (0 = x, 1 = y, 2 = z, 3 = t) of the six planes, in SaRO-GS order.
pub const PLANE_AXES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// Names of the six planes, in [`PLANE_AXES`] order.
pub const PLANE_NAMES: [&str; 6] = ["xy", "xz", "xt", "yz", "yt", "zt"];

/// Sizes of the field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
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

/// Up to 8 (pyramid texel, weight) taps: 4 bilinear taps on each of two levels.
type Taps = [(usize, f64); 8];

/// Taps of one lookup of a plane: point (u, v) in \[0,1]^2 (clamped at the border),
/// mip level `level` (clamped to the pyramid). Returns the number of taps used.
fn plane_taps(g: &PlaneGeom, u: f64, v: f64, level: f64, taps: &mut Taps) -> usize {
    let max_level = (g.levels - 1) as f64;
    let level = if level.is_nan() {
        0.0
    } else {
        level.clamp(0.0, max_level)
    };
    let l0 = level.floor() as usize;
    let f = level - l0 as f64;
    let mut count = 0;
    let mut add_level = |l: usize, wl: f64, count: &mut usize| {
        let (w, h) = g.dims(l);
        let off = g.offset(l);
        let x = u * w as f64 - 0.5;
        let y = v * h as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let clampi = |i: f64, n: usize| (i.max(0.0) as usize).min(n - 1);
        let (ix0, ix1) = (clampi(x0, w), clampi(x0 + 1.0, w));
        let (iy0, iy1) = (clampi(y0, h), clampi(y0 + 1.0, h));
        for (iy, wy) in [(iy0, 1.0 - fy), (iy1, fy)] {
            for (ix, wx) in [(ix0, 1.0 - fx), (ix1, fx)] {
                taps[*count] = (off + iy * w + ix, wl * wx * wy);
                *count += 1;
            }
        }
    };
    add_level(l0, 1.0 - f, &mut count);
    if f > 0.0 && l0 + 1 < g.levels {
        add_level(l0 + 1, f, &mut count);
    }
    count
}

/// The (u, v, level) at which Gaussian `i` looks up plane `p`.
fn lookup(q: &FieldQuery, i: usize, p: usize) -> (f64, f64, f64) {
    let (a, b) = PLANE_AXES[p];
    let c = &q.coords[i];
    let level = if b == 3 {
        0.0
    } else {
        q.levels[i][a].min(q.levels[i][b])
    };
    (c[a], c[b], level)
}

/// Parent -> children of the 2x2 box pyramid: calls `f(parent, child)` for the four
/// children of every texel of level `l` (l >= 1), indices into the whole pyramid.
fn for_each_child(g: &PlaneGeom, l: usize, mut f: impl FnMut(usize, usize)) {
    let (w, h) = g.dims(l);
    let (wc, hc) = g.dims(l - 1);
    let (off, offc) = (g.offset(l), g.offset(l - 1));
    for j in 0..h {
        for i in 0..w {
            for cj in [(2 * j).min(hc - 1), (2 * j + 1).min(hc - 1)] {
                for ci in [(2 * i).min(wc - 1), (2 * i + 1).min(wc - 1)] {
                    f(off + j * w + i, offc + cj * wc + ci);
                }
            }
        }
    }
}

/// Mip pyramid of a plane \[H, W, C]: level 0 is the plane, level l the 2x2 box mean
/// of level l-1 (nvdiffrast's mip construction for power-of-two textures).
pub fn build_pyramid<T: Float>(g: &PlaneGeom, plane: &[T], c: usize) -> Vec<T> {
    let mut pyr = vec![T::zero(); g.pyramid_texels() * c];
    pyr[..plane.len()].copy_from_slice(plane);
    let quarter = T::of(0.25);
    for l in 1..g.levels {
        for_each_child(g, l, |parent, child| {
            for k in 0..c {
                let v = pyr[child * c + k] * quarter;
                pyr[parent * c + k] += v;
            }
        });
    }
    pyr
}

/// Sums the six plane lookups of every Gaussian: output \[N, C]. Inputs: the six planes
/// in [`PLANE_NAMES`] order. The query is a constant of the op (detached).
pub struct PlaneSample {
    query: Arc<FieldQuery>,
    geoms: [PlaneGeom; 6],
    channels: usize,
    /// Test-only corruption of the backward (negative control of the gradchecks).
    corrupt_backward: bool,
}

impl PlaneSample {
    /// The op for `field`'s layout and a detached `query`.
    pub fn new(field: &KPlaneField, query: Arc<FieldQuery>) -> Self {
        PlaneSample {
            query,
            geoms: std::array::from_fn(|p| field.geom(p)),
            channels: field.config.channels,
            corrupt_backward: false,
        }
    }

    /// The same op with a deliberately wrong backward (drops the second mip level's
    /// taps), for negative controls.
    #[cfg(test)]
    pub(crate) fn corrupted(mut self) -> Self {
        self.corrupt_backward = true;
        self
    }
}

impl<T: Float> Op<T> for PlaneSample {
    type Saved = ();

    fn name(&self) -> String {
        "kplane_sample".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        assert_eq!(inputs.len(), 6, "kplane_sample: needs the six planes");
        let c = self.channels;
        let n = self.query.coords.len();
        let mut out = vec![T::zero(); n * c];
        let mut taps: Taps = [(0, 0.0); 8];
        for (p, g) in self.geoms.iter().enumerate() {
            assert_eq!(
                inputs[p].shape(),
                &[g.height, g.width, c],
                "kplane_sample: plane {} has the wrong shape",
                PLANE_NAMES[p]
            );
            let pyr = build_pyramid(g, inputs[p].data(), c);
            for (i, row) in out.chunks_exact_mut(c).enumerate() {
                let (u, v, level) = lookup(&self.query, i, p);
                let used = plane_taps(g, u, v, level, &mut taps);
                for &(texel, w) in &taps[..used] {
                    let w = T::of(w);
                    let src = &pyr[texel * c..(texel + 1) * c];
                    for (o, &s) in row.iter_mut().zip(src) {
                        *o += w * s;
                    }
                }
            }
        }
        (vec![Tensor::from_vec(out, &[n, c])], ())
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let c = self.channels;
        let g_out = ctx.grad_outputs[0].data();
        let mut taps: Taps = [(0, 0.0); 8];
        let quarter = T::of(0.25);
        (0..6)
            .map(|p| {
                if !ctx.needs_grad[p] {
                    return None;
                }
                let g = &self.geoms[p];
                let mut gp = vec![T::zero(); g.pyramid_texels() * c];
                for (i, gi) in g_out.chunks_exact(c).enumerate() {
                    let (u, v, level) = lookup(&self.query, i, p);
                    let mut used = plane_taps(g, u, v, level, &mut taps);
                    if self.corrupt_backward {
                        used = used.min(4);
                    }
                    for &(texel, w) in &taps[..used] {
                        let w = T::of(w);
                        for (d, &s) in gp[texel * c..(texel + 1) * c].iter_mut().zip(gi) {
                            *d += w * s;
                        }
                    }
                }
                // Adjoint of the pyramid: coarsest level first, so a parent's total
                // cotangent reaches its children before they pass it further down.
                for l in (1..g.levels).rev() {
                    for_each_child(g, l, |parent, child| {
                        for k in 0..c {
                            let v = gp[parent * c + k] * quarter;
                            gp[child * c + k] += v;
                        }
                    });
                }
                gp.truncate(g.width * g.height * c);
                Some(Tensor::from_vec(gp, &[g.height, g.width, c]))
            })
            .collect()
    }
}

/// Slow oracle of [`PlaneSample`]'s forward, built independently: a level-l texel is
/// the mean of the `2^l x 2^l` block of level-0 texels it covers, and bilinear
/// interpolation is a sum of hat functions `max(0, 1 - |i - x|)` over every texel at
/// the coordinate clamped to the texel-centre range (which equals clamp-to-edge).
pub fn reference_sample(
    field: &KPlaneField,
    planes: &[Tensor<f64>],
    query: &FieldQuery,
) -> Tensor<f64> {
    let c = field.config.channels;
    let n = query.coords.len();
    let mut out = vec![0.0; n * c];
    for (p, plane) in planes.iter().enumerate() {
        let g = field.geom(p);
        let texel = |l: usize, ix: usize, iy: usize, k: usize| -> f64 {
            let b = 1usize << l;
            let (mut sum, mut cnt) = (0.0, 0.0);
            for y in iy * b..((iy + 1) * b).min(g.height) {
                for x in ix * b..((ix + 1) * b).min(g.width) {
                    sum += plane.data()[(y * g.width + x) * c + k];
                    cnt += 1.0;
                }
            }
            sum / cnt
        };
        let bilinear = |l: usize, u: f64, v: f64, k: usize| -> f64 {
            let (w, h) = g.dims(l);
            let x = (u * w as f64 - 0.5).clamp(0.0, (w - 1) as f64);
            let y = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
            let mut s = 0.0;
            for iy in 0..h {
                let wy = (1.0 - (iy as f64 - y).abs()).max(0.0);
                for ix in 0..w {
                    let wx = (1.0 - (ix as f64 - x).abs()).max(0.0);
                    if wx * wy > 0.0 {
                        s += wx * wy * texel(l, ix, iy, k);
                    }
                }
            }
            s
        };
        for i in 0..n {
            let (u, v, level) = lookup(query, i, p);
            let level = level.clamp(0.0, (g.levels - 1) as f64);
            let l0 = level.floor() as usize;
            let f = level - l0 as f64;
            for k in 0..c {
                let mut val = (1.0 - f) * bilinear(l0, u, v, k);
                if f > 0.0 {
                    val += f * bilinear(l0 + 1, u, v, k);
                }
                out[i * c + k] += val;
            }
        }
    }
    Tensor::from_vec(out, &[n, c])
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::Tape;
    use maaf_autodiff::check::{GradcheckConfig, compare, gradcheck, tests_support::random_tensor};

    /// A small field with random planes and queries that cover the interior, the
    /// border (clamp) and every mip level, including fractional ones.
    fn fixture() -> (KPlaneField, Vec<Tensor<f64>>, FieldQuery) {
        let config = KPlaneConfig {
            spatial_res: 8,
            time_res: 5,
            channels: 3,
            max_mip_level: 7,
        };
        let field = KPlaneField::new(config, [-1.0, -2.0, 0.0], [1.0, 2.0, 3.0]);
        let planes: Vec<Tensor<f64>> = field
            .zero_planes::<f64>()
            .iter()
            .enumerate()
            .map(|(p, plane)| random_tensor(plane.shape(), -1.0, 1.0, 10 + p as u64))
            .collect();
        let n = 12;
        let mut means = random_tensor::<f64>(&[n, 3], -1.2, 3.2, 1).into_vec();
        // Gaussian 0 outside the box (clamp), Gaussian 1 exactly on a texel centre.
        means[0..3].copy_from_slice(&[-1.5, 2.5, 3.4]);
        means[3..6].copy_from_slice(&[-1.0 + 2.0 * 0.5 / 8.0, 0.0, 1.5]);
        let times = random_tensor::<f64>(&[n], -0.1, 1.1, 2).into_vec();
        // Scales from below the clamp (level 0) to above it (level log2 8 = 3).
        let scales = random_tensor::<f64>(&[n, 3], -5.0, 1.0, 3).map(f64::exp);
        let q = field.query(&means, &times, scales.data());
        (field, planes, q)
    }

    #[test]
    fn forward_matches_the_slow_reference() {
        let (field, planes, q) = fixture();
        assert!(q.levels.iter().flatten().any(|&l| l == 0.0));
        assert!(q.levels.iter().flatten().any(|&l| l == 3.0));
        assert!(q.levels.iter().flatten().any(|&l| l.fract() > 0.1));
        let tape = Tape::<f64>::new();
        let vars: Vec<_> = planes.iter().map(|p| tape.constant(p.clone())).collect();
        let out = tape.apply1(PlaneSample::new(&field, Arc::new(q.clone())), &vars);
        let want = reference_sample(&field, &planes, &q);
        // Same arithmetic up to summation order: a few ulps of O(1) values.
        let cmp = compare(&out.value(), &want, 1e-12, 1e-12);
        assert!(cmp.passed(), "{cmp:?}");
    }

    #[test]
    fn constant_planes_give_six_times_the_constant() {
        // A partition-of-unity check of the taps, at every level and at the border.
        let (field, planes, q) = fixture();
        let tape = Tape::<f64>::new();
        let vars: Vec<_> = planes
            .iter()
            .map(|p| tape.constant(Tensor::full(p.shape(), 0.5)))
            .collect();
        let out = tape.apply1(PlaneSample::new(&field, Arc::new(q)), &vars);
        assert!(out.value().data().iter().all(|&v| (v - 3.0).abs() < 1e-14));
    }

    #[test]
    fn plane_sample_passes_gradcheck_and_rejects_a_wrong_backward() {
        let (field, planes, q) = fixture();
        let q = Arc::new(q);
        // The op is linear in the planes, so central differences are exact up to
        // rounding (~1e-10 here); default tolerances (atol 1e-7, rtol 1e-5).
        let cfg = GradcheckConfig::default();
        let report = gradcheck(
            |t, v| t.apply1(PlaneSample::new(&field, q.clone()), v),
            &planes,
            &cfg,
        );
        report.assert_passed();
        let bad = gradcheck(
            |t, v| t.apply1(PlaneSample::new(&field, q.clone()).corrupted(), v),
            &planes,
            &cfg,
        );
        assert!(!bad.passed(), "the corrupted backward was not caught");
    }
}
