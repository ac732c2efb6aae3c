//! maaf-models: 4D representations (docs/architecture.md): parameters in a [`ParamStore`], bound on
//! a tape, plus a time t give the deformed 3D Gaussians the renderer takes.
//!
//! The trainer, the 3D filter and the renderer only see [`GaussianVars`]; which
//! representation produced them is hidden behind [`Representation`]. A new
//! representation (see `examples/custom_representation.rs`) declares its parameters in
//! a store once, says which of them are the canonical 3DGS tensors
//! ([`CanonicalIds`]: densification reads and writes those), and implements
//! [`Representation::bind`] (time-independent work, once per step) and
//! [`Bound::deform`] (per time). Checkpoints, densification (the [`ParamStore`]
//! helpers of `canonical.rs`) and the optimiser come from the store; nothing in the
//! trainer changes. What a model may customise beyond that is the optional
//! [`TrainingHooks`].
//!
//! One training step (`Trainer::update`) reads:
//!
//! ```text
//! model.set_iteration(i);                       // stage switch (e.g. SaRO static warm-up)
//! let params = model.params().bind(&tape);      // every parameter by name
//! let bound = model.bind(&params);              // time-independent work, once
//! for view in batch {                           // `batch` views (default 1)
//!     let g = bound.deform(view.time);          // GaussianVars: means, scales, quats, opacity, sh
//!     ... filter fold, render, objective (+ bound.regularisers() by name) ...
//! }                                             // backward of the views' mean objective
//! ```

mod canonical;
pub mod config;
pub mod deform;
pub mod encoding;
mod hooks;
mod init;
mod knn;
pub mod kplane;
pub mod params;
pub mod saro;
pub mod track;

use maaf_autodiff::{Float, Tape, Tensor, Var};
use maaf_splat::GaussianVars;

use crate::params::{BoundParams, ParamStore};

pub use canonical::{Canonical, CanonicalIds};
pub use config::{ModelConfig, ModelInit, build_model, scaled_count};
pub use deform::{DeformConfig, DeformModel};
pub use hooks::{TrainingHooks, TrainingTime};
pub use init::{InitialGaussians, knn_mean_sq_dist, rgb_to_sh_dc};
pub use knn::{Knn, knn};
pub use kplane::{KPlaneConfig, KPlaneField};
pub use maaf_data::PointCloud;
pub use saro::{SaroConfig, SaroModel};
pub use track::{TrackConfig, TrackModel};

/// A representation bound on one tape: deforms to any time, any number of times.
///
/// Work that does not depend on the render time (for SaRO the residual-field features
/// and the lifespans) is done once in [`Representation::bind`] and shared by every
/// `deform` call, so a batch of views at different times costs one field query.
pub trait Bound<'t, T: Float> {
    /// The deformed Gaussians at `time` (the data set's time, in \[0, 1] for D-NeRF),
    /// with the renderer's conventions: activated scales and opacity, unnormalised
    /// quaternions (w, x, y, z), SH `[N, K, 3]`.
    fn deform(&self, time: f64) -> GaussianVars<'t, T>;

    /// This step's regulariser values by name (each one element, unweighted). Only
    /// names the representation declares in [`Representation::regularisers`]; a
    /// stage may leave some out (they count as 0 then).
    fn regularisers(&self) -> Vec<(String, Var<'t, T>)> {
        Vec::new()
    }
}

/// Every deformed output of `bound` at each of `times`, then its regularisers,
/// flattened into one vector: a gradcheck contracts it with a random cotangent, i.e.
/// checks a random scalar function of all of them (the representations' tests).
#[cfg(test)]
pub(crate) fn flatten_outputs<'t, T: Float>(bound: &dyn Bound<'t, T>, times: &[f64]) -> Var<'t, T> {
    let mut parts = Vec::new();
    for &time in times {
        let g = bound.deform(time);
        for x in [g.means, g.scales, g.quats, g.opacity, g.sh] {
            let len = x.value().len();
            parts.push(x.reshape(&[len]));
        }
    }
    for (_, value) in bound.regularisers() {
        parts.push(value.reshape(&[1]));
    }
    maaf_autodiff::ops::concat(&parts, 0)
}

