//! Per-image metrics of one's own ([`ImageMetric`]), registered by name
//! ([`MetricRegistry`]): `maaf eval` computes each on every evaluated view beside
//! PSNR, SSIM and LPIPS, writes a `metrics.csv` column per metric and the mean per
//! scale in `eval.json`'s `extra`, and `maaf report` tabulates them
//! (docs/extending.md, "An image metric").

use std::sync::Arc;

use maaf_io::Registry;

use maaf_autodiff::Tensor;

/// The metrics every evaluation computes: no registered metric takes their names.
pub const BUILTIN_METRICS: [&str; 3] = ["psnr", "ssim", "lpips"];

/// The other columns of `metrics.csv`, which no metric may shadow either.
const CSV_COLUMNS: [&str; 2] = ["view", "time"];

/// A metric of one rendered view against its ground truth.
pub trait ImageMetric: Send + Sync {
    /// Its registered name: the `metrics.csv` column and the key in `eval.json`'s
    /// `extra` (1 to 64 letters, digits or `_`).
    fn name(&self) -> &str;

    /// Whether a larger value is better (PSNR, SSIM) or worse (LPIPS, an error):
    /// `maaf report` bolds the best run by it.
    fn higher_is_better(&self) -> bool;

    /// The metric of `render` against `gt`: float `[H, W, 3]` images of the same size
    /// (checked before), RGB as PSNR and SSIM get them: the data's own encoding (no
    /// gamma conversion), the ground truth composited on the evaluation's background
    /// and on [0, 1], the render unclamped and never quantised to 8 bits.
    /// An error (e.g. an image too small for the metric) stops the evaluation with
    /// the view, the scale and this message; so does a non-finite value.
    fn compute(&self, render: &Tensor<f32>, gt: &Tensor<f32>) -> Result<f64, String>;
}

impl std::fmt::Debug for dyn ImageMetric {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ImageMetric({})", self.name())
    }
}

/// Makes a registered metric (once per evaluation).
pub type MetricMaker = dyn Fn() -> Box<dyn ImageMetric> + Send + Sync;

/// Image metrics by name, beyond the built-in PSNR, SSIM and LPIPS (which are not in
/// it and whose names it refuses). Empty by default; a program adds its own
/// (`maaf::cli::Maaf::metric`). Cloning shares the makers.
#[derive(Clone, Debug)]
pub struct MetricRegistry {
    makers: Registry<MetricMaker>,
}

impl Default for MetricRegistry {
    fn default() -> Self {
        MetricRegistry {
            makers: Registry::new("metric", "maaf::cli::Maaf::metric"),
        }
    }
}

impl MetricRegistry {
    /// A registry with no metric of one's own.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the metric `maker` makes under `name` (1 to 64 letters, digits or `_`);
    /// refuses a name already registered, a built-in metric's name (`psnr`, `ssim`,
    /// `lpips`) and the other `metrics.csv` columns (`view`, `time`).
    pub fn register<F>(&mut self, name: &str, maker: F) -> Result<(), String>
    where
        F: Fn() -> Box<dyn ImageMetric> + Send + Sync + 'static,
    {
        if BUILTIN_METRICS.contains(&name) {
            return Err(format!(
                "metric `{name}` is built in (every evaluation computes {})",
                BUILTIN_METRICS.join(", ")
            ));
        }
        if CSV_COLUMNS.contains(&name) {
            return Err(format!(
                "`{name}` cannot name a metric: metrics.csv has a `{name}` column"
            ));
        }
        self.makers.register(name, Arc::new(maker))
    }

    /// The registered names, in registration order.
    pub fn names(&self) -> Vec<&str> {
        self.makers.names()
    }

    /// Makes the metrics `names` asks for, in its order (`None`: every registered
    /// one, sorted by name). Refuses a name not registered (naming the registered
    /// ones, or the closest), a name given twice, and a metric whose
    /// [`ImageMetric::name`] is not the name it is registered under.
    pub fn build(&self, names: Option<&[String]>) -> Result<Vec<Arc<dyn ImageMetric>>, String> {
        let wanted: Vec<&str> = match names {
            Some(names) => names.iter().map(String::as_str).collect(),
            None => {
                let mut all = self.names();
                all.sort_unstable();
                all
            }
        };
        let mut out: Vec<Arc<dyn ImageMetric>> = Vec::with_capacity(wanted.len());
        for (i, &name) in wanted.iter().enumerate() {
            if wanted[..i].contains(&name) {
                return Err(format!("metric `{name}` is given twice"));
            }
            let maker = self.makers.get(name).map_err(|e| self.unknown(name, e))?;
            let metric: Arc<dyn ImageMetric> = Arc::from(maker());
            if metric.name() != name {
                return Err(format!(
                    "the metric registered as `{name}` names itself `{}`",
                    metric.name()
                ));
            }
            out.push(metric);
        }
        Ok(out)
    }

