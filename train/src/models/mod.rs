//! 4D representations (DESIGN.md section 5): parameters bound on a tape plus a time t
//! give deformed 3D Gaussians as [`Var`]s.
//!
//! The trainer, the 3D filter and the renderer only see [`DeformedGaussians`]; which
//! representation produced them is hidden behind [`Representation`]. One training
//! step reads:
//!
//! ```text
//! model.set_iteration(i);                       // stage switch (e.g. SaRO static warm-up)
//! let tape = Tape::new();
//! let bound = model.bind(&tape);                // registers every parameter by name
//! for view in batch {
//!     let g = bound.deform(view.time);          // means, scales, quats, opacity, sh
//!     ... filter fold, render, photometric terms ...
//! }
//! for r in bound.regularisers() { ... }         // e.g. "l_sr", with its default weight
//! let grads = tape.backward(loss)?;
//! for slot in model.params_mut() { if let Some(g) = grads.param(&slot.name) { adam.step(...) } }
//! ```
//!
//! Densification expresses every change as one row index list (see
//! [`maaf_autodiff::PerGaussian`]): [`Representation::select_rows`] resizes every
//! per-Gaussian parameter, and [`Representation::set_rows`] then overwrites the means
//! and scales of the rows a split created.

pub mod kplane;
pub mod saro;

use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, Tape, Tensor, Var};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

pub use kplane::{KPlaneConfig, KPlaneField};
pub use saro::{SaroConfig, SaroModel};

/// The deformed 3D Gaussians at one time, as the renderer takes them.
///
/// Conventions (DESIGN.md section 3): `means` \[N,3] world units; `scales` \[N,3]
/// **activated** (positive standard deviations); `quats` \[N,4] w,x,y,z, **not**
/// normalised (the renderer normalises); `opacity` \[N] **activated**, in (0,1);
/// `sh` \[N,K,3] with K = (degree+1)^2, colour = max(SH + 0.5, 0).
pub struct DeformedGaussians<'t, T: Float> {
    /// Centres \[N,3].
    pub means: Var<'t, T>,
    /// Activated scales \[N,3].
    pub scales: Var<'t, T>,
    /// Unnormalised quaternions \[N,4] (w,x,y,z).
    pub quats: Var<'t, T>,
    /// Activated opacity \[N] (for SaRO: sigmoid opacity times the temporal factor).
    pub opacity: Var<'t, T>,
    /// Spherical-harmonic coefficients \[N,K,3].
    pub sh: Var<'t, T>,
}

/// A named regulariser value that the objective may pick up (DESIGN.md section 6).
///
/// `value` is the unweighted term; `default_weight` is the weight the reference uses
/// (the objective decides the weight it applies).
pub struct Regulariser<'t, T: Float> {
    /// Name under which the term is logged, e.g. `"l_sr"`.
    pub name: String,
    /// Unweighted value (one element).
    pub value: Var<'t, T>,
    /// Weight used by the reference implementation.
    pub default_weight: f64,
}

/// A representation bound on one tape: deforms to any time, any number of times.
///
/// Work that does not depend on the render time (for SaRO the residual-field features
/// and the lifespans) is done once at bind time and shared by every `deform` call, so
/// a batch of views at different times costs one field query.
pub trait Bound<'t, T: Float> {
    /// The deformed Gaussians at `time` (the data set's time, in \[0, 1] for D-NeRF).
    fn deform(&self, time: f64) -> DeformedGaussians<'t, T>;
    /// Regularisers of this step (empty when none is active, e.g. in a warm-up stage).
    fn regularisers(&self) -> Vec<Regulariser<'t, T>>;
}

/// A mutable view of one trainable tensor with everything Adam needs to step it.
pub struct ParamSlot<'a, T: Float> {
    /// Name under which [`Representation::bind`] registers the tensor on the tape
    /// (read its gradient with `Grads::param(name)`).
    pub name: String,
    /// The values.
    pub value: &'a mut Tensor<T>,
    /// One row per Gaussian: resized by densification, with its Adam moments.
    pub per_gaussian: bool,
    /// Learning-rate schedule (already scaled by the scene extent where it applies).
    pub lr: LrSchedule,
    /// L2 weight decay the reference adds to the gradient (`g += wd * p`), 0 if none.
    pub weight_decay: f64,
}

/// Canonical (undeformed) per-Gaussian values, activated, as plain tensors: what
/// densification reads (scale threshold, split sampling, opacity prune).
#[derive(Clone, Debug)]
pub struct Canonical<T: Float> {
    /// Centres \[N,3].
    pub means: Tensor<T>,
    /// Activated scales \[N,3].
    pub scales: Tensor<T>,
    /// Unnormalised quaternions \[N,4] (w,x,y,z).
    pub quats: Tensor<T>,
    /// Activated base opacity \[N] (without any temporal factor).
    pub opacity: Tensor<T>,
}

