//! A whole training run in a run directory: `config.json`, `log.csv`, checkpoints
//! under `checkpoints/`, the final model in `model/`, and `summary.json`; resumable
//! from the newest complete checkpoint (`resume.rs`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::best::{BestSoFar, Chosen};
use super::log::{LogLayout, RowStats, csv_line};
use super::resume::same_settings;
use super::{
    Timings, TrainConfig, Trainer, checkpoints_newest_first, load_checkpoint_with_plugins,
    load_newest, repair_run_dir, save_checkpoint, truncate_log,
};
use crate::budget::{BudgetPlan, TailControl, plan_budget};
use crate::data::Dataset;
use crate::{Error, Plugins, write_atomic};
use maaf_scene::TrainedScene;
use maaf_scene::backdrop::BACKDROP_DIR;

/// The plan a budgeted run trained by (`RUN/budget.json`, [`crate::budget::BudgetPlan`]).
pub const BUDGET_FILE: &str = "budget.json";

/// What a finished run reports (also written as `RUN/summary.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunSummary {
    /// Iterations completed.
    pub iterations: usize,
    /// Wall time of the training loop in this process, seconds (plus that of the runs it resumed).
    pub train_seconds: f64,
    /// Final number of Gaussians.
    pub num_gaussians: usize,
    /// Steps skipped for non-finite values.
    pub skipped_steps: usize,
    /// Iteration of the last opacity reset, if there was one.
    #[serde(default)]
    pub last_reset: Option<usize>,
    /// Final Gaussians whose opacity received no gradient after the last reset
    /// (`last gradient iteration <= last_reset`; without a reset: none ever).
    #[serde(default)]
    pub dead_gaussians: usize,
    /// Of `dead_gaussians`, those the last reset lowered: still at its cap.
    #[serde(default)]
    pub dead_at_cap: usize,
    /// Time per phase.
    pub timings: Timings,
    /// Mean test PSNR at the training scale, dB, when the caller measured it (`maaf
    /// train` does, after training).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_psnr: Option<f64>,
    /// With `keep_best`: the state `model/` holds, chosen by validation PSNR (the
    /// last one is `checkpoints/iter_N`, N = `iterations`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chosen: Option<Chosen>,
    /// Why the run failed after training (a NaN test PSNR), when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
}

impl RunSummary {
    /// Writes the summary as `RUN/summary.json` (atomically).
    pub fn write(&self, run: &Path) -> Result<(), Error> {
        write_json(run, "summary.json", self)
    }
}

/// Trains on `data` into `out` (created if needed) with the representation
/// `config.model` describes. With `resume`, the run in `out` continues from its
/// newest complete checkpoint (`checkpoints/iter_N` or `model/`, whatever stopped the
/// run; the checkpoint's settings apply, except the iteration budget
/// `config.iterations`), or starts over with `config` if it has none yet. A resumed
/// run is bit-identical to an uninterrupted one with the same seed and thread count.
/// Prints a progress bar on a terminal and a line every 10% otherwise.
///
/// The run folder is locked for the whole call ([`maaf_io::RunLock`]: a second
/// trainer of `out` fails at once). `RUN/data.json` records `data` (a new run: once
/// the trainer is built and its memory checked, before its first file); a resume
/// refuses a data set that differs from the recorded one, a `config` (the run's
/// `config.json`) that differs from the checkpoint's settings other than the budget,
/// and a budget below the checkpoint's iteration, each before anything changes.
pub fn train_run(
    data: &Dataset,
    config: TrainConfig,
    out: &Path,
    resume: bool,
) -> Result<RunSummary, Error> {
    train_run_with_plugins(data, config, out, resume, &Plugins::builtin())
}

