//! Sampling-rate filters by name: the config's choice ([`FilterConfig::filter_name`])
//! and any filter a user registers under a name of their own, which `filter.kind`
//! then names.

use std::sync::Arc;

use maaf_io::Registry;

use crate::config::{FilterConfig, FilterError, MotionEstimator};
use crate::motion::MotionFilter;
use crate::sampling::{NoFilter, SamplingFilter, StaticFilter};

/// Builds a filter from the run's filter config (a filter of one's own reads its
/// `options` there); an error names the option at fault.
pub type FilterConstructor =
    dyn Fn(&FilterConfig) -> Result<Box<dyn SamplingFilter>, String> + Send + Sync;

/// Filter constructors by name ([`maaf_io::Registry`]). [`FilterRegistry::builtin`]
/// holds `none`, `mip3d`, `motion` (the paper's KDE) and `window_max` (maaf's).
/// Cloning shares the constructors.
#[derive(Clone, Debug)]
pub struct FilterRegistry {
    entries: Registry<FilterConstructor>,
}

impl FilterRegistry {
    /// The built-in filters under their config names.
    pub fn builtin() -> Self {
        let mut r = FilterRegistry {
            entries: Registry::new("filter", "maaf::cli::Maaf::filter"),
        };
        // Four distinct well-formed names: registering cannot fail.
        let _ = r.register("none", |_| Ok(Box::new(NoFilter)));
        let _ = r.register("mip3d", |_| Ok(Box::new(StaticFilter)));
        let _ = r.register("motion", |_| {
            Ok(Box::new(MotionFilter(MotionEstimator::Kde)))
        });
        let _ = r.register("window_max", |_| {
            Ok(Box::new(MotionFilter(MotionEstimator::WindowMax)))
        });
        r
    }

    /// Adds a filter under `name` ([`Registry::register`]: refuses a name already
    /// registered or not 1 to 64 letters, digits or `_`).
    pub fn register<F>(&mut self, name: &str, make: F) -> Result<(), String>
    where
        F: Fn(&FilterConfig) -> Result<Box<dyn SamplingFilter>, String> + Send + Sync + 'static,
    {
        self.entries.register(name, Arc::new(make))
    }

    /// Whether a filter is registered as `name`.
    pub fn contains(&self, name: &str) -> bool {
        self.entries.contains(name)
    }

    /// The registered names, in registration order.
    pub fn names(&self) -> Vec<&str> {
        self.entries.names()
    }

    /// The filter registered as `name`, built from `cfg`, or an error naming the
    /// unknown name, the closest and the known ones, or the factory's (an option).
    pub fn build(
        &self,
        name: &str,
        cfg: &FilterConfig,
    ) -> Result<Box<dyn SamplingFilter>, FilterError> {
        let make = self
            .entries
            .get(name)
            .map_err(|message| FilterError::Config {
                field: "kind",
                message,
            })?;
        make(cfg).map_err(|e| FilterError::Config {
            field: "options",
            message: format!("filter `{name}`: {e}"),
        })
    }

    /// The filter `cfg` selects ([`FilterConfig::filter_name`]).
    pub fn for_config(&self, cfg: &FilterConfig) -> Result<Box<dyn SamplingFilter>, FilterError> {
        self.build(cfg.filter_name(), cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::FilterKind;

    #[test]
    fn the_config_selects_each_builtin_by_name() {
        let reg = FilterRegistry::builtin();
        let mut cfg = FilterConfig::default();
        for (kind, estimator, name, observes) in [
            (FilterKind::None, MotionEstimator::Kde, "none", false),
            (
                FilterKind::Mip3d,
                MotionEstimator::WindowMax,
                "mip3d",
                false,
            ),
            (FilterKind::Motion, MotionEstimator::Kde, "motion", true),
            (
                FilterKind::Motion,
                MotionEstimator::WindowMax,
                "window_max",
                true,
            ),
        ] {
            cfg.kind = kind;
            cfg.estimator = estimator;
            let f = reg.for_config(&cfg).expect("built-in");
            assert_eq!((f.name(), f.observes()), (name, observes));
        }
    }

    #[test]
    fn unknown_and_duplicate_names_are_refused() {
        let mut reg = FilterRegistry::builtin();
        let err = reg
            .build("nope", &FilterConfig::default())
            .err()
            .expect("unknown name");
        assert!(
            err.to_string().contains("filter `nope` is not registered"),
            "{err}"
        );
        assert!(reg.register("mip3d", |_| Ok(Box::new(NoFilter))).is_err());
        reg.register("mine", |_| Ok(Box::new(NoFilter)))
            .expect("new name");
        let f = reg
            .build("mine", &FilterConfig::default())
            .expect("registered");
        assert_eq!(f.name(), "none");
        assert!(
            reg.register("bad name", |_| Ok(Box::new(NoFilter)))
                .is_err()
        );
        // A config names it by `kind`, and records the name as it is.
        let cfg: FilterConfig = serde_json::from_str(r#"{"kind": "mine"}"#).expect("json");
        assert_eq!(cfg.kind, crate::FilterKind::Custom("mine".into()));
        assert_eq!(reg.for_config(&cfg).expect("registered").name(), "none");
        assert_eq!(serde_json::to_value(&cfg).expect("json")["kind"], "mine");
    }

    #[test]
    fn a_filter_of_ones_own_reads_its_options_and_a_builtin_refuses_any() {
        let mut reg = FilterRegistry::builtin();
        reg.register("scaled", |cfg| match cfg.options.get("factor") {
            None => Ok(Box::new(NoFilter)),
            Some(v) if v.as_f64().is_some_and(|f| f > 0.0) => Ok(Box::new(StaticFilter)),
            Some(v) => Err(format!("`factor`: {v} is not a number > 0")),
        })
        .expect("new name");
        let cfg = |json: &str| -> FilterConfig { serde_json::from_str(json).expect("json") };
        let two = cfg(r#"{"kind": "scaled", "options": {"factor": 2}}"#);
        two.validate()
            .expect("a custom filter's options are its own");
        assert_eq!(reg.for_config(&two).expect("valid").name(), "mip3d");
        let bad = cfg(r#"{"kind": "scaled", "options": {"factor": -1}}"#);
        let err = reg.for_config(&bad).err().expect("refused").to_string();
        assert!(
            err.contains("`options`") && err.contains("filter `scaled`: `factor`: -1"),
            "{err}"
        );
        let builtin = cfg(r#"{"kind": "motion", "options": {"factor": 2}}"#);
        let err = builtin.validate().expect_err("built-in").to_string();
        assert!(err.contains("`motion` takes no options"), "{err}");
        // Empty options are left out of the JSON, so older configs read and write alike.
        let plain = serde_json::to_value(FilterConfig::default()).expect("json");
        assert!(plain.get("options").is_none());
        assert_eq!(
            serde_json::to_value(&two).expect("json")["options"]["factor"],
            2
        );
    }
}
