//! maaf-models: 4D representations (docs/architecture.md): parameters in a [`ParamStore`], bound on
//! a tape, plus a time t give the deformed 3D Gaussians the renderer takes.
//!
//! The trainer, the 3D filter and the renderer only see [`GaussianVars`]; which
//! representation produced them is hidden behind [`Representation`]. A new
//! representation (see `examples/custom_representation.rs`) declares its parameters in
//! a store once, says which of them are the canonical 3DGS tensors
//! ([`CanonicalIds`]: densification reads and writes those), and implements
//! [`Representation::bind`] (time-independent work, once per step) and
//! [`Bound::deform`] (per time). Checkpoints, densification resizing and the
//! optimiser come from the store; nothing in the trainer changes.
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

pub mod config;
pub mod deform;
pub mod encoding;
mod init;
pub mod kplane;
pub mod params;
pub mod saro;

use std::sync::Arc;

use maaf_autodiff::scalar::{logit, sigmoid};
use maaf_autodiff::{Float, PerGaussian, Tape, Tensor, Var};
use maaf_splat::GaussianVars;

use crate::params::{BoundParams, ParamId, ParamStore};

pub use config::{ModelConfig, ModelInit, build_model};
pub use deform::{DeformConfig, DeformModel};
pub use init::{InitialGaussians, knn_mean_sq_dist, rgb_to_sh_dc};
pub use kplane::{KPlaneConfig, KPlaneField};
pub use maaf_data::PointCloud;
pub use saro::{SaroConfig, SaroModel};

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

/// Which parameters of a store hold the canonical 3DGS tensors, in 3DGS's
/// parametrisation: centres `[N,3]`, log-scales `[N,3]`, unnormalised quaternions
/// `[N,4]` (w, x, y, z) and opacity logits `[N]`. Densification reads them (scale
/// threshold, split sampling, opacity prune) and writes them (split halves, opacity
/// reset) through the defaults of [`Representation`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CanonicalIds {
    /// Centres.
    pub means: ParamId,
    /// Log-scales (`scale = exp`).
    pub log_scales: ParamId,
    /// Quaternions.
    pub quats: ParamId,
    /// Opacity logits (`opacity = sigmoid`).
    pub opacity_logits: ParamId,
}

/// Canonical (undeformed) per-Gaussian values, activated, as plain tensors: what
/// densification reads.
#[derive(Clone, Debug)]
pub struct Canonical<T: Float> {
    /// Centres \[N,3].
    pub means: Tensor<T>,
    /// Activated scales \[N,3].
    pub scales: Tensor<T>,
    /// Unnormalised quaternions \[N,4] (w,x,y,z).
    pub quats: Tensor<T>,
    /// Activated base opacity \[N] (without any temporal factor).
    pub opacity: Tensor<T>,
}

/// A 4D representation (docs/architecture.md, "Where things plug in"). Object safe: the trainer holds a
/// `Box<dyn Representation<f32>>`, built from the config by [`build_model`] or by the
/// user.
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

    /// Number of Gaussians N.
    fn num_gaussians(&self) -> usize {
        self.params().gaussians().unwrap_or(0)
    }

    /// Number of stored scalars (parameters only, no optimiser state).
    fn num_scalars(&self) -> usize {
        self.params().num_scalars()
    }

    /// Replaces every per-Gaussian row by `old\[index\[0]], old\[index\[1]], ...`
    /// (clone: repeat an index; split: repeat and drop; prune: leave out). The
    /// default resizes every per-Gaussian parameter of the store; override only if
    /// the model keeps other per-Gaussian state.
    fn select_rows(&mut self, index: &[usize]) {
        self.params_mut().select_rows(index);
    }

    /// Canonical values for densification (activated).
    fn canonical(&self) -> Canonical<T> {
        let ids = self.canonical_ids();
        let p = self.params();
        Canonical {
            means: p.value(ids.means).clone(),
            scales: p.value(ids.log_scales).map(|v| v.exp()),
            quats: p.value(ids.quats).clone(),
            opacity: p.value(ids.opacity_logits).map(sigmoid),
        }
    }

    /// Overwrites the canonical centres and **activated** scales of `rows` (after
    /// [`Representation::select_rows`] has created them, e.g. the two halves of a
    /// split). `means` and `scales` are \[rows.len(), 3].
    fn set_rows(&mut self, rows: &[usize], means: &Tensor<T>, scales: &Tensor<T>) {
        assert_eq!(means.shape(), &[rows.len(), 3], "set_rows: means shape");
        assert_eq!(scales.shape(), &[rows.len(), 3], "set_rows: scales shape");
        let ids = self.canonical_ids();
        let p = self.params_mut();
        for (j, &r) in rows.iter().enumerate() {
            for a in 0..3 {
                p.value_mut(ids.means).data_mut()[3 * r + a] = means.data()[3 * j + a];
                p.value_mut(ids.log_scales).data_mut()[3 * r + a] = scales.data()[3 * j + a].ln();
            }
        }
    }

    /// Opacity reset (3DGS `reset_opacity`), one cap per Gaussian:
    /// `o_i = min(o_i, logit(caps_i))` on the logits (a cap of 1 or more leaves the
    /// row as it is). The trainer computes the caps (`maaf_train::trainer::opacity_caps`).
    /// Returns the names of the parameters it overwrote, whose optimiser
    /// moments the trainer then zeroes (3DGS `replace_tensor_to_optimizer`): stale
    /// momentum would otherwise keep pushing the reset opacities down.
    fn reset_opacity(&mut self, caps: &[f64]) -> Vec<String> {
        let id = self.canonical_ids().opacity_logits;
        let p = self.params_mut();
        for (v, &cap) in p.value_mut(id).data_mut().iter_mut().zip(caps) {
            if cap < 1.0 {
                *v = v.min(logit(T::of(cap)));
            }
        }
        vec![p.param(id).name.clone()]
    }

    /// Indices of Gaussians the representation itself wants removed (SaRO: a temporal
    /// integral below the threshold). Empty by default.
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

    /// State outside the parameter store that a checkpoint must carry for a resumed
    /// run to continue exactly, as (name, tensor). Default: none.
    fn buffers(&self) -> Vec<(String, Tensor<T>)> {
        Vec::new()
    }

    /// Restores a buffer [`Representation::buffers`] wrote; an error names the buffer
    /// when it is unknown or has the wrong shape.
    fn load_buffer(&mut self, name: &str, _value: Tensor<T>) -> Result<(), String> {
        Err(format!("{} has no buffer `{name}`", self.name()))
    }

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
}
