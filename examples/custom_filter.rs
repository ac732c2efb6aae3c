//! A sampling-rate filter of your own, run by the normal trainer and written only
//! against maaf's public API: a "median" static filter, Mip-Splatting's Eq. 2 with
//! the median of `f / d` over the training cameras that see a Gaussian instead of
//! the maximum (a wider filter wherever the cameras disagree). It implements
//! `SamplingFilter`, is registered under a name in a `FilterRegistry` and built
//! from it as a configured filter would be, replaces the config's filter
//! (`Trainer::set_filter`), and trains; the example then checks the trained state
//! against Mip-Splatting's static nu of the same centres.
//!
//! Run: `cargo run --release --example custom_filter [-- OUT_DIR]`
//! (default `target/custom_filter`; also runs as a test).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use maaf::autodiff::PerGaussian;
use maaf::filter::{
    FilterConfig, FilterError, FilterInputs, FilterRegistry, FilterState, SamplingFilter, Viewer,
    static_nu,
};
use maaf::train::data::synthetic::{self, GenerateOptions};
use maaf::train::data::{Dataset, DatasetOptions};
use maaf::train::trainer::{TrainConfig, Trainer};

// ---- the user's filter ----

/// Refreshes so far, shared with the caller.
static REFRESHES: AtomicUsize = AtomicUsize::new(0);

/// Static nu = the median over the cameras that see the centre of `f / d`.
struct MedianFilter;

impl SamplingFilter for MedianFilter {
    fn name(&self) -> &str {
        "median"
    }

    fn compute(
        &self,
        inputs: &dyn FilterInputs,
        cfg: &FilterConfig,
    ) -> Result<FilterState, FilterError> {
        REFRESHES.fetch_add(1, Ordering::Relaxed);
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
                rates.get(rates.len() / 2).copied().unwrap_or(0.0)
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

// ---- a run with it ----

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("target/custom_filter"), PathBuf::from);
    run_in(&out)
}

/// Generates a small scene into `out/data`, trains 40 iterations with the median
/// filter and checks its state against the static filter's.
fn run_in(out: &Path) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(out)?;
    let data_dir = out.join("data");
    if !data_dir.join("transforms_train.json").exists() {
        let opts = GenerateOptions {
            size: 64,
            frames: Some(12),
            samples: 1,
            test_frames: 2,
            val_frames: 2,
            video_frames: 2,
            force: true,
            ..GenerateOptions::default()
        };
        synthetic::generate(&data_dir, &opts, &mut |_, _| {})?;
    }
    let data = Dataset::open(&data_dir, DatasetOptions::default())?;
    let mut config = TrainConfig {
        iterations: 40,
        train_scale: 0.5,
        init_points: 800,
        ..TrainConfig::default()
    };
    config.filter.refresh.start = 10;
    config.filter.refresh.every = 10;

    let mut filters = FilterRegistry::builtin();
    filters.register("median", |_| Box::new(MedianFilter))?;
    let mut trainer = Trainer::new(&data, config.clone())?;
    trainer.set_filter(filters.build("median", &config.filter)?);
    if trainer.sampling_filter().name() != "median" {
        return Err("the trainer did not take the median filter".into());
    }
    if trainer.observations.num_frames() != 0 {
        return Err("a filter that reads no observation got an observation table".into());
    }
    while trainer.iteration < config.iterations {
        trainer.step();
    }
    let refreshes = REFRESHES.load(Ordering::Relaxed);
    // Once before training, then at 10, 20, 30 (never at the last iteration).
    if refreshes < 4 {
        return Err(format!("the filter was computed {refreshes} times, expected >= 4").into());
    }
    let FilterState::Mip3d { nu, .. } = &trainer.filter else {
        return Err("the trainer does not hold the median filter's state".into());
    };
    if nu.len() != trainer.num_gaussians() || trainer.filter.rows() != nu.len() {
        return Err("the filter state has the wrong number of rows".into());
    }
    // The median never exceeds the maximum: compare both at the current centres.
    let centres: Vec<[f32; 3]> = trainer
        .canonical()
        .means
        .data()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let max_nu = static_nu(&centres, trainer.cameras(), &config.filter)?;
    trainer.refresh_filter();
    let FilterState::Mip3d { nu, .. } = &trainer.filter else {
        return Err("the refresh changed the filter's kind".into());
    };
    let above = nu.iter().zip(&max_nu).filter(|(m, x)| m > x).count();
    let below = nu.iter().zip(&max_nu).filter(|(m, x)| m < x).count();
    println!(
        "{} Gaussians, {refreshes} refreshes: median nu below the static maximum for {below}, above for {above}",
        nu.len()
    );
    if above > 0 || below == 0 {
        return Err(format!("median nu above the maximum for {above}, below for {below}").into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn trains_with_a_custom_filter() {
        let dir = std::env::temp_dir().join(format!("maaf-custom-filter-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        super::run_in(&dir).expect("the example runs");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
