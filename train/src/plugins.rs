//! Everything a run may name that a program can add to: loss terms, representations,
//! sampling filters and densification strategies, each a registry by name with the
//! built-in ones in it, and the data layouts of one's own the run's data folder may
//! be in (docs/extending.md). Every path that trains or resumes takes
//! one [`Plugins`] and refuses, before anything changes, a config naming something
//! it lacks.

use maaf_data::FormatRegistry;
use maaf_filter::FilterRegistry;

use crate::Error;
use crate::loss::TermRegistry;
use crate::trainer::StrategyRegistry;
use maaf_scene::ModelRegistry;
use maaf_scene::TrainConfig;

/// The registries a run's config is resolved against.
pub struct Plugins {
    /// Loss terms (`terms`).
    pub terms: TermRegistry<f32>,
    /// Representations (`model.kind`): built for training from the config and the
    /// initial cloud, and rebuilt from checkpoints for every other command.
    pub models: ModelRegistry,
    /// Sampling-rate filters (`filter.kind`, with `filter.estimator`).
    pub filters: FilterRegistry,
    /// Densification strategies (`densify.strategy`).
    pub strategies: StrategyRegistry,
    /// Data layouts of one's own, read after the built-in ones when a data folder is
    /// opened ([`maaf_data::Dataset::open_with`]; none built in).
    pub formats: FormatRegistry,
}

impl Default for Plugins {
    /// [`Plugins::builtin`].
    fn default() -> Self {
        Self::builtin()
    }
}

impl Plugins {
    /// The built-in terms, representations, filters and strategies, and no data
    /// layout of one's own.
    pub fn builtin() -> Self {
        Plugins {
            terms: TermRegistry::builtin(),
            models: ModelRegistry::builtin(),
            filters: FilterRegistry::builtin(),
            strategies: StrategyRegistry::builtin(),
            formats: FormatRegistry::new(),
        }
    }

    /// The built-ins with the terms of `terms` instead of the built-in terms.
    pub fn with_terms(terms: &TermRegistry<f32>) -> Self {
        Plugins {
            terms: terms.clone(),
            ..Self::builtin()
        }
    }

    /// Refuses a config (`what`: its file, or `config`) that names a term, a
    /// representation, a filter or a strategy not registered here, with one line
    /// naming it and what is registered.
    pub fn check(&self, config: &TrainConfig, what: &str) -> Result<(), Error> {
        self.terms.check(&config.terms, what)?;
        let kind = config.model.kind();
        if !self.models.names().contains(&kind) {
            return Err(Error::Input(format!(
                "{what}: {}",
                maaf_io::unknown_name(
                    "representation (model.kind)",
                    kind,
                    &self.models.names(),
                    "maaf::cli::Maaf::representation"
                )
            )));
        }
        let filter = config.filter.filter_name();
        if !self.filters.contains(filter) {
            return Err(Error::Input(format!(
                "{what}: {}",
                maaf_io::unknown_name(
                    "filter",
                    filter,
                    &self.filters.names(),
                    "maaf::cli::Maaf::filter"
                )
            )));
        }
        self.strategies.check(config, what)
    }
}
