//! A densification strategy of your own in the whole `maaf` command line, written
//! only against maaf's public API: "budgeted growth", which every `densify.every`
//! iterations removes the Gaussians whose opacity is below `densify.min_opacity` and
//! clones the Gaussians with the largest mean screen-space gradient, at most
//! `budget` per refinement and `lifetime` over the whole run (no split, no opacity
//! reset). `budget` and `lifetime` are its own options, read from the config's
//! `densify.options` (defaults 20 and 50). How many it has cloned so far is its own state: `Strategy::state` saves
//! it in every checkpoint and `Strategy::load_state` restores it, so a resumed run
//! clones exactly what the uninterrupted one would. It sees the run's `TrainState`
//! (never the trainer): it keeps the state's statistics with
//! `DensifyStats::record_views` after every backward pass and changes the Gaussians
//! through one `DensifyPlan` applied by `TrainState::apply_plan` (the model, its Adam
//! moments, the filter state and the statistics move together).
//!
//! ```text
//! # "densify": {"strategy": "budgeted_growth", "every": 2, "options": {"budget": 15}} in C.json
//! cargo run --release --example custom_strategy -- train --data DATA --out RUN --config C.json
//! cargo run --release --example custom_strategy -- train --resume RUN
//! ```
//!
//! `maaf train --resume RUN` refuses the run, naming the strategy.
//! `tests/cli/custom_plugins.rs` runs it: trains, is killed, resumes bit-identical,
//! evaluates.

use maaf::scene::TrainConfig;
use maaf::train::trainer::{DensifyPlan, DensifyStats, RefineStep, StepInfo, Strategy, TrainState};
use serde_json::{Value, json};

/// Prune below `min_opacity`, then clone the largest mean gradients within budget.
struct BudgetedGrowth {
    every: usize,
    min_opacity: f32,
    /// Most Gaussians cloned at one refinement.
    budget: usize,
    /// Most Gaussians cloned over the run.
    lifetime: usize,
    /// Gaussians cloned so far (the checkpointed state).
    cloned: usize,
}

impl Strategy for BudgetedGrowth {
    fn name(&self) -> &str {
        "budgeted_growth"
    }

    fn after_backward(&mut self, state: &mut TrainState, info: &StepInfo<'_>) {
        state.stats.record_views(info.views, info.loss_scale);
    }

    fn refine(&mut self, state: &mut TrainState, step: &RefineStep<'_>) -> bool {
        let it = step.iteration;
        if !it.is_multiple_of(self.every) || it >= step.config.iterations {
            return false;
        }
        let opacity = state.canonical().opacity;
        let grad = state.stats.mean_grad();
        let keep: Vec<usize> = (0..grad.len())
            .filter(|&i| opacity.data()[i] >= self.min_opacity)
            .collect();
        let mut by_grad = keep.clone();
        by_grad.sort_by(|&a, &b| grad[b].total_cmp(&grad[a]).then(a.cmp(&b)));
        by_grad.truncate(self.budget.min(self.lifetime.saturating_sub(self.cloned)));
        by_grad.sort_unstable();
        let plan = DensifyPlan {
            pruned: grad.len() - keep.len(),
            cloned: by_grad.len(),
            // Survivors, then a copy of each clone (same centre and scale: no new_rows).
            index: keep.into_iter().chain(by_grad).collect(),
            ..DensifyPlan::default()
        };
        state.apply_plan(&plan);
        state.stats = DensifyStats::new(plan.index.len());
        self.cloned += plan.cloned;
        plan.cloned + plan.pruned > 0
    }

    fn state(&self) -> Value {
        json!({ "cloned": self.cloned })
    }

    fn load_state(&mut self, state: &Value) -> Result<(), String> {
        let cloned = state["cloned"]
            .as_u64()
            .ok_or_else(|| format!("`cloned`: expected a count, got {}", state["cloned"]))?;
        self.cloned = cloned as usize;
        Ok(())
    }
}

/// The count option `name` of `densify.options`, `default` when absent.
fn count_option(config: &TrainConfig, name: &str, default: usize) -> Result<usize, String> {
    match config.densify.options.get(name) {
        None => Ok(default),
        Some(v) => v
            .as_u64()
            .map(|n| n as usize)
            .ok_or_else(|| format!("densify.options.{name}: expected a count, got {v}")),
    }
}

/// The strategy for a run: its interval and threshold are the config's `densify`,
/// its budgets its own options there.
fn budgeted_growth(config: &TrainConfig) -> Result<Box<dyn Strategy>, String> {
    if config.densify.every == 0 {
        return Err("densify.every = 0: budgeted growth needs a refinement interval".into());
    }
    if let Some(unknown) =
        (config.densify.options.keys()).find(|k| !["budget", "lifetime"].contains(&k.as_str()))
    {
        return Err(format!(
            "densify.options.{unknown}: not an option of budgeted growth (budget, lifetime)"
        ));
    }
    Ok(Box::new(BudgetedGrowth {
        every: config.densify.every,
        min_opacity: config.densify.min_opacity as f32,
        budget: count_option(config, "budget", 20)?,
        lifetime: count_option(config, "lifetime", 50)?,
        cloned: 0,
    }))
}

fn main() {
    maaf::cli::Maaf::new()
        .strategy("budgeted_growth", budgeted_growth)
        .run()
}
