//! Divergence: a run whose parameters stop being finite, that has pruned every
//! Gaussian, or that skips more than
//! `max_skipped_fraction` of its steps (after `skip_grace` iterations), is stopped
//! with one line naming the iteration and the last reason a step was skipped (with
//! `validate: true` the tape names the first op that produced a non-finite value).

use super::Trainer;
use crate::Error;

impl Trainer {
    /// The first parameter value that is not finite, as (parameter name, flat index,
    /// value).
    pub fn first_non_finite_param(&self) -> Option<(String, usize, f32)> {
        maaf_scene::checkpoint_read::first_non_finite(self.state.model.as_ref())
    }

    /// `Err` when the run has diverged at its current iteration: a non-finite
    /// parameter, no Gaussian left, or `skipped_steps > max_skipped_fraction *
    /// iteration` once `iteration >= skip_grace`.
    pub fn check_health(&self) -> Result<(), Error> {
        let it = self.iteration;
        if self.num_gaussians() == 0 {
            return Err(Error::Input(format!(
                "iteration {it}: training collapsed: densification pruned every Gaussian (see `densify` in the config)"
            )));
        }
        if let Some((name, index, value)) = self.first_non_finite_param() {
            return Err(Error::Input(format!(
                "iteration {it}: training diverged: parameter `{name}` is {value} at flat index {index}; lower the learning rates"
            )));
        }
        let c = &self.config;
        let allowed = c.max_skipped_fraction * it as f64;
        if it >= c.skip_grace && self.skipped_steps as f64 > allowed {
            let why = self
                .last_skip
                .as_deref()
                .unwrap_or("non-finite loss or gradient");
            let hint = if c.validate {
                ""
            } else {
                " (set \"validate\": true in the config to name the first non-finite op)"
            };
            return Err(Error::Input(format!(
                "iteration {it}: training diverged: {} of {it} steps skipped, more than max_skipped_fraction {}; last: {why}{hint}; lower the learning rates",
                self.skipped_steps, c.max_skipped_fraction
            )));
        }
        Ok(())
    }
}
