//! The neighbour pairs of the tracking regularisers (Dynamic 3D Gaussians
//! `initialize_post_first_timestep`): each Gaussian's `k` nearest others on the
//! first frame's centres, found once, with their weights and first-frame distances.

use rayon::prelude::*;

use crate::knn::knn;

/// Added under every square root of the neighbour terms (the reference's
/// `weighted_l2_loss`: `sqrt(x + 1e-20)`), so a term is differentiable where its
/// residual vanishes.
pub const EPS: f64 = 1e-20;

/// Pairs `(i, j)`, `j` one of the `k` nearest neighbours of `i` on the first frame's
/// centres `mu_0`, row-major `[n, k]` (pair `p = i k + s`), with
/// `w_ij = exp(-falloff |mu_j0 - mu_i0|^2)` and `|mu_j0 - mu_i0|`.
#[derive(Clone, Debug, PartialEq)]
pub struct Neighbours {
    /// Neighbours per Gaussian (`min(k, n - 1)`).
    pub k: usize,
    /// `j` of each pair.
    pub index: Vec<usize>,
    /// `w_ij` of each pair.
    pub weight: Vec<f64>,
    /// `|mu_j0 - mu_i0|` of each pair.
    pub distance: Vec<f64>,
    /// Pairs whose neighbour is Gaussian `r`: `incoming[start[r]..start[r + 1]]`,
    /// ascending (a gather in a fixed order, so the backward's sums do not depend on
    /// the thread count).
    start: Vec<usize>,
    incoming: Vec<usize>,
}

impl Neighbours {
    /// The `k` nearest neighbours of every centre of `points` (exact, [`knn`]) and
    /// their weights with `falloff` (the reference's 2000, in inverse squared world
    /// units).
    pub fn new(points: &[[f64; 3]], k: usize, falloff: f64) -> Self {
        let near = knn(points, k);
        let n = points.len();
        let mut start = vec![0usize; n + 1];
        for &j in &near.index {
            start[j + 1] += 1;
        }
        for r in 1..=n {
            start[r] += start[r - 1];
        }
        let mut fill = start.clone();
        let mut incoming = vec![0usize; near.index.len()];
        for (p, &j) in near.index.iter().enumerate() {
            incoming[fill[j]] = p;
            fill[j] += 1;
        }
        Neighbours {
            k: near.k,
            weight: near.sq_dist.iter().map(|d| (-falloff * d).exp()).collect(),
            distance: near.sq_dist.iter().map(|d| d.sqrt()).collect(),
            index: near.index,
            start,
            incoming,
        }
    }

    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// True for no Gaussian.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of pairs, `n k`: what the regularisers average over.
    pub fn pairs(&self) -> usize {
        self.index.len()
    }

    /// `mean_ij sqrt(w_ij |v_ij|^2 + 1e-20)` over every pair (0 without pairs), the
    /// form of the three neighbour terms: `v_ij = residual(&setup(i), i, p)` for pair
    /// `p = (i, j)`, with `setup(i)` computed once per Gaussian. Each Gaussian's pairs
    /// are summed on their own (in parallel), then the Gaussians in order.
    pub fn mean_root<S, const W: usize>(
        &self,
        setup: impl Fn(usize) -> S + Sync + Send,
        residual: impl Fn(&S, usize, usize) -> [f64; W] + Sync + Send,
    ) -> f64 {
        let rows: Vec<f64> = (0..self.len())
            .into_par_iter()
            .map(|i| {
                let s = setup(i);
                (i * self.k..(i + 1) * self.k)
                    .map(|p| root(self.weight[p], residual(&s, i, p)))
                    .sum::<f64>()
            })
            .collect();
        match self.pairs() {
            0 => 0.0,
            m => rows.iter().sum::<f64>() / m as f64,
        }
    }