/// [`train_run`] with the terms, representations, filters and strategies of
/// `plugins` (the built-in ones and the program's own): everything `config` names
/// must be registered there, for a new run and for a resume (the run's
/// `config.json`), or the call fails with one line naming the run's config, what is
/// missing and what is registered, before anything changes.
pub fn train_run_with_plugins(
    data: &Dataset,
    config: TrainConfig,
    out: &Path,
    resume: bool,
    plugins: &Plugins,
) -> Result<RunSummary, Error> {
    let started = Instant::now();
    let _lock = lock_run(out)?;
    let what = if resume {
        out.join("config.json").display().to_string()
    } else {
        "config".to_string()
    };
    plugins.check(&config, &what)?;
    if resume {
        check_unrecorded_data(out, data)?;
        maaf_scene::run_data::check_and_record_data(out, data)?;
    }
    repair_run_dir(out)?;
    let budget = config.iterations;
    let found = if resume {
        load_newest(out, |dir| load_checkpoint_with_plugins(data, dir, plugins))
    } else {
        None
    };
    let mut tail = None;
    let mut trainer = match found {
        Some((mut t, dir)) => {
            same_settings(&t.config, &config, &dir, out)?;
            check_budget(t.iteration, budget, &dir)?;
            t.config.iterations = budget;
            say_resumed(&t, &dir);
            t
        }
        None if config.budget.is_some() => {
            let (config, plan) = plan_budget(data, &config, plugins, started)?;
            log::info!(
                "budget {:.0} s: schedule x{:.3}, {} iterations, at most {} Gaussians (a step: {:.1} ms at {} Gaussians, {:.1} ms at {}), predicted {:.0} s",
                plan.budget_seconds,
                plan.scale,
                plan.iterations,
                plan.max_gaussians,
                1e3 * plan.step_seconds[0].1,
                plan.step_seconds[0].0,
                1e3 * plan.step_seconds[1].1,
                plan.step_seconds[1].0,
                plan.predicted_seconds
            );
            let trainer = Trainer::with_plugins(data, config, plugins)?;
            std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
            write_plan(out, &plan)?;
            tail = TailControl::new(&plan, &trainer.config, started).map(|c| (c, plan));
            trainer
        }
        None => Trainer::with_plugins(data, config, plugins)?,
    };
    attach_backdrop(&mut trainer, data, out, plugins)?;
    run_trainer(trainer, out, resume, (!resume).then_some(data), tail)
}

/// A run without `data.json` (an older run, or the file removed) is checked against
/// what its newest readable checkpoint records
/// ([`maaf_scene::run_data::check_checkpoint_data`]), so other data with the same view
/// count is refused rather than resumed, and other data with another view count is
/// refused rather than started over on top of the checkpoints.
fn check_unrecorded_data(out: &Path, data: &Dataset) -> Result<(), Error> {
    if maaf_scene::run_data::recorded_data(out)?.is_some() {
        return Ok(());
    }
    let newest = checkpoints_newest_first(out)
        .into_iter()
        .find(|(dir, _)| maaf_scene::Opened::open(dir).is_ok());
    match newest {
        Some((dir, _)) => maaf_scene::run_data::check_checkpoint_data(&dir, data),
        None => Ok(()),
    }
}

/// With a background layer in the run's config ([`maaf_scene::BackdropConfig`]): trains
/// it into `RUN/backdrop` first (a run of its own with
/// [`TrainConfig::backdrop_layer`]'s settings; resumed when cut short, left as it
/// is when finished), then puts it behind `trainer` ([`Trainer::set_backdrop`]).
pub(super) fn attach_backdrop(
    trainer: &mut Trainer,
    data: &Dataset,
    out: &Path,
    plugins: &Plugins,
) -> Result<(), Error> {
    if !trainer.config.backdrop.enabled() {
        return Ok(());
    }
    let dir = out.join(BACKDROP_DIR);
    let config = trainer.config.backdrop_layer();
    let done = std::fs::read(dir.join("summary.json"))
        .ok()
        .and_then(|b| serde_json::from_slice::<RunSummary>(&b).ok())
        .is_some_and(|s| s.iterations == config.iterations);
    if !done {
        log::info!(
            "background layer: {} iterations into {}",
            config.iterations,
            dir.display()
        );
        let resume = dir.join("config.json").is_file();
        train_run_with_plugins(data, config, &dir, resume, plugins)?;
    }
    let layer = TrainedScene::load(&dir, &plugins.models)?;
    trainer.set_backdrop(layer);
    Ok(())
}

/// The exclusive lock of the run folder `out` for a training ([`maaf_io::RunLock`]).
pub(super) fn lock_run(out: &Path) -> Result<maaf_io::RunLock, Error> {
    let doing = format!("trained (pid {})", std::process::id());
    maaf_io::RunLock::exclusive(out, &doing).map_err(|e| Error::Input(e.to_string()))
}

/// Refuses to resume a checkpoint past the iteration budget: it would report more
/// iterations than the budget and record a budget below what was trained.
fn check_budget(iteration: usize, budget: usize, dir: &Path) -> Result<(), Error> {
    if iteration > budget {
        return Err(Error::Input(format!(
            "{}: the run has trained {iteration} iterations, past the budget of {budget}; resume with a budget of at least {iteration} iterations",
            dir.display()
        )));
    }
    Ok(())
}