/// A 4D representation (DESIGN.md section 5). Object safe: a trainer can hold a
/// `Box<dyn Representation<T>>`.
pub trait Representation<T: Float> {
    /// Short name (`"saro"`, later `"deform"`), as in `--model`.
    fn name(&self) -> &'static str;

    /// Number of Gaussians N.
    fn num_gaussians(&self) -> usize;

    /// Tells the model which iteration starts (1-based as in the references): a
    /// model with stages (SaRO's static warm-up) switches here.
    fn set_iteration(&mut self, iteration: usize);

    /// Registers the parameters the current stage uses on `tape` (by the names of
    /// [`Representation::params_mut`]) and returns the bound model.
    fn bind<'t>(&self, tape: &'t Tape<T>) -> Box<dyn Bound<'t, T> + 't>;

    /// Every trainable tensor with its Adam schedule. Parameters the current stage
    /// does not bind simply get no gradient.
    fn params_mut(&mut self) -> Vec<ParamSlot<'_, T>>;

    /// Replaces every per-Gaussian parameter's rows by `old\[index\[0]], old\[index\[1]], ...`
    /// (clone: repeat an index; split: repeat and drop; prune: leave out). Apply the
    /// same list to the optimiser moments and every other per-Gaussian container.
    fn select_rows(&mut self, index: &[usize]);

    /// Overwrites the canonical centres and **activated** scales of `rows` (after
    /// [`Representation::select_rows`] has created them, e.g. the two halves of a split).
    /// `means` and `scales` are \[rows.len(), 3].
    fn set_rows(&mut self, rows: &[usize], means: &Tensor<T>, scales: &Tensor<T>);

    /// Canonical values for densification.
    fn canonical(&self) -> Canonical<T>;

    /// Opacity reset: clamps every base opacity to at most `max_opacity` (3DGS uses 0.01).
    /// Returns the names of the parameters it overwrote, whose optimiser moments the
    /// trainer then zeroes (3DGS `replace_tensor_to_optimizer`): stale momentum would
    /// otherwise keep pushing the reset opacities down until pruning removes them.
    fn reset_opacity(&mut self, max_opacity: f64) -> Vec<String>;

    /// Indices of Gaussians the representation itself wants removed (SaRO: a temporal
    /// integral below the threshold). Empty by default.
    fn short_lived(&self) -> Vec<usize> {
        Vec::new()
    }

    /// Number of stored scalars (parameters only, no optimiser state).
    fn num_scalars(&self) -> usize;

    /// Deformed centres \[N,3] at each of `times`, outside any training tape: what the
    /// motion-aware filter refresh needs (DESIGN.md section 4: every training
    /// (camera, time) sees the *deformed* centre). The default deforms everything on a
    /// scratch tape per time; a representation should override it with a cheaper path.
    fn centres_at_times(&self, times: &[f64]) -> Vec<Tensor<T>> {
        times
            .iter()
            .map(|&t| {
                let tape = Tape::new();
                // The binding ends the borrow of the tape before the tape is dropped.
                #[allow(clippy::let_and_return)]
                let centres = self.bind(&tape).deform(t).means.value().clone();
                centres
            })
            .collect()
    }
}

/// A coloured point cloud used to initialise a representation.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCloud {
    /// Positions.
    pub points: Vec<[f64; 3]>,
    /// Colours in \[0, 1].
    pub colours: Vec<[f64; 3]>,
}

impl PointCloud {
    /// `n` points uniform in the box `\[lo, hi]^3` with uniform random colours, as
    /// SaRO-GS and D-NeRF loaders do for synthetic scenes (SaRO-GS
    /// `scene/dataset_readers.py`: 100 000 points in \[-1.3, 1.3]^3). Seeded.
    pub fn random_in_box(n: usize, lo: f64, hi: f64, seed: u64) -> Self {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut draw3 = |a: f64, b: f64| {
            [
                rng.random_range(a..b),
                rng.random_range(a..b),
                rng.random_range(a..b),
            ]
        };
        let points = (0..n).map(|_| draw3(lo, hi)).collect();
        let colours = (0..n).map(|_| draw3(0.0, 1.0)).collect();
        PointCloud { points, colours }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the cloud has no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Axis-aligned bounds `(min, max)`; a degenerate axis is widened to 1e-6 so that
    /// normalisation by the extent never divides by zero.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.points {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        for a in 0..3 {
            if !lo[a].is_finite() {
                (lo[a], hi[a]) = (-1.0, 1.0);
            }
            if hi[a] - lo[a] < 1e-6 {
                hi[a] = lo[a] + 1e-6;
            }
        }
        (lo, hi)
    }
}

/// SH band-0 constant C0 = 1 / (2 sqrt(pi)) (Inria/gsplat `SH_C0`).
pub const SH_C0: f64 = 0.282_094_791_773_878_1;