    /// The cotangent of each pair's root from the cotangent of the mean (the op's
    /// output): `dL/dL_out / (n k)`.
    pub fn seed<T: maaf_autodiff::Float>(&self, grad_output: &maaf_autodiff::Tensor<T>) -> f64 {
        grad_output.data()[0].to_f64() / self.pairs().max(1) as f64
    }

    /// The cotangents of a per-Gaussian input of width `W` when each Gaussian `i` gives
    /// `own[i]` to itself and `to_neighbour[p]` to the neighbour `j` of each of its
    /// pairs `p`: `own[r] + sum_{p: j = r} to_neighbour[p]`, the incoming pairs added
    /// in ascending order.
    pub fn gather<const W: usize>(
        &self,
        own: &[[f64; W]],
        to_neighbour: &[[f64; W]],
    ) -> Vec<[f64; W]> {
        (0..self.len())
            .into_par_iter()
            .map(|r| {
                let mut g = own[r];
                for &p in &self.incoming[self.start[r]..self.start[r + 1]] {
                    for (a, v) in g.iter_mut().zip(&to_neighbour[p]) {
                        *a += v;
                    }
                }
                g
            })
            .collect()
    }

    /// Runs `f(i, own_i, pairs_i)` for every Gaussian `i` in parallel, where `own_i`
    /// is its slot of a `[n]` output and `pairs_i` its `k` slots of a `[n k]` output
    /// (both start at zero): the first half of a backward, before [`Self::gather`].
    pub fn per_row<const W: usize, const V: usize>(
        &self,
        f: impl Fn(usize, &mut [f64; W], &mut [[f64; V]]) + Sync + Send,
    ) -> (Vec<[f64; W]>, Vec<[f64; V]>) {
        let mut own = vec![[0.0; W]; self.len()];
        let mut pairs = vec![[0.0; V]; self.pairs()];
        if self.k > 0 {
            own.par_iter_mut()
                .zip(pairs.par_chunks_mut(self.k))
                .enumerate()
                .for_each(|(i, (o, p))| f(i, o, p));
        }
        (own, pairs)
    }
}

/// A pair's root `sqrt(w |v|^2 + 1e-20)` of its weight `w` and residual `v`.
fn root<const W: usize>(w: f64, v: [f64; W]) -> f64 {
    (w * v.iter().map(|x| x * x).sum::<f64>() + EPS).sqrt()
}

/// `g d/dv sqrt(w |v|^2 + 1e-20) = g w v / sqrt(w |v|^2 + 1e-20)`: the cotangent of a
/// pair's residual `v` from the cotangent `g` of its root.
pub fn root_vjp<const W: usize>(g: f64, w: f64, v: [f64; W]) -> [f64; W] {
    let r = root(w, v);
    v.map(|x| g * w * x / r)
}

/// Row `i` of a row-major `[n, W]` slice, as f64.
pub fn row<T: maaf_autodiff::Float, const W: usize>(data: &[T], i: usize) -> [f64; W] {
    std::array::from_fn(|a| data[W * i + a].to_f64())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incoming_lists_every_pair_once_under_its_neighbour() {
        let points = crate::PointCloud::random_in_box(50, -1.0, 1.0, 2).points;
        let nb = Neighbours::new(&points, 6, 3.0);
        assert_eq!((nb.len(), nb.k, nb.pairs()), (50, 6, 300));
        let own = vec![[0.0]; 50];
        let ones: Vec<[f64; 1]> = (0..300).map(|p| [p as f64]).collect();
        let got = nb.gather(&own, &ones);
        for (r, g) in got.iter().enumerate() {
            let want: f64 = (0..300)
                .filter(|&p| nb.index[p] == r)
                .map(|p| p as f64)
                .sum();
            assert_eq!(g[0], want);
        }
        for p in 0..300 {
            let d2 = nb.distance[p] * nb.distance[p];
            assert!((nb.weight[p] - (-3.0 * d2).exp()).abs() < 1e-12);
        }
    }
}
