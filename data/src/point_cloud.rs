//! The coloured point cloud a representation starts from: a data set's `points3d.ply`,
//! the visual hull of its masks, or random points in its bounds.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// A coloured point cloud used to initialise a representation.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCloud {
    /// Positions.
    pub points: Vec<[f64; 3]>,
    /// Colours in \[0, 1].
    pub colours: Vec<[f64; 3]>,
    /// Time at which each point was observed, when the source has one (a multi-view
    /// video's per-frame points); a representation with temporal centres starts them
    /// there instead of at random.
    pub times: Option<Vec<f64>>,
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
        PointCloud {
            points,
            colours,
            times: None,
        }
    }

    /// At most `max` of the points, chosen uniformly without replacement by a seeded
    /// partial Fisher-Yates shuffle and kept in their original order; the cloud
    /// itself when it has no more than `max`.
    pub fn subsample(&self, max: usize, seed: u64) -> PointCloud {
        let n = self.len();
        if n <= max {
            return self.clone();
        }
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut order: Vec<usize> = (0..n).collect();
        for i in 0..max {
            let j = rng.random_range(i..n);
            order.swap(i, j);
        }
        let mut keep = order[..max].to_vec();
        keep.sort_unstable();
        PointCloud {
            points: keep.iter().map(|&i| self.points[i]).collect(),
            colours: keep.iter().map(|&i| self.colours[i]).collect(),
            times: self
                .times
                .as_ref()
                .map(|t| keep.iter().map(|&i| t[i]).collect()),
        }
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
