//! Iterations a model confines to one time ([`TrainingHooks::training_time`], the
//! tracking model's frames): the views drawn at that time, and the optimiser moments
//! the model restarts ([`TrainingHooks::reset_moments`]).
//!
//! [`TrainingHooks::training_time`]: crate::models::TrainingHooks::training_time
//! [`TrainingHooks::reset_moments`]: crate::models::TrainingHooks::reset_moments

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_pcg::Pcg64;

use super::Trainer;
use crate::models::TrainingTime;

impl Trainer {
    /// The training views of `iteration` when it trains on `at.time`: `batch`
    /// consecutive entries of a sequence over the training views at the time nearest
    /// to it, in a seeded order reshuffled for every pass over them, the passes
    /// counted from `at.since` (Dynamic 3D Gaussians' per-timestep sampler: pop a
    /// shuffled list, reshuffle when empty). It depends only on the seed, `at` and
    /// `iteration`, so a resumed run draws the same views.
    pub(super) fn views_at_time(&self, iteration: usize, at: TrainingTime) -> Vec<usize> {
        let gap = |t: f64| (t - at.time).abs();
        let nearest = self
            .views
            .times
            .iter()
            .copied()
            .map(gap)
            .fold(f64::INFINITY, f64::min);
        let pool: Vec<usize> = (0..self.views.times.len())
            .filter(|&v| gap(self.views.times[v]) == nearest)
            .collect();
        let batch = self.config.batch;
        (0..batch)
            .map(|slot| {
                let k = iteration.saturating_sub(at.since) * batch + slot;
                let pass = (k / pool.len()) as u64;
                let mut order = pool.clone();
                let seed = self.config.seed
                    ^ (at.since as u64).wrapping_mul(0xA24B_AED4_963E_E407)
                    ^ pass.wrapping_mul(0x9E37_79B9_7F4A_7C15);
                order.shuffle(&mut Pcg64::seed_from_u64(seed));
                order[k % pool.len()]
            })
            .collect()
    }

    /// Zeroes the Adam moments of the parameters the model restarts at `iteration`
    /// (their step counts kept).
    pub(super) fn restart_moments(&mut self, iteration: usize) {
        let names = self
            .state
            .model
            .hooks()
            .map_or_else(Vec::new, |h| h.reset_moments(iteration));
        for name in names {
            self.state.adam.zero_moments(&name);
        }
    }
}
