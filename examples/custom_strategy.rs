//! A densification strategy of your own, run by the normal trainer and written only
//! against maaf's public API: "budgeted growth", which every `every` iterations
//! removes the Gaussians whose opacity is below `min_opacity` and clones the
//! `budget` Gaussians with the largest mean screen-space gradient (no split, no
//! opacity reset). It keeps the trainer's statistics with
//! `DensifyStats::record_views` after every backward pass, changes the Gaussians
//! through one `DensifyPlan` applied by `Trainer::apply_plan` (the model, its Adam
//! moments, the filter state and the statistics move together), and tallies what
//! it did, which the example then checks against the trained model.
//!
//! Run: `cargo run --release --example custom_strategy [-- OUT_DIR]`
//! (default `target/custom_strategy`; also runs as a test).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use maaf::autodiff::PerGaussian;
use maaf::train::data::synthetic::{self, GenerateOptions};
use maaf::train::data::{Dataset, DatasetOptions};
use maaf::train::trainer::{DensifyPlan, DensifyStats, StepInfo, Strategy, TrainConfig, Trainer};

// ---- the user's strategy ----

/// What the strategy did, shared with the caller.
#[derive(Debug, Default)]
struct Tally {
    /// Steps whose statistics were recorded.
    steps: usize,
    /// Gaussians cloned and pruned over the run.
    cloned: usize,
    pruned: usize,
}

/// Prune below `min_opacity`, then clone the `budget` largest mean gradients.
struct BudgetedGrowth {
    every: usize,
    budget: usize,
    min_opacity: f32,
    tally: Arc<Mutex<Tally>>,
}

impl Strategy for BudgetedGrowth {
    fn name(&self) -> &str {
        "budgeted_growth"
    }

    fn after_backward(&mut self, trainer: &mut Trainer, info: &StepInfo<'_>) {
        trainer.stats.record_views(info.views, info.loss_scale);
        if let Ok(mut t) = self.tally.lock() {
            t.steps += 1;
        }
    }

    fn refine(&mut self, trainer: &mut Trainer, iteration: usize) -> bool {
        if !iteration.is_multiple_of(self.every) || iteration >= trainer.config.iterations {
            return false;
        }
        let opacity = trainer.canonical().opacity;
        let grad = trainer.stats.mean_grad();
        let keep: Vec<usize> = (0..grad.len())
            .filter(|&i| opacity.data()[i] >= self.min_opacity)
            .collect();
        let mut by_grad = keep.clone();
        by_grad.sort_by(|&a, &b| grad[b].total_cmp(&grad[a]).then(a.cmp(&b)));
        by_grad.truncate(self.budget);
        by_grad.sort_unstable();
        let plan = DensifyPlan {
            pruned: grad.len() - keep.len(),
            cloned: by_grad.len(),
            // Survivors, then a copy of each clone (same centre and scale: no new_rows).
            index: keep.into_iter().chain(by_grad).collect(),
            ..DensifyPlan::default()
        };
        trainer.apply_plan(&plan);
        trainer.stats = DensifyStats::new(plan.index.len());
        if let Ok(mut t) = self.tally.lock() {
            t.cloned += plan.cloned;
            t.pruned += plan.pruned;
        }
        plan.cloned + plan.pruned > 0
    }
}

// ---- a run with it ----

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("target/custom_strategy"), PathBuf::from);
    run_in(&out)
}

/// Generates a small scene into `out/data`, trains 60 iterations with the strategy
/// and checks the model against the strategy's tally.
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
    let config = TrainConfig {
        iterations: 60,
        train_scale: 0.5,
        init_points: 800,
        ..TrainConfig::default()
    };
    let mut trainer = Trainer::new(&data, config.clone())?;
    let start = trainer.num_gaussians();
    let tally = Arc::new(Mutex::new(Tally::default()));
    trainer.set_strategy(Box::new(BudgetedGrowth {
        every: 20,
        budget: 50,
        min_opacity: 0.05,
        tally: Arc::clone(&tally),
    }));
    while trainer.iteration < config.iterations {
        trainer.step();
    }
    let t = tally.lock().map_err(|_| "tally poisoned")?;
    let end = trainer.num_gaussians();
    println!(
        "{start} -> {end} Gaussians: {} cloned, {} pruned over {} recorded steps",
        t.cloned, t.pruned, t.steps
    );
    // Two refinements (20, 40; none at the last iteration), each cloning the budget.
    if t.cloned != 2 * 50 {
        return Err(format!("cloned {} Gaussians, expected 100", t.cloned).into());
    }
    if end != start + t.cloned - t.pruned {
        return Err(format!(
            "{end} Gaussians, the tally says {}",
            start + t.cloned - t.pruned
        )
        .into());
    }
    if t.steps != config.iterations - trainer.skipped_steps {
        return Err(format!(
            "statistics recorded at {} of {} steps",
            t.steps, config.iterations
        )
        .into());
    }
    if trainer.filter.rows() != end || trainer.stats.denom.len() != end {
        return Err("the filter or the statistics were not resized with the Gaussians".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn trains_with_a_custom_strategy() {
        let dir = std::env::temp_dir().join(format!("maaf-custom-strategy-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        super::run_in(&dir).expect("the example runs");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
