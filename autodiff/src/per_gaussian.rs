//! One resize mechanism for every per-Gaussian container (parameters, optimiser
//! moments, filter state, statistics): select rows by index.
//!
//! Densification expresses every change as a row index list over the old rows:
//! cloning Gaussian `i` appends `i` again, splitting appends it twice and drops the
//! original, pruning leaves it out. Applying the same list to every container keeps
//! them in lock-step (docs/architecture.md, "One training step as data").

use crate::{Float, Tensor};

/// A container with one row per Gaussian.
pub trait PerGaussian {
    /// Number of rows (Gaussians).
    fn rows(&self) -> usize;
    /// Replaces the rows by `old[index[0]], old[index[1]], ...` (repeats allowed).
    fn select_rows(&mut self, index: &[usize]);
}

impl<T: Float> PerGaussian for Tensor<T> {
    fn rows(&self) -> usize {
        Tensor::rows(self)
    }
    fn select_rows(&mut self, index: &[usize]) {
        *self = self.gather_rows(index);
    }
}

impl<T: Clone> PerGaussian for Vec<T> {
    fn rows(&self) -> usize {
        self.len()
    }
    fn select_rows(&mut self, index: &[usize]) {
        *self = index.iter().map(|&i| self[i].clone()).collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clone_split_prune_as_one_index_list() {
        let mut t = Tensor::<f32>::from_vec(vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5], &[3, 2]);
        let mut v = vec![10, 11, 12];
        // keep 0, drop 1, clone 2 (twice).
        let index = [0, 2, 2];
        t.select_rows(&index);
        v.select_rows(&index);
        assert_eq!(t.shape(), &[3, 2]);
        assert_eq!(t.data(), &[0.0, 0.5, 2.0, 2.5, 2.0, 2.5]);
        assert_eq!(v, vec![10, 12, 12]);
    }
}
