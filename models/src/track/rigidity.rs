//! Local rigidity (Dynamic 3D Gaussians `compute_rigid_loss`, weight 4) as one op
//! with a hand-written backward.
//!
//! For frame k > 0 with centres `mu` and quaternions `q` (the variables) and the
//! previous frame's centres `mu'` and unit quaternions `p` (constants):
//!
//! ```text
//! R_i   = rotation(q_i / |q_i| * conj(p_i))          (relative rotation since k - 1)
//! e_ij  = R_i^T (mu_j - mu_i) - (mu'_j - mu'_i)
//! L     = mean_ij sqrt(w_ij |e_ij|^2 + 1e-20)
//! ```
//!
//! over the pairs of [`Neighbours`]: the neighbours of each Gaussian keep their
//! offsets in its local frame as it moves.

use std::sync::Arc;

use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::{Float, Tensor};

use super::frames::Frame;
use maaf_splat::math::{quat_to_rotmat, rotmat_vjp};

use super::neighbours::{Neighbours, root_vjp, row};
use super::quat::Relative;

/// The local-rigidity op: inputs the centres `[N, 3]` and quaternions `[N, 4]` of the
/// current frame, output the scalar `L` (module docs).
pub struct Rigidity<T: Float> {
    neighbours: Arc<Neighbours>,
    previous: Arc<Frame<T>>,
    /// Test-only negative control: leave out the rotation's gradient.
    #[cfg(test)]
    fault: bool,
}

impl<T: Float> Rigidity<T> {
    /// The op over `neighbours` against the `previous` frame.
    pub fn new(neighbours: Arc<Neighbours>, previous: Arc<Frame<T>>) -> Self {
        Rigidity {
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

    /// Gaussian `i`'s relative rotation and its matrix.
    fn relative(&self, quats: &[T], i: usize) -> (Relative, [[f64; 3]; 3]) {
        let rel = Relative::new(row(quats, i), row(self.previous.quats.data(), i));
        let r = quat_to_rotmat(rel.value);
        (rel, r)
    }

    /// `(d, e)` of pair `p = (i, j)`: the current offset `mu_j - mu_i` and `e_ij`.
    fn residual(&self, means: &[T], r: &[[f64; 3]; 3], i: usize, p: usize) -> ([f64; 3], [f64; 3]) {
        let j = self.neighbours.index[p];
        let before = self.previous.means.data();
        let (mi, mj) = (row::<T, 3>(means, i), row::<T, 3>(means, j));
        let (pi, pj) = (row::<T, 3>(before, i), row::<T, 3>(before, j));
        let d: [f64; 3] = std::array::from_fn(|a| mj[a] - mi[a]);
        let e =
            std::array::from_fn(|a| (0..3).map(|b| r[b][a] * d[b]).sum::<f64>() - (pj[a] - pi[a]));
        (d, e)
    }
}

impl<T: Float> Op<T> for Rigidity<T> {
    type Saved = ();

    fn name(&self) -> String {
        "track_rigidity".into()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (means, quats) = (x[0].data(), x[1].data());
        let mean = self.neighbours.mean_root(
            |i| self.relative(quats, i).1,
            |r, i, p| self.residual(means, r, i, p).1,
        );
        (vec![Tensor::scalar(T::of(mean))], ())
    }

    /// With `g = dL/dL_out / M`: `dL/de = g w e / sqrt(w |e|^2 + 1e-20)`,
    /// `dL/d(mu_j - mu_i) = R dL/de` (to `mu_j`, minus to `mu_i`), and
    /// `dL/dR = sum_j (mu_j - mu_i) (dL/de)^T`, which [`rotmat_vjp`] and
    /// [`Relative::vjp`] carry to `q_i`.
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let nb = &self.neighbours;
        let (means, quats) = (c.inputs[0].data(), c.inputs[1].data());
        let g = nb.seed(&c.grad_outputs[0]);
        let (own, to_neighbour) = nb.per_row::<7, 3>(|i, own, out| {
            let (rel, r) = self.relative(quats, i);
            let mut gr = [[0.0; 3]; 3];
            for (s, slot) in out.iter_mut().enumerate() {
                let p = i * nb.k + s;
                let (d, e) = self.residual(means, &r, i, p);
                let ge = root_vjp(g, nb.weight[p], e);
                *slot = std::array::from_fn(|b| (0..3).map(|a| r[b][a] * ge[a]).sum());
                for b in 0..3 {
                    own[b] -= slot[b];
                    for a in 0..3 {
                        gr[b][a] += d[b] * ge[a];
                    }
                }
            }
            #[cfg(test)]
            if self.fault {
                return;
            }
            let gq = rel.vjp(rotmat_vjp(rel.value, &gr));
            own[3..].copy_from_slice(&gq);
        });
        let own_means: Vec<[f64; 3]> = own.iter().map(|o| [o[0], o[1], o[2]]).collect();
        let dmeans = nb.gather(&own_means, &to_neighbour);
        let flat = |v: Vec<T>, shape: &[usize]| Some(Tensor::from_vec(v, shape));
        vec![
            c.needs_grad[0]
                .then(|| dmeans.iter().flatten().map(|&v| T::of(v)).collect())
                .and_then(|v| flat(v, c.inputs[0].shape())),
            c.needs_grad[1]
                .then(|| {
                    own.iter()
                        .flat_map(|o| o[3..].iter().map(|&v| T::of(v)))
                        .collect()
                })
                .and_then(|v| flat(v, c.inputs[1].shape())),
        ]
    }
}