/// DC coefficient that renders as colour `c`: `(c - 0.5) / C0` (3DGS `RGB2SH`).
pub fn rgb_to_sh_dc(c: f64) -> f64 {
    (c - 0.5) / SH_C0
}

/// `ln(p / (1 - p))`, the inverse of the sigmoid (3DGS `inverse_sigmoid`).
pub fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

/// Mean squared distance from each point to its `k` nearest other points (3DGS
/// `distCUDA2` uses k = 3), clamped below at 1e-7 as 3DGS does. Exact: a uniform grid
/// is searched ring by ring until the k-th candidate is closer than the searched
/// radius, so the result equals brute force. O(N) for roughly uniform clouds.
pub fn knn_mean_sq_dist(points: &[[f64; 3]], k: usize) -> Vec<f64> {
    let n = points.len();
    if n <= 1 || k == 0 {
        return vec![1e-7; n];
    }
    let k = k.min(n - 1);
    let cloud = PointCloud {
        points: points.to_vec(),
        colours: Vec::new(),
    };
    let (lo, hi) = cloud.bounds();
    // About two points per cell on average.
    let volume: f64 = (0..3).map(|a| hi[a] - lo[a]).product();
    let cell = (2.0 * volume / n as f64).cbrt().max(1e-9);
    let dims: [usize; 3] =
        std::array::from_fn(|a| (((hi[a] - lo[a]) / cell).ceil() as usize).clamp(1, 1 << 10));
    let cell_of = |p: &[f64; 3]| -> [usize; 3] {
        std::array::from_fn(|a| {
            (((p[a] - lo[a]) / cell).floor().max(0.0) as usize).min(dims[a] - 1)
        })
    };
    let flat = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    // Counting sort of the points by cell.
    let mut start = vec![0usize; dims[0] * dims[1] * dims[2] + 1];
    for p in points {
        start[flat(cell_of(p)) + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut fill = start.clone();
    let mut order = vec![0usize; n];
    for (i, p) in points.iter().enumerate() {
        let c = flat(cell_of(p));
        order[fill[c]] = i;
        fill[c] += 1;
    }
    let max_ring = dims.iter().copied().max().unwrap_or(1);
    let mut out = Vec::with_capacity(n);
    let mut best: Vec<f64> = Vec::with_capacity(k + 1);
    for (i, p) in points.iter().enumerate() {
        let c = cell_of(p);
        best.clear();
        for ring in 0..=max_ring {
            // Visit the cells at Chebyshev distance exactly `ring` from c.
            let r = ring as isize;
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                            continue;
                        }
                        let q = [c[0] as isize + dx, c[1] as isize + dy, c[2] as isize + dz];
                        if (0..3).any(|a| q[a] < 0 || q[a] >= dims[a] as isize) {
                            continue;
                        }
                        let cf = flat([q[0] as usize, q[1] as usize, q[2] as usize]);
                        for &j in &order[start[cf]..start[cf + 1]] {
                            if j == i {
                                continue;
                            }
                            let d2: f64 = (0..3).map(|a| (points[j][a] - p[a]).powi(2)).sum();
                            if best.len() < k || d2 < best[k - 1] {
                                let pos = best.partition_point(|&b| b <= d2);
                                best.insert(pos, d2);
                                best.truncate(k);
                            }
                        }
                    }
                }
            }
            // Every point within distance ring*cell of p lies in rings 0..=ring.
            let covered = ring as f64 * cell;
            if best.len() == k && best[k - 1] <= covered * covered {
                break;
            }
        }
        let mean = best.iter().sum::<f64>() / best.len().max(1) as f64;
        out.push(mean.max(1e-7));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knn_matches_brute_force() {
        let cloud = PointCloud::random_in_box(400, -1.3, 1.3, 3);
        let fast = knn_mean_sq_dist(&cloud.points, 3);
        for (i, p) in cloud.points.iter().enumerate() {
            let mut d: Vec<f64> = cloud
                .points
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, q)| (0..3).map(|a| (q[a] - p[a]).powi(2)).sum())
                .collect();
            d.sort_by(f64::total_cmp);
            let want = (d[0] + d[1] + d[2]) / 3.0;
            // Same three distances summed in possibly another order: ~1 ulp.
            assert!(
                (fast[i] - want).abs() <= 1e-12 * want,
                "{i}: {} vs {want}",
                fast[i]
            );
        }
    }

    #[test]
    fn sh_dc_inverts_the_renderer_colour() {
        for c in [0.0, 0.3, 1.0] {
            assert!((rgb_to_sh_dc(c) * SH_C0 + 0.5 - c).abs() < 1e-15);
        }
        assert!((1.0 / (1.0 + (-logit(0.1)).exp()) - 0.1).abs() < 1e-15);
    }
}
