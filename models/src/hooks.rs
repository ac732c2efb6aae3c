//! What a representation may customise beyond modelling (docs/architecture.md, "Where
//! things plug in"): state it keeps outside its [`ParamStore`](crate::params::ParamStore)
//! and the ways it steers training. Optional: a representation without any returns
//! `None` from [`Representation::hooks`] (the default) and the trainer uses plain 3DGS.

use std::sync::Arc;

use maaf_autodiff::{Float, PerGaussian, Tensor};

use crate::Representation;

/// The optional part of a representation, reached through [`Representation::hooks`]
/// and [`Representation::hooks_mut`] (a model opting in implements this trait and
/// returns `Some(self)` from both). Every method has a neutral default, so a model
/// overrides only what it uses.
///
/// Two groups:
/// - **state outside the store**, which the trainer cannot see otherwise:
///   [`TrainingHooks::select_state_rows`] (per-Gaussian state resized with the
///   parameters), [`TrainingHooks::buffers`] / [`TrainingHooks::load_buffer`] (what a
///   checkpoint carries beside the parameters) and [`TrainingHooks::state_scalars`]
///   (its size). Deformable-3DGS's GroupFlow tables are such state.
/// - **training customisations**: [`TrainingHooks::short_lived`] (Gaussians to prune),
///   [`TrainingHooks::lr_row_scale`] and [`TrainingHooks::densify_grad_scale`]
///   (per-Gaussian scales of the learning rate and of the densification statistic),
///   [`TrainingHooks::training_time`] (the one time an iteration trains on) and
///   [`TrainingHooks::reset_moments`] (optimiser moments to restart). SaRO-GS's
///   temporal pruning and adaptive optimisation, and the tracking model's frame by
///   frame training, are such customisations.
pub trait TrainingHooks<T: Float> {
    /// Resizes the representation's own per-Gaussian state (not its parameter store,
    /// which the caller resizes with the same list) to `old\[index\[0]], old\[index\[1]],
    /// ...` (clone: repeat an index; split: repeat and drop; prune: leave out).
    /// Default: no such state.
    fn select_state_rows(&mut self, _index: &[usize]) {}

    /// Number of scalars of state outside the store that the model renders with
    /// (counted in the model's size). Default: 0.
    fn state_scalars(&self) -> usize {
        0
    }

    /// State outside the parameter store that a checkpoint must carry for a resumed
    /// run (or a loaded scene) to continue exactly, as (name, tensor). Default: none.
    fn buffers(&self) -> Vec<(String, Tensor<T>)> {
        Vec::new()
    }

    /// Restores a buffer [`TrainingHooks::buffers`] wrote; an error names the buffer
    /// when it is unknown or has the wrong shape. Default: every name is unknown.
    fn load_buffer(&mut self, name: &str, _value: Tensor<T>) -> Result<(), String> {
        Err(format!("no buffer `{name}`"))
    }

    /// Indices of Gaussians the representation itself wants removed (SaRO: a temporal
    /// integral below the threshold), pruned at each densification. Default: none.
    fn short_lived(&self) -> Vec<usize> {
        Vec::new()
    }

    /// Per-Gaussian multipliers of the learning rate of parameter `name` at the
    /// current iteration (one per row), or `None` for the plain rate. `densifying`:
    /// whether the iteration is inside the densification window. SaRO: the adaptive
    /// optimisation. Default: `None`.
    fn lr_row_scale(&self, _name: &str, _densifying: bool) -> Option<Arc<[T]>> {
        None
    }

    /// Per-Gaussian multipliers of the densification statistic (the mean screen-space
    /// gradient) before it meets the threshold, or `None`. Default: `None`.
    fn densify_grad_scale(&self) -> Option<Arc<[T]>> {
        None
    }

    /// The only time iteration `iteration` (1-based) may train on, or `None` (the
    /// default): every training view, in the run's seeded order. With a time, the
    /// trainer draws the iteration's views among the training views at that time
    /// (the nearest time the data has), in a seeded order reshuffled for every pass
    /// over them, the passes counted from [`TrainingTime::since`]. Called after
    /// [`Representation::set_iteration`](crate::Representation::set_iteration).
    fn training_time(&self, _iteration: usize) -> Option<TrainingTime> {
        None
    }

    /// Names of the parameters whose Adam moments restart (both zeroed, the step
    /// count kept, as PyTorch keeps `step` when a parameter is replaced) before the
    /// update of iteration `iteration`, after
    /// [`Representation::set_iteration`](crate::Representation::set_iteration).
    /// Default: none.
    fn reset_moments(&self, _iteration: usize) -> Vec<String> {
        Vec::new()
    }
}

/// What [`TrainingHooks::training_time`] returns: the time an iteration trains on and
/// the first iteration of the run of iterations that train on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrainingTime {
    /// The time (the data's).
    pub time: f64,
    /// The first iteration (1-based) at this time: the passes over its views count
    /// from there, so a resumed run draws the same views.
    pub since: usize,
}

/// A representation is a per-Gaussian container: its rows are its store's, and a
/// row selection resizes the store's per-Gaussian parameters and then whatever state
/// its hooks keep ([`TrainingHooks::select_state_rows`]), so densification applies one
/// index list to it as to every other container.
impl<T: Float> PerGaussian for dyn Representation<T> + '_ {
    fn rows(&self) -> usize {
        self.params().rows()
    }

    fn select_rows(&mut self, index: &[usize]) {
        self.params_mut().select_rows(index);
        if let Some(hooks) = self.hooks_mut() {
            hooks.select_state_rows(index);
        }
    }
}
