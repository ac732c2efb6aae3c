//! Rotation similarity (Dynamic 3D Gaussians `compute_rot_loss`, weight 4) as one
//! op with a hand-written backward: neighbours turn alike between frames.
//!
//! ```text
//! r_i = q_i / |q_i| * conj(p_i)                (relative rotation since k - 1)
//! L   = mean_ij sqrt(w_ij |r_j - r_i|^2 + 1e-20)
//! ```
//!
//! with `q` the current frame's quaternions (the variables) and `p` the previous
//! frame's unit quaternions (constants).

use std::sync::Arc;

use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::{Float, Tensor};
use rayon::prelude::*;

use super::frames::Frame;
use super::neighbours::{Neighbours, root_vjp, row};
use super::quat::Relative;

/// The rotation-similarity op: input the quaternions `[N, 4]` of the current frame,
/// output the scalar `L` (module docs).
pub struct Similarity<T: Float> {
    neighbours: Arc<Neighbours>,
    previous: Arc<Frame<T>>,
    /// Test-only negative control: leave out the gradient to the neighbour `j`.
    #[cfg(test)]
    fault: bool,
}

impl<T: Float> Similarity<T> {
    /// The op over `neighbours` against the `previous` frame.
    pub fn new(neighbours: Arc<Neighbours>, previous: Arc<Frame<T>>) -> Self {
        Similarity {
            neighbours,
            previous,
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

    /// Every Gaussian's relative rotation.
    fn relative(&self, quats: &[T]) -> Vec<Relative> {
        let before = self.previous.quats.data();
        (0..self.neighbours.len())
            .into_par_iter()
            .map(|i| Relative::new(row(quats, i), row(before, i)))
            .collect()
    }
}

/// `r_j - r_i`.
fn difference(rel: &[Relative], i: usize, j: usize) -> [f64; 4] {
    std::array::from_fn(|a| rel[j].value[a] - rel[i].value[a])
}

impl<T: Float> Op<T> for Similarity<T> {
    type Saved = ();

    fn name(&self) -> String {
        "track_rotation".into()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let nb = &self.neighbours;
        let rel = self.relative(x[0].data());
        let mean = nb.mean_root(|_| (), |(), i, p| difference(&rel, i, nb.index[p]));
        (vec![Tensor::scalar(T::of(mean))], ())
    }

    /// With `g = dL/dL_out / M`: `dL/dr_j += g w (r_j - r_i) / sqrt(..)` and the
    /// same subtracted from `dL/dr_i`; [`Relative::vjp`] carries each to `q`.
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let nb = &self.neighbours;
        let rel = self.relative(c.inputs[0].data());
        let g = nb.seed(&c.grad_outputs[0]);
        let (own, to_neighbour) = nb.per_row::<4, 4>(|i, own, out| {
            for (s, slot) in out.iter_mut().enumerate() {
                let p = i * nb.k + s;
                *slot = root_vjp(g, nb.weight[p], difference(&rel, i, nb.index[p]));
                for a in 0..4 {
                    own[a] -= slot[a];
                }
                #[cfg(test)]
                if self.fault {
                    *slot = [0.0; 4];
                }
            }
        });
        let drel = nb.gather(&own, &to_neighbour);
        let dq: Vec<T> = drel
            .par_iter()
            .zip(&rel)
            .flat_map_iter(|(g, r)| r.vjp(*g).map(T::of))
            .collect();
        vec![Some(Tensor::from_vec(dq, c.inputs[0].shape()))]
    }
}