    /// The line for a metric `name` not registered here: the registry's
    /// (`registered`), or, when nothing is registered, which metrics every
    /// evaluation computes anyway.
    fn unknown(&self, name: &str, registered: String) -> String {
        if !self.makers.is_empty() {
            return registered;
        }
        format!(
            "metric `{name}` is not registered: this program has no metric beyond {} (a program of one's own registers others: maaf::cli::Maaf::metric, docs/extending.md)",
            BUILTIN_METRICS.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A metric whose value is a constant, under any name.
    struct Constant(&'static str);

    impl ImageMetric for Constant {
        fn name(&self) -> &str {
            self.0
        }
        fn higher_is_better(&self) -> bool {
            false
        }
        fn compute(&self, _: &Tensor<f32>, _: &Tensor<f32>) -> Result<f64, String> {
            Ok(1.0)
        }
    }

    fn with(names: &[&'static str]) -> MetricRegistry {
        let mut r = MetricRegistry::new();
        for &n in names {
            r.register(n, move || Box::new(Constant(n)))
                .expect("a new name");
        }
        r
    }

    #[test]
    fn a_duplicate_builtin_or_malformed_name_is_refused() {
        let mut r = with(&["mae"]);
        let err = r
            .register("mae", || Box::new(Constant("mae")))
            .expect_err("duplicate");
        assert_eq!(err, "metric `mae` is already registered (registered: mae)");
        for name in BUILTIN_METRICS {
            let err = r
                .register(name, || Box::new(Constant("x")))
                .expect_err("built-in");
            assert!(err.contains("built in"), "{err}");
        }
        let err = r
            .register("time", || Box::new(Constant("time")))
            .expect_err("csv column");
        assert!(err.contains("metrics.csv"), "{err}");
        assert!(r.register("two words", || Box::new(Constant("x"))).is_err());
        assert_eq!(r.names(), ["mae"]);
    }

    #[test]
    fn an_unknown_name_is_refused_naming_the_registered_ones() {
        let r = with(&["mae", "gradient_similarity"]);
        let err = r
            .build(Some(&["gradient_similiarity".to_string()]))
            .expect_err("unknown");
        assert!(err.contains("did you mean `gradient_similarity`?"), "{err}");
        assert!(
            err.contains("registered: mae, gradient_similarity"),
            "{err}"
        );
        let err = r.build(Some(&["lpips".to_string()])).expect_err("built-in");
        assert!(err.contains("not registered"), "{err}");
        let err = MetricRegistry::new()
            .build(Some(&["mae".to_string()]))
            .expect_err("none registered");
        assert!(
            err.contains("metric `mae` is not registered") && err.contains("Maaf::metric"),
            "{err}"
        );
        let twice = ["mae".to_string(), "mae".to_string()];
        assert!(r.build(Some(&twice)).expect_err("twice").contains("twice"));
    }

    #[test]
    fn every_metric_is_built_in_name_order_unless_an_order_is_asked() {
        let r = with(&["mae", "gradient_similarity"]);
        let names = |m: Vec<Arc<dyn ImageMetric>>| -> Vec<String> {
            m.iter().map(|m| m.name().to_string()).collect()
        };
        assert_eq!(
            names(r.build(None).expect("all")),
            ["gradient_similarity", "mae"]
        );
        let asked = ["mae".to_string(), "gradient_similarity".to_string()];
        assert_eq!(names(r.build(Some(&asked)).expect("asked")), asked);
        let mut r = MetricRegistry::new();
        r.register("mae", || Box::new(Constant("other")))
            .expect("registers");
        let err = r.build(None).expect_err("misnamed");
        assert!(err.contains("names itself `other`"), "{err}");
    }
}