/// [`train_run`] for a trainer the caller built ([`Trainer::with_model`] for a
/// representation of its own, custom terms pushed onto [`Trainer::objective`]): the
/// library's run entry point for research code. With `resume`, the newest complete
/// checkpoint of `out` is restored into `trainer` ([`Trainer::restore`]), which keeps
/// its objective and its iteration budget: build the trainer exactly as when the run
/// started, so custom terms are re-supplied. Refuses a resume whose objective differs
/// from the one `log.csv` was written with, and a trainer whose objective lacks terms
/// its config names ([`crate::loss::Objective::unregistered`]: one loaded by
/// [`super::load_checkpoint`] for rendering).
pub fn train_run_with(mut trainer: Trainer, out: &Path, resume: bool) -> Result<RunSummary, Error> {
    let _lock = lock_run(out)?;
    if let Some(name) = trainer.objective.unregistered().first() {
        return Err(Error::Input(format!(
            "{}: the trainer's objective lacks the term `{name}` its config names (load it with load_checkpoint_with_plugins)",
            out.display()
        )));
    }
    repair_run_dir(out)?;
    if resume {
        let budget = trainer.config.iterations;
        if let Some(((), dir)) = load_newest(out, |dir| trainer.restore(dir)) {
            check_budget(trainer.iteration, budget, &dir)?;
            trainer.config.iterations = budget;
            say_resumed(&trainer, &dir);
        }
    }
    run_trainer(trainer, out, resume, None, None)
}

fn say_resumed(trainer: &Trainer, dir: &Path) {
    log::info!(
        "resuming from {} (iteration {} of {})",
        dir.display(),
        trainer.iteration,
        trainer.config.iterations
    );
}

/// `RUN/<file>` as pretty JSON, atomically.
fn write_json(run: &Path, file: &str, value: &impl Serialize) -> Result<(), Error> {
    let json = serde_json::to_vec_pretty(value).map_err(|e| Error::Input(e.to_string()))?;
    write_atomic(&run.join(file), &json)
}

/// `RUN/config.json`.
fn write_config(out: &Path, config: &TrainConfig) -> Result<(), Error> {
    write_json(out, "config.json", config)
}

/// `RUN/budget.json`.
fn write_plan(out: &Path, plan: &BudgetPlan) -> Result<(), Error> {
    write_json(out, BUDGET_FILE, plan)
}

