//! A sampling-rate filter of your own in the whole `maaf` command line, written only
//! against maaf's public API: a "median" static filter, Mip-Splatting's Eq. 2 with
//! the median of `f / d` over the training cameras that see a Gaussian instead of
//! the maximum (a wider filter wherever the cameras disagree); its own option
//! `quantile` (default 0.5, `"filter": {"kind": "median", "options": {"quantile":
//! 0.25}}`) picks another order statistic. It implements `SamplingFilter` and is
//! registered under the name `median`, which a training config then names like a
//! built-in filter:
//!
//! ```text
//! cargo run --release --example custom_filter -- train --data DATA --out RUN \
//!     --filter median          # or "filter": {"kind": "median"} in --config
//! cargo run --release --example custom_filter -- train --resume RUN
//! cargo run --release --example custom_filter -- eval --run RUN   # labelled `median`
//! ```
//!
//! `maaf train --resume RUN` refuses the run, naming the filter; every command that
//! only reads the run (eval, render, export-ply, report) works in plain `maaf` too,
//! since the checkpoint holds the filter's state. `tests/cli/custom_plugins.rs` runs
//! it: trains, is killed, resumes bit-identical, evaluates.

use maaf::filter::{FilterConfig, FilterError, FilterInputs, FilterState, SamplingFilter, Viewer};

// ---- the user's filter ----

/// Static nu = the `quantile` (0.5: the median) over the cameras that see the
/// centre of `f / d`.
struct MedianFilter {
    quantile: f64,
}

impl SamplingFilter for MedianFilter {
    fn name(&self) -> &str {
        "median"
    }

    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError> {
        let viewers: Vec<Viewer> = inputs
            .cameras()
            .iter()
            .map(|c| Viewer::new(c, cfg))
            .collect();
        let mut nu: Vec<f32> = inputs
            .canonical_centres()
            .iter()
            .map(|&p| {
                let mut rates: Vec<f32> =
                    viewers.iter().filter_map(|v| v.sampling_rate(p)).collect();
                rates.sort_by(f32::total_cmp);
                let at = (self.quantile * rates.len() as f64) as usize;
                rates
                    .get(at.min(rates.len().saturating_sub(1)))
                    .copied()
                    .unwrap_or(0.0)
            })
            .collect();
        // Unseen Gaussians take the smallest rate seen (Mip-Splatting's rule).
        let smallest = nu
            .iter()
            .copied()
            .filter(|&v| v > 0.0)
            .fold(f32::INFINITY, f32::min);
        if !smallest.is_finite() {
            return Err(FilterError::NothingVisible);
        }
        for v in nu.iter_mut().filter(|v| **v <= 0.0) {
            *v = smallest;
        }
        Ok(FilterState::Mip3d { s3d: cfg.s3d, nu })
    }
}

/// The filter for a run: `quantile` from `filter.options` (0.5 when absent), in
/// [0, 1].
fn median(cfg: &FilterConfig) -> Result<Box<dyn SamplingFilter>, String> {
    if let Some(unknown) = cfg.options.keys().find(|k| *k != "quantile") {
        return Err(format!(
            "`{unknown}` is not an option of the median filter (quantile)"
        ));
    }
    let quantile = match cfg.options.get("quantile") {
        None => 0.5,
        Some(v) => v
            .as_f64()
            .filter(|q| (0.0..=1.0).contains(q))
            .ok_or_else(|| format!("`quantile`: expected a number in [0, 1], got {v}"))?,
    };
    Ok(Box::new(MedianFilter { quantile }))
}

fn main() {
    maaf::cli::Maaf::new().filter("median", median).run()
}
