//! The training state: everything a step changes that has a row per Gaussian (the
//! model, its Adam moments, the filter state, the f/d observations, the
//! densification statistics and the liveness record), held together so that one
//! index list ([`TrainState::apply_plan`]) selects and reorders every row. Strategies
//! and the trainer's phases receive it, never the trainer.

use maaf_autodiff::optim::{Adam, AdamConfig};
use maaf_autodiff::{PerGaussian, Tensor};
use maaf_filter::{FilterState, ObservationTable};

use super::{DensifyPlan, DensifyStats, Liveness};
use crate::models::{Canonical, Representation};

/// The per-Gaussian state of a run, resized in lock-step.
pub struct TrainState {
    /// The 4D representation.
    pub model: Box<dyn Representation<f32>>,
    /// Adam moments per parameter.
    pub adam: Adam<f32>,
    /// Current 3D filter of every Gaussian.
    pub filter: FilterState,
    /// f/d observations recorded from training forward passes: the motion filter's
    /// input, at most `filter.max_views` frames; no frames for the other filters.
    pub observations: ObservationTable,
    /// Densification statistics.
    pub stats: DensifyStats,
    /// Per Gaussian, the last iteration with an opacity gradient and whether the last
    /// reset lowered it: the dead-Gaussian counts of the run's summary.
    pub liveness: Liveness,
    /// Iteration of the last opacity reset (large-screen pruning starts after it).
    pub last_reset: Option<usize>,
}

impl TrainState {
    /// A fresh state around `model`: no moments, no filter, empty statistics and
    /// `observations` (its frames chosen by the caller) sized to the model.
    pub fn new(model: Box<dyn Representation<f32>>, observations: ObservationTable) -> Self {
        let n = model.rows();
        TrainState {
            model,
            adam: Adam::new(AdamConfig::default()),
            filter: FilterState::None { rows: n },
            observations,
            stats: DensifyStats::new(n),
            liveness: Liveness::new(n),
            last_reset: None,
        }
    }

    /// Number of Gaussians.
    pub fn rows(&self) -> usize {
        self.model.rows()
    }

    /// The model's canonical Gaussians, activated ([`ParamStore::canonical`] of its
    /// [`CanonicalIds`]): what densification, the opacity reset, a strategy and the
    /// filters read.
    ///
    /// [`ParamStore::canonical`]: maaf_models::params::ParamStore::canonical
    /// [`CanonicalIds`]: crate::models::CanonicalIds
    pub fn canonical(&self) -> Canonical<f32> {
        self.model.params().canonical(self.model.canonical_ids())
    }

    /// Applies a densification plan to the model, its Adam moments, the filter
    /// state, the observations, the statistics and the liveness record with one
    /// index list: row `i` of the result is row `plan.index[i]` of before, and the
    /// rows `plan.new_rows` then get the plan's new means and scales. Each row's
    /// statistics travel with it (a densification then restarts them, a pruning
    /// keeps them).
    pub fn apply_plan(&mut self, plan: &DensifyPlan) {
        let n_old = self.model.rows();
        let names = self.model.params().per_gaussian_names();
        self.model.select_rows(&plan.index);
        if !plan.new_rows.is_empty() {
            let k = plan.new_rows.len();
            let ids = self.model.canonical_ids();
            self.model.params_mut().set_canonical_rows(
                ids,
                &plan.new_rows,
                &Tensor::from_vec(plan.new_means.clone(), &[k, 3]),
                &Tensor::from_vec(plan.new_scales.clone(), &[k, 3]),
            );
        }
        for name in names {
            if let Some(m) = self.adam.moments_mut(&name)
                && m.rows() == n_old
            {
                m.select_rows(&plan.index);
            }
        }
        self.filter.select_rows(&plan.index);
        self.observations.select_rows(&plan.index);
        self.stats.select_rows(&plan.index);
        self.liveness.select_rows(&plan.index);
    }
}
