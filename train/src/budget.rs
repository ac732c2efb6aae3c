//! The budget's planner (`budget`, `maaf train --budget 10m`): a short warm-up on the
//! run's own data and settings measures what a step, a filter refresh and a
//! validation cost on this machine, and one factor `s` scaling the schedule
//! ([`TrainConfig::scaled_schedule`]) is chosen so that the predicted wall time of the
//! run fits the budget.
//!
//! Cost model: a step at N Gaussians takes `a + b N` seconds, fitted to the warm-up's
//! steps at the initial count and at twice it (rows resampled as clones);
//! the count is taken as the initial one until `densify.from`, growing linearly to
//! the cap at `densify.until` and at the cap after it, an upper bound, since pruning
//! keeps most runs under their cap. Refreshes and validations cost their measured
//! time scaled by the count, one refresh per `filter.refresh.every` iterations from
//! its start and one per densification. The time already spent (loading, the
//! warm-up) comes off the budget, and 5 % is kept for the final save and test pass.
//! When densification ends, [`TailControl`] sets the final iteration count from the
//! run's measured speed.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::bench::{hold_schedule, resample_rows};
use crate::data::Dataset;
use crate::trainer::Trainer;
use crate::{Error, Plugins};
use maaf_scene::TrainConfig;

/// Steps timed at each Gaussian count (after one untimed step).
const TIMED_STEPS: usize = 5;
/// Share of the budget kept for the final checkpoint and the test pass.
const RESERVE: f64 = 0.05;
/// Largest and smallest schedule factors.
const SCALE_RANGE: (f64, f64) = (0.005, 4.0);

/// What a budget chose and why (`RUN/budget.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BudgetPlan {
    /// The budget, seconds.
    pub budget_seconds: f64,
    /// Wall time from the start of the run to the end of the warm-up, seconds.
    pub spent_seconds: f64,
    /// Seconds per step measured at two Gaussian counts, `(count, seconds)`.
    pub step_seconds: [(usize, f64); 2],
    /// Seconds of one filter refresh at the larger count.
    pub refresh_seconds: f64,
    /// Seconds of one validation at the larger count.
    pub validation_seconds: f64,
    /// The factor the schedule was scaled by.
    pub scale: f64,
    /// The iterations and Gaussian cap it gave.
    pub iterations: usize,
    /// Gaussian cap of the scaled schedule.
    pub max_gaussians: usize,
    /// The wall time the model predicts for the whole run, seconds.
    pub predicted_seconds: f64,
    /// The run's iterations as the tail control set them when densification ended
    /// ([`TailControl`]); `None` before that, or when the run has no tail.
    #[serde(default)]
    pub adjusted_iterations: Option<usize>,
}

/// Corrects the planned run where its cost is known: when densification ends (the
/// Gaussian count settles), the wall time per iteration of the last iterations before
/// it, validations and refreshes included, sets how many iterations the rest of the
/// budget holds. Only the iteration count changes; the learning-rate decays and
/// windows keep the plan's lengths. The warm-up's model errs on the safe side (it
/// times the initial Gaussians, which pruning soon thins, and assumes the cap is
/// reached), so the tail mostly grows.
pub struct TailControl {
    started: Instant,
    available: f64,
    at: usize,
    window: usize,
    mark: Option<Instant>,
}

impl TailControl {
    /// The control of a run planned by `plan` into `config` (the scaled schedule),
    /// which started at `started`; `None` when densification does not end before
    /// the last iteration.
    pub fn new(plan: &BudgetPlan, config: &TrainConfig, started: Instant) -> Option<Self> {
        let at = config.densify.until;
        (at >= 2 && at < config.iterations).then(|| TailControl {
            started,
            available: plan.budget_seconds * (1.0 - RESERVE),
            at,
            window: (at / 4).clamp(1, 100),
            mark: None,
        })
    }

    /// Called after iteration `it`: at the end of densification, the run's new
    /// iteration count (at least `it + 1`).
    pub fn after(&mut self, it: usize) -> Option<usize> {
        if it == self.at - self.window {
            self.mark = Some(Instant::now());
        }
        if it != self.at {
            return None;
        }
        let per = self.mark?.elapsed().as_secs_f64() / self.window as f64;
        let left = self.available - self.started.elapsed().as_secs_f64();
        let more = if per > 0.0 { (left / per).floor() } else { 0.0 };
        Some(it + (more.max(1.0) as usize))
    }
}

/// Measured costs of the warm-up.
struct Costs {
    /// `a`, `b` of `a + b N` seconds per step.
    step: (f64, f64),
    /// Seconds of one refresh and one validation per Gaussian, at the larger count.
    refresh_per_gaussian: f64,
    validation_per_gaussian: f64,
    initial: usize,
}

