//! Densification as a strategy (the shape of gsplat's `Strategy`): what to do with
//! each gradient step's statistics after the backward pass, and how to change the
//! set of Gaussians after the step. The trainer holds one; the config names it
//! (`densify.strategy`, looked up in a [`StrategyRegistry`]: the two built-in ones
//! and any a program registers), or a user's replaces it
//! ([`Trainer::set_strategy`]).
//!
//! gsplat's `step_pre_backward` exists to keep the gradient of the screen-space
//! means (`retain_grad`); maaf's tape keeps every gradient, so the hooks are the
//! two that do work: [`Strategy::after_backward`] (gsplat's statistics update in
//! `step_post_backward`) and [`Strategy::refine`] (its refinement, which runs here
//! after validation, so validation sees the model the step trained).
//!
//! A strategy receives the run's [`TrainState`] and a record of the step, never the
//! trainer. It changes the Gaussians only through [`TrainState::apply_plan`] (one row
//! index list for the model, its Adam moments, the filter state, observations,
//! statistics and liveness) and [`TrainState::reset_opacity`]. Its statistics are the
//! state's [`DensifyStats`] (gsplat's `state`, held by the caller and checkpointed
//! with the run); state of its own is checkpointed through [`Strategy::state`] and
//! [`Strategy::load_state`].

use std::sync::Arc;

use maaf_io::Registry;

use serde_json::Value;

use maaf_splat::{Camera, RenderSettings};

use super::prune::maybe_prune;
use super::{DensifyStats, TrainConfig, TrainState, Trainer, ViewGrad, plan_densify};

/// What a strategy sees of one gradient step (gsplat's `info`).
pub struct StepInfo<'a> {
    /// The iteration (1-based) whose gradient step this is.
    pub iteration: usize,
    /// Per view of the batch: the gradient of its screen-space means, its radii and
    /// its image size.
    pub views: &'a [ViewGrad<'a>],
    /// What turns the batch objective's gradient into each view's own (the batch
    /// size: the objective is the views' mean).
    pub loss_scale: f32,
}

/// What a strategy's refinement sees of the run after iteration `iteration`'s update
/// (and validation): the configuration, the scene's extent and the training views,
/// with the render settings of that iteration (what sensitivity pruning renders).
pub struct RefineStep<'a> {
    /// The iteration (1-based) just completed.
    pub iteration: usize,
    /// The run's configuration (`densify`, `prune`, `seed`, `iterations`, ...).
    pub config: &'a TrainConfig,
    /// Radius of the training cameras' bounding sphere (3DGS `cameras_extent`).
    pub extent: f64,
    /// The training cameras, at the training scale.
    pub cameras: &'a [Camera],
    /// The time of each training camera's view.
    pub times: &'a [f64],
    /// The render settings of `iteration`.
    pub settings: &'a RenderSettings,
}

/// A densification strategy: the two points of a training iteration where the set
/// of Gaussians and its statistics may change.
pub trait Strategy: Send {
    /// The strategy's name (for messages).
    fn name(&self) -> &str;

