//! Checkpoints: a folder holding `tensors.safetensors` (parameters, Adam moments,
//! densification statistics, f/d observations) and `state.json` (iteration, counters,
//! configuration, filter state). Written to a temporary folder and renamed into place,
//! so a crash never leaves a half-written checkpoint.

use std::collections::HashMap;
use std::path::Path;

use maaf_autodiff::Tensor;
use maaf_autodiff::optim::Moments;
use maaf_filter::FilterState;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use serde::{Deserialize, Serialize};

use super::{Timings, TrainConfig, TrainError, Trainer, io};
use crate::data::Dataset;

/// Non-tensor state of a run.
#[derive(Serialize, Deserialize)]
struct State {
    iteration: usize,
    skipped_steps: usize,
    last_reset: Option<usize>,
    num_gaussians: usize,
    config: TrainConfig,
    filter: FilterState,
    timings: Timings,
    adam_steps: HashMap<String, u64>,
}

fn bytes_of(data: &[f32]) -> Vec<u8> {
    data.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Writes the trainer's full state to the folder `dir` atomically (temp folder, then
/// rename; an existing `dir` is replaced only after the new one is complete).
pub fn save_checkpoint(trainer: &mut Trainer, dir: &Path) -> Result<(), TrainError> {
    let mut named: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
    let mut adam_steps = HashMap::new();
    let mut names = Vec::new();
    for slot in trainer.model.params_mut() {
        named.push((
            format!("param/{}", slot.name),
            slot.value.shape().to_vec(),
            bytes_of(slot.value.data()),
        ));
        names.push(slot.name.clone());
    }
    for name in names {
        if let Some(m) = trainer.adam.moments(&name) {
            named.push((
                format!("adam_m/{name}"),
                m.m.shape().to_vec(),
                bytes_of(m.m.data()),
            ));
            named.push((
                format!("adam_v/{name}"),
                m.v.shape().to_vec(),
                bytes_of(m.v.data()),
            ));
            adam_steps.insert(name, m.steps);
        }
    }
    let n = trainer.num_gaussians();
    let s = &trainer.stats;
    named.push(("stats/grad_accum".into(), vec![n], bytes_of(&s.grad_accum)));
    named.push(("stats/denom".into(), vec![n], bytes_of(&s.denom)));
    named.push(("stats/max_radii".into(), vec![n], bytes_of(&s.max_radii)));
    let f = trainer.observations.num_frames();
    let obs: Vec<f32> = (0..n)
        .flat_map(|i| trainer.observations.row(i).to_vec())
        .collect();
    named.push(("observations".into(), vec![n, f], bytes_of(&obs)));
    let views: Vec<(String, TensorView<'_>)> = named
        .iter()
        .map(|(name, shape, bytes)| {
            TensorView::new(Dtype::F32, shape.clone(), bytes)
                .map(|v| (name.clone(), v))
                .map_err(|e| TrainError::Input(format!("checkpoint tensor {name}: {e}")))
        })
        .collect::<Result<_, _>>()?;
    let blob = safetensors::serialize(views, None)
        .map_err(|e| TrainError::Input(format!("checkpoint serialisation: {e}")))?;
    let state = State {
        iteration: trainer.iteration,
        skipped_steps: trainer.skipped_steps,
        last_reset: trainer.last_reset,
        num_gaussians: n,
        config: trainer.config.clone(),
        filter: trainer.filter.clone(),
        timings: trainer.timings.clone(),
        adam_steps,
    };
    let json = serde_json::to_vec(&state)
        .map_err(|e| TrainError::Input(format!("checkpoint state: {e}")))?;
    let parent = dir.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(io(parent))?;
    let name = dir
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "checkpoint".into());
    let tmp = parent.join(format!(".{name}.tmp"));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(io(&tmp))?;
    }
    std::fs::create_dir_all(&tmp).map_err(io(&tmp))?;
    std::fs::write(tmp.join("tensors.safetensors"), blob).map_err(io(&tmp))?;
    std::fs::write(tmp.join("state.json"), json).map_err(io(&tmp))?;
    let old = parent.join(format!(".{name}.old"));
    if dir.exists() {
        if old.exists() {
            std::fs::remove_dir_all(&old).map_err(io(&old))?;
        }
        std::fs::rename(dir, &old).map_err(io(dir))?;
    }
    std::fs::rename(&tmp, dir).map_err(io(dir))?;
    if old.exists() {
        std::fs::remove_dir_all(&old).map_err(io(&old))?;
    }
    Ok(())
}

