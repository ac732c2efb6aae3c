//! Reading a checkpoint folder written by `maaf_train::trainer::save_checkpoint`: its state, the
//! tensors file checked against the recorded CRC-32, the representation's parameters
//! and buffers, the f/d observations and the scene record. The one reader behind
//! both `maaf_train::trainer::Trainer::restore` and [`crate::TrainedScene::load`], so a
//! trained scene holds exactly the model and filter state a trainer restores.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use maaf_autodiff::{PerGaussian, Tensor};
use maaf_filter::{CameraTime, FilterState, ObservationTable};
use maaf_models::Representation;
use safetensors::{Dtype, SafeTensors};
use serde::{Deserialize, Serialize};

use crate::{Error, SceneRecord, Timings, TrainConfig};

/// Non-tensor state of a run.
#[derive(Serialize, Deserialize)]
pub struct State {
    /// The representation's name: a checkpoint loads only into the same kind.
    pub model: String,
    /// Iterations completed.
    pub iteration: usize,
    /// Steps skipped because a value or gradient was not finite.
    pub skipped_steps: usize,
    /// Iteration of the last opacity reset.
    pub last_reset: Option<usize>,
    /// Number of Gaussians (rows of every per-Gaussian tensor).
    pub num_gaussians: usize,
    /// The run's configuration.
    pub config: TrainConfig,
    /// The 3D filter of every Gaussian.
    pub filter: FilterState,
    /// Wall time per training phase.
    pub timings: Timings,
    /// Adam steps taken per parameter.
    pub adam_steps: HashMap<String, u64>,
    /// The densification strategy's own state (the trainer's `Strategy::state`);
    /// absent when it keeps none, and in checkpoints written before it existed.
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub strategy: serde_json::Value,
    /// CRC-32 of `tensors.safetensors` as 8 hex digits; absent in checkpoints written
    /// before it existed (loaded unchecked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tensors_crc32: Option<String>,
    /// Whether the run's filter smoothed ([`maaf_filter::SamplingFilter::smooths`]:
    /// the 2D Mip filter instead of the 3DGS dilation), so a run is rendered as it
    /// trained without the filter's code; absent in checkpoints written before it
    /// existed ([`crate::TrainedScene::smooths`] then infers it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smooths: Option<bool>,
}

/// Prefix of the representation's buffers ([`maaf_models::TrainingHooks::buffers`]).
pub const BUFFER: &str = "buffer/";

