//! Sampling-rate filters by name: the config's choice ([`FilterConfig::filter_name`])
//! and any filter a user registers under a name of their own.

use crate::config::{FilterConfig, FilterError};
use crate::motion::{MotionKdeFilter, WindowMaxFilter};
use crate::sampling::{NoFilter, SamplingFilter, StaticFilter};

/// Builds a filter from the run's filter config.
pub type FilterConstructor = fn(&FilterConfig) -> Box<dyn SamplingFilter>;

/// Filter constructors by name. [`FilterRegistry::builtin`] holds `none`, `mip3d`,
/// `motion` (the paper's KDE) and `window_max` (ours).
#[derive(Clone, Debug)]
pub struct FilterRegistry {
    entries: Vec<(String, FilterConstructor)>,
}

impl FilterRegistry {
    /// The built-in filters under their config names.
    pub fn builtin() -> Self {
        let entries: Vec<(String, FilterConstructor)> = vec![
            ("none".into(), |_| Box::new(NoFilter)),
            ("mip3d".into(), |_| Box::new(StaticFilter)),
            ("motion".into(), |_| Box::new(MotionKdeFilter)),
            ("window_max".into(), |_| Box::new(WindowMaxFilter)),
        ];
        FilterRegistry { entries }
    }

    /// Adds a filter under `name`; refuses a name already registered.
    pub fn register(&mut self, name: &str, make: FilterConstructor) -> Result<(), FilterError> {
        if self.entries.iter().any(|(n, _)| n == name) {
            return Err(FilterError::Shape(format!(
                "filter `{name}` is already registered"
            )));
        }
        self.entries.push((name.to_string(), make));
        Ok(())
    }

    /// The registered names, in registration order.
    pub fn names(&self) -> Vec<&str> {
        self.entries.iter().map(|(n, _)| n.as_str()).collect()
    }

    /// The filter registered as `name`, built from `cfg`, or an error naming the
    /// unknown name and the known ones.
    pub fn build(
        &self,
        name: &str,
        cfg: &FilterConfig,
    ) -> Result<Box<dyn SamplingFilter>, FilterError> {
        match self.entries.iter().find(|(n, _)| n == name) {
            Some((_, make)) => Ok(make(cfg)),
            None => Err(FilterError::Config {
                field: "kind",
                message: format!(
                    "unknown filter `{name}` (known: {})",
                    self.names().join(", ")
                ),
            }),
        }
    }

    /// The filter `cfg` selects ([`FilterConfig::filter_name`]).
    pub fn for_config(&self, cfg: &FilterConfig) -> Result<Box<dyn SamplingFilter>, FilterError> {
        self.build(cfg.filter_name(), cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{FilterKind, MotionEstimator};

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
        assert!(err.to_string().contains("unknown filter `nope`"), "{err}");
        assert!(reg.register("mip3d", |_| Box::new(NoFilter)).is_err());
        reg.register("mine", |_| Box::new(NoFilter))
            .expect("new name");
        let f = reg
            .build("mine", &FilterConfig::default())
            .expect("registered");
        assert_eq!(f.name(), "none");
    }
}
