//! Densification as a strategy (the shape of gsplat's `Strategy`): what to do with
//! each gradient step's statistics after the backward pass, and how to change the
//! set of Gaussians after the step. The trainer holds one; the config chooses
//! between the two built-in ones ([`for_config`]) and a user's replaces it
//! ([`Trainer::set_strategy`]).
//!
//! gsplat's `step_pre_backward` exists to keep the gradient of the screen-space
//! means (`retain_grad`); maaf's tape keeps every gradient, so the hooks are the
//! two that do work: [`Strategy::after_backward`] (gsplat's statistics update in
//! `step_post_backward`) and [`Strategy::refine`] (its refinement, which runs here
//! after validation, so validation sees the model the step trained).
//!
//! A strategy changes the Gaussians only through [`Trainer::apply_plan`] (one row
//! index list for the model, its Adam moments, the filter state, observations,
//! statistics and liveness) and [`Trainer::reset_opacity`]. Its statistics are the
//! trainer's [`DensifyStats`] (gsplat's `state`, held by the caller and checkpointed
//! with the run); state of its own is not checkpointed.

use super::{DensifyStats, TrainConfig, Trainer, ViewGrad, plan_densify};

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

/// A densification strategy: the two points of a training iteration where the set
/// of Gaussians and its statistics may change.
pub trait Strategy: Send {
    /// The strategy's name (for messages).
    fn name(&self) -> &str;

    /// After the backward pass and the optimiser step of a step that was not
    /// skipped: gather the statistics the strategy needs.
    fn after_backward(&mut self, trainer: &mut Trainer, info: &StepInfo<'_>);

    /// After iteration `iteration`'s update (and validation): clone, split, prune,
    /// reset opacities as due. Returns whether the set of Gaussians changed (the
    /// filter is then refreshed if `filter.refresh.after_densify`).
    fn refine(&mut self, trainer: &mut Trainer, iteration: usize) -> bool;
}

/// The 3DGS adaptive density control as SaRO-GS configures it (`config.densify`):
/// the mean NDC gradient of the screen means is accumulated after every step; every
/// `densify.every` iterations in `[from, until]` Gaussians are cloned, split and
/// pruned ([`plan_densify`]) and the statistics restart; every
/// `densify.opacity_reset_every` iterations up to `until` the opacities are reset.
#[derive(Clone, Copy, Debug, Default)]
pub struct DefaultStrategy;

impl DefaultStrategy {
    /// Clone / split / prune when the schedule says so at `it`; whether the set of
    /// Gaussians changed.
    pub fn densify(&self, trainer: &mut Trainer, it: usize) -> bool {
        let d = &trainer.config.densify;
        if !(it >= d.from && it <= d.until && d.every > 0 && it.is_multiple_of(d.every)) {
            return false;
        }
        let big_screen = trainer.last_reset.is_some();
        let seed = trainer.config.seed ^ (it as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
        let plan = plan_densify(
            trainer.model.as_ref(),
            &trainer.stats,
            d,
            trainer.extent,
            big_screen,
            seed,
        );
        trainer.apply_plan(&plan);
        // 3DGS restarts the gradient statistics after every densify_and_prune.
        trainer.stats = DensifyStats::new(plan.index.len());
        plan.cloned + plan.split + plan.pruned > 0
    }

    /// The opacity reset when the schedule says so at `it`.
    pub fn reset(&self, trainer: &mut Trainer, it: usize) {
        let d = &trainer.config.densify;
        if d.opacity_reset_every > 0 && it <= d.until && it.is_multiple_of(d.opacity_reset_every) {
            let to = d.reset_opacity;
            trainer.reset_opacity(to);
            trainer.last_reset = Some(it);
        }
    }
}

impl Strategy for DefaultStrategy {
    fn name(&self) -> &str {
        "default"
    }

    fn after_backward(&mut self, trainer: &mut Trainer, info: &StepInfo<'_>) {
        trainer.stats.record_views(info.views, info.loss_scale);
    }

    fn refine(&mut self, trainer: &mut Trainer, it: usize) -> bool {
        // Nothing at the last iteration: a run shorter than the schedule must not end
        // on an opacity reset or an unrefined densification.
        if it >= trainer.config.iterations {
            return false;
        }
        let changed = self.densify(trainer, it);
        self.reset(trainer, it);
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
        "sensitivity_pruning"
    }

    fn after_backward(&mut self, trainer: &mut Trainer, info: &StepInfo<'_>) {
        self.base.after_backward(trainer, info);
    }

    fn refine(&mut self, trainer: &mut Trainer, it: usize) -> bool {
        if it >= trainer.config.iterations {
            return false;
        }
        let mut changed = self.base.densify(trainer, it);
        changed |= trainer.maybe_prune(it);
        self.base.reset(trainer, it);
        changed
    }
}

/// The strategy `config` chooses: [`SensitivityPruning`] when `prune.every > 0`,
/// else [`DefaultStrategy`].
pub fn for_config(config: &TrainConfig) -> Box<dyn Strategy> {
    if config.prune.every > 0 {
        Box::new(SensitivityPruning::default())
    } else {
        Box::new(DefaultStrategy)
    }
}

impl Trainer {
    /// Replaces the densification strategy (the trainer starts with the config's,
    /// [`for_config`]). The statistics the trainer holds are kept.
    pub fn set_strategy(&mut self, strategy: Box<dyn Strategy>) {
        self.strategy = Some(strategy);
    }

    /// The strategy's [`Strategy::after_backward`] for one step.
    pub(super) fn strategy_after_backward(&mut self, info: &StepInfo<'_>) {
        if let Some(mut s) = self.strategy.take() {
            s.after_backward(self, info);
            self.strategy = Some(s);
        }
    }

    /// The strategy's [`Strategy::refine`] after iteration `it`.
    pub(super) fn strategy_refine(&mut self, it: usize) -> bool {
        match self.strategy.take() {
            Some(mut s) => {
                let changed = s.refine(self, it);
                self.strategy = Some(s);
                changed
            }
            None => false,
        }
    }
}
