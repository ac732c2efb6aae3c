//! Exact k nearest neighbours of every point of a cloud: what 3DGS's initial scale
//! (`distCUDA2`, k = 3) and Dynamic 3D Gaussians' neighbour regularisers (`o3d_knn`,
//! k = 20) read.

use rayon::prelude::*;

/// The `k` nearest other points of each of `n` points, nearest first, row-major
/// `[n, k]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Knn {
    /// Neighbours per point (`min(k, n - 1)` of the request).
    pub k: usize,
    /// Index of neighbour `s` of point `i` at `i * k + s`.
    pub index: Vec<usize>,
    /// Its squared distance to point `i`, ascending along each row.
    pub sq_dist: Vec<f64>,
}

/// The `k` nearest other points of every point (`min(k, n - 1)` of them; none for a
/// single point). Exact: a uniform grid (about two points per cell) is searched ring
/// by ring around each point until the k-th candidate is closer than the searched
/// radius, so the result equals brute force; equal distances keep the order the
/// search met them in. O(N) for roughly uniform clouds; points run in parallel, each
/// on its own, so the result does not depend on the thread count.
pub fn knn(points: &[[f64; 3]], k: usize) -> Knn {
    let n = points.len();
    let k = k.min(n.saturating_sub(1));
    if k == 0 {
        return Knn {
            k,
            index: Vec::new(),
            sq_dist: Vec::new(),
        };
    }
    let grid = Grid::new(points);
    let rows: Vec<Vec<(f64, usize)>> = (0..n)
        .into_par_iter()
        .map(|i| grid.nearest(points, i, k))
        .collect();
    Knn {
        k,
        index: rows.iter().flatten().map(|&(_, j)| j).collect(),
        sq_dist: rows.iter().flatten().map(|&(d, _)| d).collect(),
    }
}

/// The points sorted into a uniform grid of cubic cells (a counting sort by cell).
struct Grid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// Points of cell `c` are `order[start[c]..start[c + 1]]`.
    start: Vec<usize>,
    order: Vec<usize>,
}

impl Grid {
    fn new(points: &[[f64; 3]]) -> Self {
        let (lo, hi) = points.iter().fold(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    std::array::from_fn(|a| lo[a].min(p[a])),
                    std::array::from_fn(|a| hi[a].max(p[a])),
                )
            },
        );
        let n = points.len();
        // About two points per cell on average.
        let volume: f64 = (0..3).map(|a| hi[a] - lo[a]).product();
        let cell = (2.0 * volume / n as f64).cbrt().max(1e-9);
        let dims =
            std::array::from_fn(|a| (((hi[a] - lo[a]) / cell).ceil() as usize).clamp(1, 1 << 10));
        let mut grid = Grid {
            lo,
            cell,
            dims,
            start: vec![0; dims[0] * dims[1] * dims[2] + 1],
            order: vec![0; n],
        };
        for p in points {
            let c = grid.flat(grid.cell_of(p));
            grid.start[c + 1] += 1;
        }
        for i in 1..grid.start.len() {
            grid.start[i] += grid.start[i - 1];
        }
        let mut fill = grid.start.clone();
        for (i, p) in points.iter().enumerate() {
            let c = grid.flat(grid.cell_of(p));
            grid.order[fill[c]] = i;
            fill[c] += 1;
        }
        grid
    }

    fn cell_of(&self, p: &[f64; 3]) -> [usize; 3] {
        std::array::from_fn(|a| {
            (((p[a] - self.lo[a]) / self.cell).floor().max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    fn flat(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// The `k` nearest points to point `i` other than itself as (squared distance,
    /// index), nearest first.
    fn nearest(&self, points: &[[f64; 3]], i: usize, k: usize) -> Vec<(f64, usize)> {
        let p = &points[i];
        let c = self.cell_of(p);
        let max_ring = self.dims.iter().copied().max().unwrap_or(1);
        let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
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
                        if (0..3).any(|a| q[a] < 0 || q[a] >= self.dims[a] as isize) {
                            continue;
                        }
                        let cf = self.flat([q[0] as usize, q[1] as usize, q[2] as usize]);
                        for &j in &self.order[self.start[cf]..self.start[cf + 1]] {
                            if j == i {
                                continue;
                            }
                            let d2: f64 = (0..3).map(|a| (points[j][a] - p[a]).powi(2)).sum();
                            if best.len() < k || d2 < best[k - 1].0 {
                                let pos = best.partition_point(|&(b, _)| b <= d2);
                                best.insert(pos, (d2, j));
                                best.truncate(k);
                            }
                        }
                    }
                }
            }
            // Every point within distance ring*cell of p lies in rings 0..=ring.
            let covered = ring as f64 * self.cell;
            if best.len() == k && best[k - 1].0 <= covered * covered {
                break;
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PointCloud;

    #[test]
    fn neighbours_and_the_initial_scale_match_brute_force() {
        let mut points = PointCloud::random_in_box(300, -1.3, 1.3, 4).points;
        // A flat patch and a duplicate: degenerate boxes and zero distances.
        points.extend((0..20).map(|i| [0.1 * f64::from(i), 0.5, 0.5]));
        points.push(points[0]);
        let got = knn(&points, 20);
        let initial = crate::knn_mean_sq_dist(&points, 3);
        assert_eq!(got.k, 20);
        for (i, p) in points.iter().enumerate() {
            let mut d: Vec<f64> = points
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, q)| (0..3).map(|a| (q[a] - p[a]).powi(2)).sum())
                .collect();
            d.sort_by(f64::total_cmp);
            let row = &got.sq_dist[20 * i..20 * (i + 1)];
            assert_eq!(row, &d[..20], "row {i}");
            let mean3 = (d[0] + d[1] + d[2]) / 3.0;
            assert_eq!(mean3.max(1e-7), initial[i], "3DGS's initial scale, row {i}");
            for (s, &j) in got.index[20 * i..20 * (i + 1)].iter().enumerate() {
                let q = points[j];
                let d2: f64 = (0..3).map(|a| (q[a] - p[a]).powi(2)).sum();
                assert!(j != i && d2 == row[s], "row {i} slot {s}");
            }
        }
        assert_eq!(knn(&points[..1], 20).k, 0);
        assert_eq!(knn(&points[..5], 20).k, 4);
    }
}
