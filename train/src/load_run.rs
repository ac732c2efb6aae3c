//! Loading a trained run back into a [`Trainer`] on its data set, for what continues
//! stepping it (`maaf bench`); evaluation and rendering load a
//! [`maaf_scene::TrainedScene`] instead (`maaf_eval::load_scene_on`).

use std::path::Path;

use maaf_data::{Dataset, Split};
use maaf_scene::model_dir;
use maaf_scene::run_data::{DataFingerprint, recorded_data};

use crate::trainer::{Trainer, load_checkpoint_with_plugins};
use crate::{Error, Plugins};

/// Loads the trained model of `run` (`RUN/model/`) into a [`Trainer`] on `data`, for
/// what continues training it (`maaf bench`); evaluation and rendering load a
/// [`maaf_scene::TrainedScene`] instead. One-line errors for a missing run or model and for a
/// data set that does not match the run (different number of training views,
/// different image size when `RUN/data.json` records it, or a training scale the
/// images cannot be downsampled to). The run's terms, representation, filter and
/// strategy must be registered in `plugins` (a program's own: `maaf::cli::Maaf`), or
/// the error names the one missing.
pub fn load_run(run: &Path, data: &Dataset, plugins: &Plugins) -> Result<Trainer, Error> {
    let model = model_dir(run)?;
    if let Some(rec) = recorded_data(run)? {
        rec.check(&DataFingerprint::of(data)?, run)?;
    }
    load_checkpoint_with_plugins(data, &model, plugins).map_err(|e| {
        let msg = e.to_string();
        if msg.contains("different data set") {
            Error::Input(format!(
                "{}: does not match the run {} (it was trained on a different number of training views; this data set has {})",
                data.root().display(),
                run.display(),
                data.len(Split::Train)
            ))
        } else {
            Error::Input(format!("{}: cannot load the model: {msg}", run.display()))
        }
    })
}