/// Chooses the schedule for `config`'s budget: warms up on `data` with `plugins`,
/// then returns the scaled config (without its budget) and the plan. `started` is
/// when the run began, so loading counts against the budget. Refuses a budget that
/// cannot hold even the shortest schedule.
pub fn plan_budget(
    data: &Dataset,
    config: &TrainConfig,
    plugins: &Plugins,
    started: Instant,
) -> Result<(TrainConfig, BudgetPlan), Error> {
    let Some(budget) = config.budget else {
        return Err(Error::Input("plan_budget: the config has no budget".into()));
    };
    let (costs, measured) = warm_up(data, config, plugins)?;
    let spent = started.elapsed().as_secs_f64();
    let available = budget.seconds() * (1.0 - RESERVE) - spent;
    let predict = |s: f64| predicted(&config.scaled_schedule(s), &costs);
    let (lo, hi) = SCALE_RANGE;
    if available <= 0.0 || predict(lo) > available {
        return Err(Error::Input(format!(
            "budget {budget}: too short for this run: loading and the warm-up took {spent:.1} s and the shortest schedule ({} iterations) needs about {:.1} s more",
            config.scaled_schedule(lo).iterations,
            predict(lo)
        )));
    }
    let scale = if predict(hi) <= available {
        hi
    } else {
        // The prediction grows with s: bisect for the largest s that fits.
        let (mut a, mut b) = (lo, hi);
        for _ in 0..50 {
            let mid = 0.5 * (a + b);
            if predict(mid) <= available {
                a = mid;
            } else {
                b = mid;
            }
        }
        a
    };
    let chosen = config.scaled_schedule(scale);
    let plan = BudgetPlan {
        budget_seconds: budget.seconds(),
        spent_seconds: spent,
        step_seconds: measured,
        refresh_seconds: costs.refresh_per_gaussian * measured[1].0 as f64,
        validation_seconds: costs.validation_per_gaussian * measured[1].0 as f64,
        scale,
        iterations: chosen.iterations,
        max_gaussians: chosen.densify.max_gaussians,
        predicted_seconds: spent + predicted(&chosen, &costs),
        adjusted_iterations: None,
    };
    Ok((chosen, plan))
}

/// Times steps of a trainer of `config` at its initial count and at twice it, one
/// filter refresh and one validation, in the representation's dynamic stage; the
/// trainer is dropped afterwards.
fn warm_up(
    data: &Dataset,
    config: &TrainConfig,
    plugins: &Plugins,
) -> Result<(Costs, [(usize, f64); 2]), Error> {
    let mut warm = config.clone();
    warm.budget = None;
    // Timed in the dynamic stage, where nearly all of a run's steps are: a static
    // stage's steps skip the representation's field and networks.
    if let Some(stage) = warm.model.warm_up_mut() {
        *stage = 0;
    }
    let mut t = Trainer::with_plugins(data, warm, plugins)?;
    hold_schedule(&mut t.config, usize::MAX);
    let initial = t.num_gaussians();
    let timed = |t: &mut Trainer| {
        t.step();
        let t0 = Instant::now();
        for _ in 0..TIMED_STEPS {
            t.step();
        }
        t0.elapsed().as_secs_f64() / TIMED_STEPS as f64
    };
    let small = (initial, timed(&mut t));
    // Twice the initial count gives the slope at a fraction of the cap's cost.
    let cap = 2 * initial.max(1);
    t.check_memory(cap)?;
    resample_rows(&mut t, cap, config.seed);
    let large = (cap, timed(&mut t));
    let t0 = Instant::now();
    t.refresh_filter();
    let refresh = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    t.validation_psnr();
    let validation = t0.elapsed().as_secs_f64();
    let b = ((large.1 - small.1) / (large.0 - small.0) as f64).max(0.0);
    let a = (small.1 - b * small.0 as f64).max(0.0);
    let costs = Costs {
        step: (a, b),
        refresh_per_gaussian: refresh / cap as f64,
        validation_per_gaussian: validation / cap as f64,
        initial,
    };
    Ok((costs, [small, large]))
}

/// Predicted seconds of training `c` (module doc).
fn predicted(c: &TrainConfig, costs: &Costs) -> f64 {
    let n = c.iterations as f64;
    let d = &c.densify;
    let (n0, cap) = (
        costs.initial as f64,
        d.max_gaussians.max(costs.initial) as f64,
    );
    let from = (d.from as f64).min(n);
    let until = (d.until as f64).clamp(from, n);
    // Gaussian-iterations: flat, a linear ramp, flat at the cap.
    let area = from * n0 + (until - from) * 0.5 * (n0 + cap) + (n - until) * cap;
    let mean = area / n.max(1.0);
    let (a, b) = costs.step;
    let steps = a * n + b * area;
    let r = &c.filter.refresh;
    let refreshes = if r.every > 0 {
        (n - (r.start as f64).min(n)) / r.every as f64
    } else {
        0.0
    } + if r.after_densify && d.every > 0 {
        (until - from) / d.every as f64
    } else {
        0.0
    };
    let validations = if c.val_every > 0 {
        n / c.val_every as f64
    } else {
        0.0
    };
    steps
        + refreshes * costs.refresh_per_gaussian * mean
        + validations * costs.validation_per_gaussian * mean
}
