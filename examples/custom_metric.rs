//! A per-image metric of your own in the whole `maaf` command line, written only
//! against maaf's public API: the mean absolute error of the image as it is shown
//! (render and ground truth clamped to [0, 1]), averaged over pixels and RGB
//! channels; lower is better. It implements `ImageMetric` and is registered under
//! the name `mae`:
//!
//! ```text
//! cargo run --release --example custom_metric -- eval --run RUN
//! cargo run --release --example custom_metric -- eval --run RUN --metrics mae
//! maaf report --runs RUN --out REPORT      # plain maaf shows the column too
//! ```
//!
//! Every evaluated view gets a `mae` column in `RUN/eval/<scale>x/metrics.csv`, each
//! scale of `RUN/eval.json` its mean in `"extra": {"mae": ...}`, and `maaf report`
//! (which only reads eval.json) a table of it. `tests/cli/custom_plugins.rs` runs it
//! and recomputes the value from the saved render and ground-truth PNGs.

use maaf::autodiff::Tensor;
use maaf::eval::ImageMetric;

// ---- the user's metric ----

/// Mean over pixels and channels of `|clamp(render) - clamp(gt)|`, on [0, 1].
struct MeanAbsoluteError;

impl ImageMetric for MeanAbsoluteError {
    fn name(&self) -> &str {
        "mae"
    }

    fn higher_is_better(&self) -> bool {
        false
    }

    fn compute(&self, render: &Tensor<f32>, gt: &Tensor<f32>) -> Result<f64, String> {
        let (render, gt) = (render.data(), gt.data());
        if render.is_empty() {
            return Err("the image has no pixels".into());
        }
        let shown = |v: f32| f64::from(v.clamp(0.0, 1.0));
        let sum: f64 = render
            .iter()
            .zip(gt)
            .map(|(&r, &g)| (shown(r) - shown(g)).abs())
            .sum();
        Ok(sum / render.len() as f64)
    }
}

fn main() {
    maaf::cli::Maaf::new()
        .metric("mae", || Box::new(MeanAbsoluteError))
        .run()
}