    /// After the backward pass and the optimiser step of a step that was not
    /// skipped: gather the statistics the strategy needs.
    fn after_backward(&mut self, state: &mut TrainState, info: &StepInfo<'_>);

    /// After `step.iteration`'s update (and validation): clone, split, prune, reset
    /// opacities as due. Returns whether the set of Gaussians changed (the filter is
    /// then refreshed if `filter.refresh.after_densify`).
    fn refine(&mut self, state: &mut TrainState, step: &RefineStep<'_>) -> bool;

    /// The strategy's own state (counters, budgets, random state: whatever
    /// [`Strategy::refine`] reads besides the training state), saved in every checkpoint's
    /// `state.json` so a resumed run continues bit for bit. Floats survive exactly
    /// (JSON numbers are written in their shortest round-trip form). Default: none
    /// (`null`).
    fn state(&self) -> Value {
        Value::Null
    }

    /// Restores what [`Strategy::state`] returned, when a checkpoint is loaded
    /// (resume, branch); an error (one line naming the bad field) stops the load.
    /// Not called for a checkpoint without state. Default: nothing to restore.
    fn load_state(&mut self, state: &Value) -> Result<(), String> {
        let _ = state;
        Ok(())
    }
}

/// The 3DGS adaptive density control as SaRO-GS configures it (`config.densify`):
/// the mean NDC gradient of the screen means is accumulated after every step; every
/// `densify.every` iterations in `[from, until]` Gaussians are cloned, split and
/// pruned ([`plan_densify`]) and the statistics restart; every
/// `densify.opacity_reset_every` iterations up to `until` the opacities are reset.
#[derive(Clone, Copy, Debug, Default)]
pub struct DefaultStrategy;

impl DefaultStrategy {
    /// Clone / split / prune when the schedule says so at `step.iteration`; whether
    /// the set of Gaussians changed.
    pub fn densify(&self, state: &mut TrainState, step: &RefineStep<'_>) -> bool {
        let (d, it) = (&step.config.densify, step.iteration);
        if !(it >= d.from && it <= d.until && d.every > 0 && it.is_multiple_of(d.every)) {
            return false;
        }
        let big_screen = state.last_reset.is_some();
        let seed = step.config.seed ^ (it as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
        let plan = plan_densify(
            state.model.as_ref(),
            &state.stats,
            d,
            step.extent,
            big_screen,
            seed,
        );
        state.apply_plan(&plan);
        // 3DGS restarts the gradient statistics after every densify_and_prune.
        state.stats = DensifyStats::new(plan.index.len());
        plan.cloned + plan.split + plan.pruned > 0
    }

    /// The opacity reset when the schedule says so at `step.iteration`.
    pub fn reset(&self, state: &mut TrainState, step: &RefineStep<'_>) {
        let (d, it) = (&step.config.densify, step.iteration);
        if d.opacity_reset_every > 0 && it <= d.until && it.is_multiple_of(d.opacity_reset_every) {
            state.reset_opacity(d.reset_opacity, it);
        }
    }
}

impl Strategy for DefaultStrategy {
    fn name(&self) -> &str {
        "default"
    }

    fn after_backward(&mut self, state: &mut TrainState, info: &StepInfo<'_>) {
        state.stats.record_views(info.views, info.loss_scale);
    }

    fn refine(&mut self, state: &mut TrainState, step: &RefineStep<'_>) -> bool {
        // Nothing at the last iteration: a run shorter than the schedule must not end
        // on an opacity reset or an unrefined densification.
        if step.iteration >= step.config.iterations {
            return false;
        }
        let changed = self.densify(state, step);
        self.reset(state, step);
        changed
    }
}

/// [`DefaultStrategy`] plus sensitivity pruning (`config.prune`, e.g.
/// `configs/compact_prune.json`): at each iteration densification, then the
/// pruning of the lowest Speedy-Splat scores when due (`trainer/prune.rs`), then
/// the opacity reset.
#[derive(Clone, Copy, Debug, Default)]
pub struct SensitivityPruning {
    /// Densification and opacity reset.
    pub base: DefaultStrategy,
}

impl Strategy for SensitivityPruning {
    fn name(&self) -> &str {
        "sensitivity"
    }

    fn after_backward(&mut self, state: &mut TrainState, info: &StepInfo<'_>) {
        self.base.after_backward(state, info);
    }

    fn refine(&mut self, state: &mut TrainState, step: &RefineStep<'_>) -> bool {
        if step.iteration >= step.config.iterations {
            return false;
        }
        let mut changed = self.base.densify(state, step);
        changed |= maybe_prune(state, step);
        self.base.reset(state, step);
        changed
    }
}

/// Makes a strategy from the run's config (it reads its settings there).
pub type StrategyMaker = dyn Fn(&TrainConfig) -> Result<Box<dyn Strategy>, String> + Send + Sync;

/// Densification strategies by name: what `densify.strategy` may name.
/// [`StrategyRegistry::builtin`] holds `default` ([`DefaultStrategy`]) and
/// `sensitivity` ([`SensitivityPruning`]); a program adds its own
/// (`maaf::cli::Maaf::strategy`). Cloning shares the makers.
#[derive(Clone)]
pub struct StrategyRegistry {
    makers: Registry<StrategyMaker>,
}

impl StrategyRegistry {
    /// The built-in strategies.
    pub fn builtin() -> Self {
        let mut r = StrategyRegistry {
            makers: Registry::new("strategy (densify.strategy)", "maaf::cli::Maaf::strategy"),
        };
        let _ = r.register("default", |c| {
            no_options(c, "default")?;
            Ok(Box::new(DefaultStrategy))
        });
        let _ = r.register("sensitivity", |c| {
            no_options(c, "sensitivity")?;
            Ok(Box::new(SensitivityPruning::default()))
        });
        r
    }

    /// Adds the strategy `maker` makes under `name`; refuses a name already
    /// registered or not 1 to 64 letters, digits or `_` ([`Registry::register`]).
    pub fn register<F>(&mut self, name: &str, maker: F) -> Result<(), String>
    where
        F: Fn(&TrainConfig) -> Result<Box<dyn Strategy>, String> + Send + Sync + 'static,
    {
        self.makers.register(name, Arc::new(maker))
    }

    /// The registered names, in registration order.
    pub fn names(&self) -> Vec<&str> {
        self.makers.names()
    }

    /// The name of the strategy `config` runs: `densify.strategy`, else the built-in
    /// one the config implies (`sensitivity` when `prune.every > 0`, else `default`).
    pub fn name_for(config: &TrainConfig) -> &str {
        match &config.densify.strategy {
            Some(name) => name,
            None if config.prune.every > 0 => "sensitivity",
            None => "default",
        }
    }

    /// Refuses (`what`: the config's file or section) a config whose strategy is not
    /// registered, naming it and the registered ones.
    pub fn check(&self, config: &TrainConfig, what: &str) -> Result<(), crate::Error> {
        (self.makers.get(Self::name_for(config)))
            .map(|_| ())
            .map_err(|e| crate::Error::Input(format!("{what}: {e}")))
    }

    /// The strategy `config` names, made by its maker (whose error names the field).
    pub fn build(&self, config: &TrainConfig) -> Result<Box<dyn Strategy>, crate::Error> {
        self.check(config, "config")?;
        let name = Self::name_for(config);
        let maker = self.makers.get(name).map_err(crate::Error::Input)?;
        let strategy = maker(config)
            .map_err(|e| crate::Error::Input(format!("config: densify.strategy `{name}`: {e}")))?;
        Ok(strategy)
    }
}

/// Refuses `densify.options` for a built-in strategy, which has none.
fn no_options(config: &TrainConfig, name: &str) -> Result<(), String> {
    if config.densify.options.is_empty() {
        return Ok(());
    }
    Err(format!(
        "densify.options: the built-in strategy `{name}` takes no options (options are for a strategy of one's own)"
    ))
}

impl Trainer {
    /// Replaces the densification strategy (the trainer starts with the one the
    /// config names). The statistics the trainer holds are kept; call it before
    /// loading a checkpoint so the strategy's own state is restored into it.
    pub fn set_strategy(&mut self, strategy: Box<dyn Strategy>) {
        self.strategy = strategy;
    }

    /// The strategy's own state ([`Strategy::state`]), for a checkpoint.
    pub(super) fn strategy_state(&self) -> Value {
        self.strategy.state()
    }

    /// Restores the strategy's own state from a checkpoint ([`Strategy::load_state`]).
    pub(super) fn load_strategy_state(&mut self, state: &Value) -> Result<(), String> {
        if state.is_null() {
            return Ok(());
        }
        let loaded = self.strategy.load_state(state);
        loaded.map_err(|e| format!("strategy `{}`: {e}", self.strategy.name()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_config_names_a_strategy_and_an_unregistered_one_is_refused() {
        let mut config = TrainConfig::default();
        assert_eq!(StrategyRegistry::name_for(&config), "default");
        config.prune.every = 100;
        assert_eq!(StrategyRegistry::name_for(&config), "sensitivity");
        let mut reg = StrategyRegistry::builtin();
        assert_eq!(reg.build(&config).expect("built in").name(), "sensitivity");
        config.densify.strategy = Some("mine".into());
        let err = reg
            .build(&config)
            .err()
            .expect("not registered")
            .to_string();
        assert!(
            err.contains("`mine` is not registered") && err.contains("default, sensitivity"),
            "{err}"
        );
        reg.register("mine", |_| Ok(Box::new(DefaultStrategy)))
            .expect("new name");
        assert!(reg.build(&config).is_ok());
        assert!(
            reg.register("mine", |_| Ok(Box::new(DefaultStrategy)))
                .is_err()
        );
        assert!(
            reg.register("no name", |_| Ok(Box::new(DefaultStrategy)))
                .is_err()
        );
        config.densify.strategy = Some("default".into());
        config.densify.options.insert("budget".into(), 20.into());
        let err = reg.build(&config).err().expect("options").to_string();
        assert!(err.contains("`default` takes no options"), "{err}");
        // Old configs (no key) read as before; the key is written as null.
        let json = serde_json::to_value(TrainConfig::default()).expect("json");
        assert!(json["densify"]["strategy"].is_null());
    }
}
