//! A new run that starts from another run's checkpoint with settings of its own
//! (`maaf train --from`).

use std::path::Path;

use super::run::{RunSummary, attach_backdrop, lock_run, run_trainer};
use super::{TrainConfig, Trainer};
use crate::data::Dataset;
use crate::{Error, Plugins};

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
    branch_run_with_plugins(data, config, out, from, &Plugins::builtin(), false)
}

/// [`branch_run`] with the registries of `plugins` ([`train_run_with_plugins`]).
/// Unless `other_data`, `data` must be the data set the checkpoint was trained on
/// ([`maaf_scene::run_data::check_checkpoint_data`]: its run's `data.json`, else its
/// scene record); `other_data` branches onto another data set on purpose.
pub fn branch_run_with_plugins(
    data: &Dataset,
    config: TrainConfig,
    out: &Path,
    from: &Path,
    plugins: &Plugins,
    other_data: bool,
) -> Result<RunSummary, Error> {
    let _lock = lock_run(out)?;
    if !other_data {
        maaf_scene::run_data::check_checkpoint_data(from, data).map_err(|e| match e {
            Error::Input(m) => {
                Error::Input(format!("{m} (to branch onto it on purpose: --other-data)"))
            }
            other => other,
        })?;
    }
    let mut trainer = Trainer::with_plugins(data, config, plugins)?;
    let fresh = trainer.branch_from(from)?;
    attach_backdrop(&mut trainer, data, out, plugins)?;
    if trainer.iteration >= trainer.config.iterations {
        return Err(Error::Input(format!(
            "{}: the checkpoint is at iteration {}, so a branch from it needs a budget above {} iterations (this one is {})",
            from.display(),
            trainer.iteration,
            trainer.iteration,
            trainer.config.iterations
        )));
    }
    log::info!(
        "branching from {} at iteration {} of {}{}",
        from.display(),
        trainer.iteration,
        trainer.config.iterations,
        if fresh.is_empty() {
            String::new()
        } else {
            format!(" (starting fresh: {})", fresh.join(", "))
        }
    );
    run_trainer(trainer, out, false, Some(data), None)
}