/// A 4D representation (docs/architecture.md, "Where things plug in"). Object safe: the
/// trainer holds a `Box<dyn Representation<f32>>`, built from the config by
/// [`build_model`] or by the user.
///
/// **Modelling** is all a new representation implements (`examples/custom_representation.rs`):
/// - required: [`name`](Self::name), [`params`](Self::params) /
///   [`params_mut`](Self::params_mut) (every tensor declared once in a [`ParamStore`]),
///   [`canonical_ids`](Self::canonical_ids) (which of them are the canonical 3DGS
///   tensors) and [`bind`](Self::bind) (whose [`Bound::deform`] gives the Gaussians at
///   a time);
/// - with defaults: [`label`](Self::label), [`regularisers`](Self::regularisers),
///   [`set_iteration`](Self::set_iteration) (stages),
///   [`centres_at_times`](Self::centres_at_times) (a cheaper path for the filter).
///
/// Densification, the opacity reset, the optimiser and checkpoints need nothing more:
/// they work on the store through [`CanonicalIds`] ([`ParamStore::canonical`],
/// [`ParamStore::set_canonical_rows`], [`ParamStore::cap_opacity`],
/// [`ParamStore::select_rows`](maaf_autodiff::PerGaussian::select_rows)).
///
/// **Optional hooks**, for a model with state outside its store or that steers
/// training (SaRO's temporal pruning and adaptive optimisation, Deformable-3DGS's
/// GroupFlow tables): implement [`TrainingHooks`] and return it from
/// [`hooks`](Self::hooks) and [`hooks_mut`](Self::hooks_mut) (default `None`).
pub trait Representation<T: Float> {
    /// Short name (`"saro"`), recorded in checkpoints: a checkpoint only loads into a
    /// representation of the same name.
    fn name(&self) -> &str;

    /// What eval and report call this model: the name plus any variant that changes
    /// what is trained (e.g. `deform + GroupFlow (500 groups)`). Defaults to
    /// [`Self::name`].
    fn label(&self) -> String {
        self.name().to_string()
    }

    /// The parameters.
    fn params(&self) -> &ParamStore<T>;

    /// The parameters, mutably (optimiser, checkpoint load, densification).
    fn params_mut(&mut self) -> &mut ParamStore<T>;

    /// Which parameters are the canonical 3DGS tensors.
    fn canonical_ids(&self) -> CanonicalIds;

    /// Binds the representation on the tape of `params` (from
    /// [`ParamStore::bind`] in training, or any vars in store order in a gradient
    /// check). Stop-gradient inputs are read from [`Representation::params`], so a
    /// gradient check that perturbs `params` keeps them fixed.
    fn bind<'t>(&self, params: &BoundParams<'t, T>) -> Box<dyn Bound<'t, T> + 't>;

    /// Regularisers the representation provides, as `(name, weight)`: the trainer adds
    /// one objective term per entry (logged under that name) that reads the value
    /// [`Bound::regularisers`] returns. Default: none.
    fn regularisers(&self) -> Vec<(String, f64)> {
        Vec::new()
    }

    /// Tells the model which iteration starts (1-based, as in the references): a
    /// model with stages (SaRO's static warm-up) switches here. Default: no stages.
    fn set_iteration(&mut self, _iteration: usize) {}

    /// Deformed centres \[N,3] at each of `times`, outside any training tape: what the
    /// motion-aware filter's observation pass needs (every training (camera, time)
    /// sees the *deformed* centre). The default binds the parameters as constants
    /// once and deforms per time; a representation may override it with a cheaper
    /// path (SaRO evaluates only the motion head).
    fn centres_at_times(&self, times: &[f64]) -> Vec<Tensor<T>> {
        times
            .iter()
            .map(|&t| {
                // A scratch tape per time keeps memory at one deformation.
                let tape = Tape::new();
                let params = self.params().bind_constants(&tape);
                let centres = self.bind(&params).deform(t).means.value().clone();
                drop(params);
                centres
            })
            .collect()
    }

    /// The optional hooks (state outside the store, training customisations), or
    /// `None` (the default): plain 3DGS training. A model implementing
    /// [`TrainingHooks`] returns `Some(self)` here and from [`Self::hooks_mut`].
    fn hooks(&self) -> Option<&dyn TrainingHooks<T>> {
        None
    }

    /// The optional hooks, mutably (densification resizing, checkpoint load).
    fn hooks_mut(&mut self) -> Option<&mut dyn TrainingHooks<T>> {
        None
    }
}
