//! Isometry (Dynamic 3D Gaussians `compute_iso_loss`, weight 2) as one op with a
//! hand-written backward: neighbours keep their first-frame distance.
//!
//! ```text
//! l_ij = sqrt(|mu_j - mu_i|^2 + 1e-20)
//! L    = mean_ij sqrt(w_ij (l_ij - |mu_j0 - mu_i0|)^2 + 1e-20)
//! ```
//!
//! with `mu` the current frame's centres (the variables) and `mu_0` the first
//! frame's (constants, [`Neighbours::distance`]).

use std::sync::Arc;

use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::{Float, Tensor};

use super::neighbours::{EPS, Neighbours, root_vjp, row};

/// The isometry op: input the centres `[N, 3]` of the current frame, output the
/// scalar `L` (module docs).
pub struct Isometry {
    neighbours: Arc<Neighbours>,
    /// Test-only negative control: a gradient twice too large.
    #[cfg(test)]
    fault: bool,
}

impl Isometry {
    /// The op over `neighbours`.
    pub fn new(neighbours: Arc<Neighbours>) -> Self {
        Isometry {
            neighbours,
            #[cfg(test)]
            fault: false,
        }
    }

    /// Test-only: the same op with its deliberate backward fault on (`on`).
    #[cfg(test)]
    pub(super) fn faulty(mut self, on: bool) -> Self {
        self.fault = on;
        self
    }
}

/// `(mu_j - mu_i, l_ij)` of pair `p = (i, j)`.
fn offset<T: Float>(nb: &Neighbours, means: &[T], i: usize, p: usize) -> ([f64; 3], f64) {
    let (mi, mj) = (row::<T, 3>(means, i), row::<T, 3>(means, nb.index[p]));
    let d: [f64; 3] = std::array::from_fn(|a| mj[a] - mi[a]);
    let l = (d.iter().map(|v| v * v).sum::<f64>() + EPS).sqrt();
    (d, l)
}

impl<T: Float> Op<T> for Isometry {
    type Saved = ();

    fn name(&self) -> String {
        "track_isometry".into()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let nb = &self.neighbours;
        let means = x[0].data();
        let mean = nb.mean_root(
            |_| (),
            |(), i, p| [offset(nb, means, i, p).1 - nb.distance[p]],
        );
        (vec![Tensor::scalar(T::of(mean))], ())
    }

    /// With `g = dL/dL_out / M`: `dL/dl = g w (l - l_0) / sqrt(..)` and
    /// `dL/d(mu_j - mu_i) = dL/dl (mu_j - mu_i) / l`, to `mu_j`, minus to `mu_i`.
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let nb = &self.neighbours;
        let means = c.inputs[0].data();
        let g = nb.seed(&c.grad_outputs[0]);
        #[cfg(test)]
        let g = if self.fault { 2.0 * g } else { g };
        let (own, to_neighbour) = nb.per_row::<3, 3>(|i, own, out| {
            for (s, slot) in out.iter_mut().enumerate() {
                let p = i * nb.k + s;
                let (d, l) = offset(nb, means, i, p);
                let [gl] = root_vjp(g, nb.weight[p], [l - nb.distance[p]]);
                *slot = d.map(|v| gl * v / l);
                for a in 0..3 {
                    own[a] -= slot[a];
                }
            }
        });
        let dmeans = nb.gather(&own, &to_neighbour);
        let dm = dmeans.iter().flatten().map(|&v| T::of(v)).collect();
        vec![Some(Tensor::from_vec(dm, c.inputs[0].shape()))]
    }
}
