//! Representations by name: how a run's model is rebuilt from its checkpoint without
//! the code that trained it. A checkpoint records its representation's
//! [`Representation::name`]; [`super::TrainedScene::load`] looks that name up here and
//! calls the loader with the run's configuration and a [`ModelInit`] rebuilt from the
//! checkpoint ([`super::SceneRecord::model_init`]), then loads the saved tensors into
//! what it returns. The built-in `saro`, `deform` and `track` are registered by
//! [`ModelRegistry::builtin`]; a custom representation registers its own loader.

use std::sync::Arc;

use maaf_io::Registry;
use maaf_models::{ModelInit, Representation, build_model};

use crate::TrainConfig;

/// Builds an untrained representation of a run from its configuration and initial
/// cloud, the same way it was built for training (its parameters are then replaced by
/// the checkpoint's, of any Gaussian count).
pub type ModelLoader =
    dyn Fn(&TrainConfig, &ModelInit) -> Result<Box<dyn Representation<f32>>, String> + Send + Sync;

/// Representation name -> loader ([`maaf_io::Registry`]). Cloning shares the loaders.
#[derive(Clone, Debug)]
pub struct ModelRegistry {
    loaders: Registry<ModelLoader>,
}

impl ModelRegistry {
    /// A registry with no representation.
    pub fn empty() -> Self {
        ModelRegistry {
            loaders: Registry::new(
                "representation (model.kind)",
                "maaf::cli::Maaf::representation",
            ),
        }
    }

    /// The built-in representations, `saro`, `deform` and `track`, all built by
    /// [`build_model`] from the run's `config.model` (resolved as
    /// `maaf_train::trainer::Trainer::new` resolves it).
    pub fn builtin() -> Self {
        let mut r = Self::empty();
        for name in maaf_models::ModelConfig::KINDS {
            // Distinct well-formed names.
            let _ = r.register(name, |config, init| {
                let mut model = config.model.clone();
                model.resolve(init);
                build_model(&model, init)
            });
        }
        r
    }

    /// Registers the loader of the representation called `name` (its
    /// [`Representation::name`]); refuses a name already registered or not 1 to 64
    /// letters, digits or `_` ([`Registry::register`]).
    pub fn register<F>(&mut self, name: &str, loader: F) -> Result<(), String>
    where
        F: Fn(&TrainConfig, &ModelInit) -> Result<Box<dyn Representation<f32>>, String>
            + Send
            + Sync
            + 'static,
    {
        self.loaders.register(name, Arc::new(loader))
    }

    /// The registered names, in registration order.
    pub fn names(&self) -> Vec<&str> {
        self.loaders.names()
    }

    /// Builds the representation `name` with its loader; an unknown name is an error
    /// naming it, the closest and what is registered.
    pub fn build(
        &self,
        name: &str,
        config: &TrainConfig,
        init: &ModelInit,
    ) -> Result<Box<dyn Representation<f32>>, String> {
        let loader = self.loaders.get(name)?;
        let model = loader(config, init)?;
        if model.name() != name {
            return Err(format!(
                "the loader registered as `{name}` built a `{}` model",
                model.name()
            ));
        }
        Ok(model)
    }
}

impl Default for ModelRegistry {
    /// [`ModelRegistry::builtin`].
    fn default() -> Self {
        Self::builtin()
    }
}