fn tensor(st: &SafeTensors<'_>, name: &str, file: &Path) -> Result<Tensor<f32>, TrainError> {
    let view = st
        .tensor(name)
        .map_err(|e| TrainError::Input(format!("{}: tensor `{name}`: {e}", file.display())))?;
    if view.dtype() != Dtype::F32 {
        return Err(TrainError::Input(format!(
            "{}: tensor `{name}` is not f32",
            file.display()
        )));
    }
    let data: Vec<f32> = view
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Ok(Tensor::from_vec(data, view.shape()))
}

/// Restores a trainer from a checkpoint folder written by [`save_checkpoint`], on the
/// same data set. Errors name the file and the missing or malformed entry.
pub fn load_checkpoint(data: &Dataset, dir: &Path) -> Result<Trainer, TrainError> {
    let state_path = dir.join("state.json");
    let text = std::fs::read(&state_path).map_err(io(&state_path))?;
    let state: State = serde_json::from_slice(&text)
        .map_err(|e| TrainError::Input(format!("{}: {e}", state_path.display())))?;
    let blob_path = dir.join("tensors.safetensors");
    let blob = std::fs::read(&blob_path).map_err(io(&blob_path))?;
    let st = SafeTensors::deserialize(&blob)
        .map_err(|e| TrainError::Input(format!("{}: {e}", blob_path.display())))?;
    let mut trainer = Trainer::initial(data, state.config.clone())?;
    let mut names = Vec::new();
    for slot in trainer.model.params_mut() {
        *slot.value = tensor(&st, &format!("param/{}", slot.name), &blob_path)?;
        names.push(slot.name.clone());
    }
    if trainer.model.num_gaussians() != state.num_gaussians {
        return Err(TrainError::Input(format!(
            "{}: {} Gaussians in the parameters, state.json says {}",
            dir.display(),
            trainer.model.num_gaussians(),
            state.num_gaussians
        )));
    }
    for name in names {
        if let Some(&steps) = state.adam_steps.get(&name) {
            let m = tensor(&st, &format!("adam_m/{name}"), &blob_path)?;
            let v = tensor(&st, &format!("adam_v/{name}"), &blob_path)?;
            trainer.adam.set_moments(&name, Moments { m, v, steps });
        }
    }
    let n = state.num_gaussians;
    trainer.stats.grad_accum = tensor(&st, "stats/grad_accum", &blob_path)?.into_vec();
    trainer.stats.denom = tensor(&st, "stats/denom", &blob_path)?.into_vec();
    trainer.stats.max_radii = tensor(&st, "stats/max_radii", &blob_path)?.into_vec();
    let obs = tensor(&st, "observations", &blob_path)?;
    let f = trainer.observations.num_frames();
    if obs.shape() != [n, f] {
        return Err(TrainError::Input(format!(
            "{}: observations have shape {:?}, expected [{n}, {f}] (different data set?)",
            blob_path.display(),
            obs.shape()
        )));
    }
    trainer.observations =
        maaf_filter::ObservationTable::new(trainer.observations.times().to_vec(), n);
    for i in 0..n {
        trainer
            .observations
            .row_mut(i)
            .copy_from_slice(&obs.data()[i * f..(i + 1) * f]);
    }
    trainer.filter = state.filter;
    trainer.iteration = state.iteration;
    // The stage (e.g. SaRO-GS's static warm-up) follows the iteration; without this a
    // loaded run would render its canonical, undeformed Gaussians.
    trainer.model.set_iteration(state.iteration);
    trainer.skipped_steps = state.skipped_steps;
    trainer.last_reset = state.last_reset;
    trainer.timings = state.timings;
    Ok(trainer)
}
