//! A whole training run in a run directory: `config.json`, `log.csv`, checkpoints
//! under `checkpoints/`, the final model in `model/`, and `summary.json`; resumable
//! from the newest complete checkpoint (`resume.rs`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::{
    Timings, TrainConfig, Trainer, load_checkpoint, load_newest, log_line, repair_run_dir,
    save_checkpoint, truncate_log,
};
use crate::data::Dataset;
use crate::{Error, write_atomic};

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
    /// Time per phase.
    pub timings: Timings,
}

/// Trains on `data` into `out` (created if needed) with the representation
/// `config.model` describes. With `resume`, the run in `out` continues from its
/// newest complete checkpoint (`checkpoints/iter_N` or `model/`, whatever stopped the
/// run; the checkpoint's settings apply, except the iteration budget
/// `config.iterations`), or starts over with `config` if it has none yet. A resumed
/// run is bit-identical to an uninterrupted one with the same seed and thread count.
/// Prints a progress bar on a terminal and a line every 10% otherwise.
pub fn train_run(
    data: &Dataset,
    config: TrainConfig,
    out: &Path,
    resume: bool,
) -> Result<RunSummary, Error> {
    repair_run_dir(out)?;
    let budget = config.iterations;
    let found = if resume {
        load_newest(out, |dir| load_checkpoint(data, dir))
    } else {
        None
    };
    let trainer = match found {
        Some((mut t, dir)) => {
            t.config.iterations = budget;
            say_resumed(&t, &dir);
            t
        }
        None => Trainer::new(data, config)?,
    };
    run_trainer(trainer, out, resume)
}

/// A new run in `out` that starts from another run's checkpoint folder `from`
/// (`RUN/checkpoints/iter_N` or `RUN/model`) with `config`, its own settings
/// ([`Trainer::branch_from`]): iteration, parameters, Adam moments, statistics,
/// observations, filter state and the training time so far come from the
/// checkpoint; `log.csv` starts at the branch iteration. Two branches of one
/// checkpoint share their first iterations bit for bit, so a late-stage option is
/// compared without training the prefix twice.
pub fn branch_run(
    data: &Dataset,
    config: TrainConfig,
    out: &Path,
    from: &Path,
) -> Result<RunSummary, Error> {
    let mut trainer = Trainer::new(data, config)?;
    let fresh = trainer.branch_from(from)?;
    log_line(&format!(
        "branching from {} at iteration {} of {}{}",
        from.display(),
        trainer.iteration,
        trainer.config.iterations,
        if fresh.is_empty() {
            String::new()
        } else {
            format!(" (starting fresh: {})", fresh.join(", "))
        }
    ));
    run_trainer(trainer, out, false)
}

/// [`train_run`] for a trainer the caller built ([`Trainer::with_model`] for a
/// representation of its own, custom terms pushed onto [`Trainer::objective`]): the
/// library's run entry point for research code. With `resume`, the newest complete
/// checkpoint of `out` is restored into `trainer` ([`Trainer::restore`]), which keeps
/// its objective and its iteration budget: build the trainer exactly as for the first
/// session, so custom terms are re-supplied. Refuses a resume whose objective differs
/// from the one `log.csv` was written with.
pub fn train_run_with(mut trainer: Trainer, out: &Path, resume: bool) -> Result<RunSummary, Error> {
    repair_run_dir(out)?;
    if resume {
        let budget = trainer.config.iterations;
        if let Some(((), dir)) = load_newest(out, |dir| trainer.restore(dir)) {
            trainer.config.iterations = budget;
            say_resumed(&trainer, &dir);
        }
    }
    run_trainer(trainer, out, resume)
}

fn say_resumed(trainer: &Trainer, dir: &Path) {
    log_line(&format!(
        "resuming from {} (iteration {} of {})",
        dir.display(),
        trainer.iteration,
        trainer.config.iterations
    ));
}

/// The header of `log.csv` for `trainer`'s objective.
fn log_header(trainer: &Trainer) -> String {
    let mut header = String::from("iteration");
    for name in trainer.objective.names() {
        header.push(',');
        header.push_str(&name);
    }
    header.push_str(",total,num_gaussians,elapsed_seconds,skipped_steps,val_psnr");
    header
}

fn run_trainer(mut trainer: Trainer, out: &Path, resume: bool) -> Result<RunSummary, Error> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let model_dir = out.join("model");
    let config_json =
        serde_json::to_vec_pretty(&trainer.config).map_err(|e| Error::Input(e.to_string()))?;
    write_atomic(&out.join("config.json"), &config_json)?;
    let log_path = out.join("log.csv");
    let header = log_header(&trainer);
    if resume {
        truncate_log(&log_path, &header, trainer.iteration)?;
    } else {
        write_atomic(&log_path, format!("{header}\n").as_bytes())?;
    }
    let mut log = std::fs::OpenOptions::new()
        .append(true)
        .open(&log_path)
        .map_err(|e| Error::io(&log_path, e))?;
    let total = trainer.config.iterations;
    let bar = indicatif::ProgressBar::new(total as u64);
    bar.set_position(trainer.iteration as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:30} {pos}/{len} [{elapsed_precise}<{eta_precise}] {msg}",
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
        trainer.schedule();
        trainer.check_health()?;
        let loss = trainer
            .last_terms
            .iter()
            .find(|(n, _)| n == "total")
            .map_or(f64::NAN, |(_, v)| *v);
        if it.is_multiple_of(trainer.config.log_every.max(1)) || it == total {
            let mut row = it.to_string();
            for name in trainer.objective.names() {
                let v = trainer
                    .last_terms
                    .iter()
                    .find(|(n, _)| *n == name)
                    .map_or(f64::NAN, |(_, v)| *v);
                row.push_str(&format!(",{v:.6e}"));
            }
            let elapsed = before + start.elapsed().as_secs_f64() - val_seconds;
            row.push_str(&format!(
                ",{loss:.6e},{},{elapsed:.3},{},{val}\n",
                trainer.num_gaussians(),
                trainer.skipped_steps
            ));
            log.write_all(row.as_bytes())
                .map_err(|e| Error::io(&log_path, e))?;
            bar.set_message(format!(
                "loss {loss:.4}  gaussians {}",
                trainer.num_gaussians()
            ));
        }
        bar.set_position(it as u64);
        if bar.is_hidden() && (it * 10 / total.max(1)) != ((it - 1) * 10 / total.max(1)) {
            eprintln!(
                "maaf: iteration {it}/{total}  loss {loss:.4}  gaussians {}",
                trainer.num_gaussians()
            );
        }
        if it.is_multiple_of(ckpt_every) && it < total {
            save_checkpoint(&trainer, &checkpoint_dir(out, it))?;
        }
    }
    bar.finish_and_clear();
    save_checkpoint(&trainer, &model_dir)?;
    let summary = RunSummary {
        iterations: trainer.iteration,
        train_seconds: trainer.timings.total(),
        num_gaussians: trainer.num_gaussians(),
        skipped_steps: trainer.skipped_steps,
        timings: trainer.timings.clone(),
    };
    let json = serde_json::to_vec_pretty(&summary).map_err(|e| Error::Input(e.to_string()))?;
    write_atomic(&out.join("summary.json"), &json)?;
    Ok(summary)
}

/// `RUN/checkpoints/iter_NNNNNN`.
pub fn checkpoint_dir(run: &Path, iteration: usize) -> PathBuf {
    run.join("checkpoints").join(format!("iter_{iteration:06}"))
}
