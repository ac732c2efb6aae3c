//! Filter refreshes, outside the tape: the trainer's [`SamplingFilter`] (the
//! config's, by name from [`FilterRegistry`](maaf_filter::FilterRegistry), or a
//! user's) computes the filter state from the inputs the trainer supplies.

use maaf_autodiff::PerGaussian;
use maaf_filter::{FilterInputs, ObservationTable, SamplingFilter};
use maaf_splat::Camera;

use super::Trainer;
use maaf_scene::{centres, observed_views};

/// The trainer as a filter's inputs.
struct Inputs<'a>(&'a Trainer);

impl FilterInputs for Inputs<'_> {
    fn gaussians(&self) -> usize {
        self.0.state.model.rows()
    }

    fn canonical_centres(&self) -> Vec<[f32; 3]> {
        let model = &self.0.state.model;
        centres(model.params().value(model.canonical_ids().means))
    }

    fn cameras(&self) -> &[Camera] {
        &self.0.views.cameras
    }

    fn observations(&self) -> &ObservationTable {
        &self.0.state.observations
    }
}

impl Trainer {
    /// Replaces the filter by `filter` (a user's [`SamplingFilter`]; the trainer
    /// starts with the config's). The observation table is rebuilt for it, empty
    /// when it reads no observation, and the filter is computed again at the next
    /// step. Call it before training (or before loading a checkpoint, whose
    /// observations must then match).
    pub fn set_filter(&mut self, filter: Box<dyn SamplingFilter>) {
        let (observed, slot) = observed_views(
            &self.views.times,
            filter.observes(),
            self.config.filter.max_views,
        );
        self.state.observations = ObservationTable::for_frames(&observed, self.num_gaussians());
        self.observed = observed;
        self.observed_slot = slot;
        self.sampling = filter;
        self.filter_ready = false;
    }

    /// The filter that computes [`Trainer::filter`].
    pub fn sampling_filter(&self) -> &dyn SamplingFilter {
        self.sampling.as_ref()
    }

    /// Computes the filter if no step or checkpoint has yet (Mip-Splatting computes
    /// it once before training): for a filter that observes, a full observation
    /// pass over every observed training (camera, time) first, with the deformed
    /// centres of each distinct time (the field is queried once). Called by the
    /// first [`Trainer::step`]; call it before rendering a trainer that has not stepped.
    pub fn ensure_filter(&mut self) {
        if self.filter_ready {
            return;
        }
        self.filter_ready = true;
        if self.sampling.observes() {
            let mut times: Vec<f32> = self.observed.iter().map(|f| f.time).collect();
            times.sort_by(f32::total_cmp);
            times.dedup();
            let at: Vec<f64> = times.iter().map(|&t| f64::from(t)).collect();
            let all = self.state.model.centres_at_times(&at);
            let result = self.state.observations.observe_all(
                &self.observed,
                &self.views.cameras,
                &self.config.filter,
                |t| {
                    let k = times.partition_point(|&x| x < t).min(all.len() - 1);
                    centres(&all[k])
                },
            );
            if let Err(e) = result {
                log::warn!("observation pass failed: {e}");
            }
        }
        self.refresh_filter();
    }

    /// Recomputes the 3D filter with the trainer's [`SamplingFilter`]. On a failure
    /// (logged) the previous filter stays.
    pub fn refresh_filter(&mut self) {
        match self.sampling.compute(&Inputs(self), &self.config.filter) {
            Ok(state) => self.state.filter = state,
            Err(e) => log::warn!("filter refresh skipped: {e}"),
        }
    }
}