/// `data` as little-endian bytes (a safetensors f32 payload).
pub fn bytes_of(data: &[f32]) -> Vec<u8> {
    data.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// A checkpoint folder opened for loading.
pub struct Opened {
    /// Its `state.json`.
    pub state: State,
    blob: Vec<u8>,
    /// Its `tensors.safetensors`, for messages.
    pub blob_path: PathBuf,
}

/// The f32 tensor `name` of `st`, or an error naming `file` and the tensor.
pub fn tensor(st: &SafeTensors<'_>, name: &str, file: &Path) -> Result<Tensor<f32>, Error> {
    let view = st
        .tensor(name)
        .map_err(|e| Error::Input(format!("{}: tensor `{name}`: {e}", file.display())))?;
    if view.dtype() != Dtype::F32 {
        return Err(Error::Input(format!(
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

/// The first parameter value of `model` that is not finite, as (parameter name, flat
/// index, value).
pub fn first_non_finite(model: &dyn Representation<f32>) -> Option<(String, usize, f32)> {
    model.params().named_tensors().find_map(|(name, t)| {
        t.first_non_finite()
            .map(|i| (name.to_string(), i, t.data()[i]))
    })
}

impl Opened {
    /// `DIR/state.json`, or an error naming the file. A checkpoint written before the
    /// config had `background` takes it from its scene record (the colour the run
    /// trained on), where it has one.
    pub fn read_state(dir: &Path) -> Result<State, Error> {
        let path = dir.join("state.json");
        let bad = |e: serde_json::Error| Error::Input(format!("{}: {e}", path.display()));
        let text = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        let value: serde_json::Value = serde_json::from_slice(&text).map_err(bad)?;
        let has_background = value.pointer("/config/background").is_some();
        let mut state: State = serde_json::from_value(value).map_err(bad)?;
        if !has_background {
            let blob_path = dir.join("tensors.safetensors");
            let blob = std::fs::read(&blob_path).map_err(|e| Error::io(&blob_path, e))?;
            let st = SafeTensors::deserialize(&blob)
                .map_err(|e| Error::Input(format!("{}: {e}", blob_path.display())))?;
            if let Some(record) = SceneRecord::from_tensors(&st, &blob_path)? {
                state.config.background = maaf_data::Background(record.background);
            }
        }
        Ok(state)
    }

    /// Opens `dir` with its state already read: reads the tensors file and refuses it
    /// when its CRC-32 is not the recorded one (a damaged file).
    pub fn with_state(dir: &Path, state: State) -> Result<Self, Error> {
        let blob_path = dir.join("tensors.safetensors");
        let blob = std::fs::read(&blob_path).map_err(|e| Error::io(&blob_path, e))?;
        if let Some(stored) = &state.tensors_crc32 {
            let computed = format!("{:08x}", crc32fast::hash(&blob));
            if *stored != computed {
                return Err(Error::Input(format!(
                    "{}: damaged: its CRC-32 is {computed}, state.json recorded {stored}",
                    blob_path.display()
                )));
            }
        }
        Ok(Opened {
            state,
            blob,
            blob_path,
        })
    }

    /// Opens the checkpoint folder `dir` ([`Self::read_state`], [`Self::with_state`]).
    pub fn open(dir: &Path) -> Result<Self, Error> {
        Self::with_state(dir, Self::read_state(dir)?)
    }

    /// The tensors file's contents.
    pub fn tensors(&self) -> Result<SafeTensors<'_>, Error> {
        SafeTensors::deserialize(&self.blob)
            .map_err(|e| Error::Input(format!("{}: {e}", self.blob_path.display())))
    }

    /// Loads the representation's state into `model` (built the way the run built
    /// it): every parameter (any Gaussian count; one named in `kept` keeps that value
    /// instead, for a branch), refusing non-finite values and a Gaussian count other
    /// than the state's, then the buffers around `set_iteration(iteration)`.
    pub fn load_model(
        &self,
        model: &mut dyn Representation<f32>,
        dir: &Path,
        mut kept: HashMap<String, Tensor<f32>>,
    ) -> Result<(), Error> {
        let st = self.tensors()?;
        let file = &self.blob_path;
        model
            .params_mut()
            .load(|name| match kept.remove(name) {
                Some(value) => Ok(value),
                None => tensor(&st, &format!("param/{name}"), file).map_err(|e| e.to_string()),
            })
            .map_err(|e| Error::Input(format!("{}: {e}", file.display())))?;
        if let Some((name, index, value)) = first_non_finite(model) {
            return Err(Error::Input(format!(
                "{}: parameter `{name}` is {value} at flat index {index}: the run diverged, this model cannot be used",
                file.display()
            )));
        }
        let n = self.state.num_gaussians;
        if model.rows() != n {
            return Err(Error::Input(format!(
                "{}: {} Gaussians in the parameters, state.json says {n}",
                dir.display(),
                model.rows(),
            )));
        }
        // The stage (e.g. SaRO-GS's static warm-up) follows the iteration; without this a
        // loaded run would render its canonical, undeformed Gaussians.
        // Buffers before the stage, so a stage switch that would build one (GroupFlow's
        // fit past `group_flow.at`) finds it saved instead of fitting it again, and
        // after it: `set_iteration` may recompute a buffer (SaRO's adaptive scale) from
        // the parameters, which have moved since the run computed the saved one.
        let mut buffers: Vec<&str> = st
            .names()
            .into_iter()
            .filter_map(|k| k.strip_prefix(BUFFER))
            .collect();
        buffers.sort_unstable();
        let load_buffers = |model: &mut dyn Representation<f32>| -> Result<(), Error> {
            for name in &buffers {
                let value = tensor(&st, &format!("{BUFFER}{name}"), file)?;
                let model_name = model.name().to_string();
                match model.hooks_mut() {
                    Some(hooks) => hooks.load_buffer(name, value),
                    None => Err(format!("{model_name} has no buffer `{name}`")),
                }
                .map_err(|e| Error::Input(format!("{}: {e}", file.display())))?;
            }
            Ok(())
        };
        load_buffers(model)?;
        model.set_iteration(self.state.iteration);
        load_buffers(model)
    }

    /// The f/d observations for the frames `observed` (indices into the `views`
    /// training views), or `None` when there are no frames (only the motion filter
    /// reads observations; older runs saved them for every filter: ignored). A run
    /// saved before `filter.max_views` holds every training view: its observed views'
    /// columns are read.
    pub fn observations(
        &self,
        observed: &[CameraTime],
        views: usize,
    ) -> Result<ObservationTable, Error> {
        let n = self.state.num_gaussians;
        let mut table = ObservationTable::for_frames(observed, n);
        let f = table.num_frames();
        if f == 0 {
            return Ok(table);
        }
        let st = self.tensors()?;
        let obs = tensor(&st, "observations", &self.blob_path)?;
        let columns: Vec<usize> = if obs.shape() == [n, f] {
            (0..f).collect()
        } else if obs.shape() == [n, views] {
            observed.iter().map(|o| o.camera).collect()
        } else {
            return Err(Error::Input(format!(
                "{}: observations have shape {:?}, expected [{n}, {f}] (a different data set, or another filter.max_views?)",
                self.blob_path.display(),
                obs.shape()
            )));
        };
        let width = obs.shape()[1];
        for i in 0..n {
            let row = &obs.data()[i * width..(i + 1) * width];
            for (slot, &c) in table.row_mut(i).iter_mut().zip(&columns) {
                *slot = row[c];
            }
        }
        Ok(table)
    }

    /// The checkpoint's [`SceneRecord`], `None` for one written before it existed.
    pub fn scene_record(&self) -> Result<Option<SceneRecord>, Error> {
        SceneRecord::from_tensors(&self.tensors()?, &self.blob_path)
    }
}