/// Trains `trainer` into `out` to its budget. `record` is the data set of a new run
/// (or branch), recorded as `RUN/data.json` once every check has passed, so a
/// refused start writes nothing into the run folder. With `tail` (a new run with a
/// wall-clock budget) the iteration count is set again when densification ends, and
/// `config.json` and `budget.json` rewritten.
pub(super) fn run_trainer(
    mut trainer: Trainer,
    out: &Path,
    resume: bool,
    record: Option<&Dataset>,
    mut tail: Option<(TailControl, BudgetPlan)>,
) -> Result<RunSummary, Error> {
    if trainer.config.backdrop.enabled() && trainer.backdrop().is_none() {
        return Err(Error::Input(format!(
            "{}: the config has a background layer but the trainer none (train_run and branch_run train it; with train_run_with call Trainer::set_backdrop first)",
            out.display()
        )));
    }
    trainer.check_memory(trainer.num_gaussians())?;
    for warning in trainer.config.schedule_warnings() {
        log::warn!("{}: {warning}", out.display());
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    if let Some(data) = record {
        maaf_scene::run_data::record_data(out, data)?;
    }
    let model_dir = out.join("model");
    write_config(out, &trainer.config)?;
    let log_path = out.join("log.csv");
    let current = LogLayout::of(&trainer.objective);
    let layout = if resume {
        let old = current.unweighted();
        let headers = [current.header(), old.header()];
        if truncate_log(&log_path, &headers, trainer.iteration)? == 0 {
            current
        } else {
            log::info!("log.csv predates the weighted-term columns: appending in its layout");
            old
        }
    } else {
        write_atomic(&log_path, &csv_line(&current.header())?)?;
        current
    };
    let file = std::fs::OpenOptions::new()
        .append(true)
        .open(&log_path)
        .map_err(|e| Error::io(&log_path, e))?;
    let mut best = if trainer.config.keep_best {
        Some(BestSoFar::resume(out, &log_path)?)
    } else {
        None
    };
    let mut log = csv::Writer::from_writer(file);
    let log_error = |e: csv::Error| Error::Input(format!("{}: {e}", log_path.display()));
    let mut total = trainer.config.iterations;
    // The bar names the run, so a sequence of trainings (the demo, a suite) says which
    // one is running; progress is info, hidden by `maaf -q`.
    let name = run_name(out);
    let bar = if log::log_enabled!(log::Level::Info) {
        indicatif::ProgressBar::new(total as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_position(trainer.iteration as u64);
    bar.set_prefix(name.clone());
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} {bar:30} {pos}/{len} [{elapsed_precise}<{eta_precise}] {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let before = trainer.timings.total();
    let mut val_seconds = 0.0;
    let ckpt_every = trainer.config.checkpoint_every.max(1);
    while trainer.iteration < total {
        trainer.update();
        let it = trainer.iteration;
        // Validation renders the model this iteration trained, before the schedule
        // densifies or resets opacities (after a reset it would read ~13 dB); its
        // time is not training time and is left out of `elapsed`.
        let val_every = trainer.config.val_every;
        let val = if val_every > 0 && (it.is_multiple_of(val_every) || it == total) {
            let t0 = Instant::now();
            let psnr = trainer.validation_psnr();
            val_seconds += t0.elapsed().as_secs_f64();
            psnr.map_or(String::new(), |p| format!("{p:.4}"))
        } else {
            String::new()
        };
        if let Some(best) = &mut best
            && best.offer(it, &val)
        {
            save_checkpoint(&trainer, best.dir())?;
        }
        trainer.schedule();
        trainer.check_health()?;
        let loss = trainer
            .last_terms
            .iter()
            .find(|(n, _)| n == "total")
            .map_or(f64::NAN, |(_, v)| *v);
        if it.is_multiple_of(trainer.config.log_every.max(1)) || it == total {
            let elapsed = before + start.elapsed().as_secs_f64() - val_seconds;
            let stats = RowStats {
                iteration: it,
                total: loss,
                num_gaussians: trainer.num_gaussians(),
                elapsed,
                skipped: trainer.skipped_steps,
                val: &val,
            };
            log.write_record(layout.row(&trainer.last_terms, &stats))
                .and_then(|()| log.flush().map_err(csv::Error::from))
                .map_err(log_error)?;
            bar.set_message(format!(
                "loss {loss:.4}  gaussians {}",
                trainer.num_gaussians()
            ));
        }
        bar.set_position(it as u64);
        if bar.is_hidden() && (it * 10 / total.max(1)) != ((it - 1) * 10 / total.max(1)) {
            log::info!(
                "{name}: iteration {it}/{total}  loss {loss:.4}  gaussians {}",
                trainer.num_gaussians()
            );
        }
        if let Some((control, plan)) = &mut tail
            && let Some(iterations) = control.after(it)
        {
            log::info!("{name}: budget: {iterations} iterations (planned {total})");
            total = iterations;
            trainer.config.iterations = iterations;
            bar.set_length(total as u64);
            write_config(out, &trainer.config)?;
            plan.adjusted_iterations = Some(iterations);
            write_plan(out, plan)?;
        }
        if it.is_multiple_of(ckpt_every) && it < total {
            save_checkpoint(&trainer, &checkpoint_dir(out, it))?;
        }
    }
    bar.finish_and_clear();
    let chosen = best.as_ref().and_then(BestSoFar::chosen);
    match &best {
        Some(best) if chosen.is_some() => {
            save_checkpoint(&trainer, &checkpoint_dir(out, trainer.iteration))?;
            best.install(&model_dir)?;
        }
        _ => save_checkpoint(&trainer, &model_dir)?,
    }
    let summary = RunSummary {
        iterations: trainer.iteration,
        train_seconds: trainer.timings.total(),
        num_gaussians: trainer.num_gaussians(),
        skipped_steps: trainer.skipped_steps,
        last_reset: trainer.state.last_reset,
        dead_gaussians: trainer.state.liveness.dead(trainer.state.last_reset),
        dead_at_cap: trainer.state.liveness.at_cap(trainer.state.last_reset),
        timings: trainer.timings.clone(),
        test_psnr: None,
        chosen,
        failure: None,
    };
    summary.write(out)?;
    Ok(summary)
}

/// How progress lines name the run in `out`: its folder and the folder above it
/// (`runs/motion`), as a sequence of runs tells them apart.
fn run_name(out: &Path) -> String {
    let parts: Vec<String> = out
        .components()
        .rev()
        .filter_map(|c| match c {
            std::path::Component::Normal(p) => Some(p.to_string_lossy().into_owned()),
            _ => None,
        })
        .take(2)
        .collect();
    parts.into_iter().rev().collect::<Vec<_>>().join("/")
}

/// `RUN/checkpoints/iter_NNNNNN`.
pub fn checkpoint_dir(run: &Path, iteration: usize) -> PathBuf {
    run.join("checkpoints").join(format!("iter_{iteration:06}"))
}
