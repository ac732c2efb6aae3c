//! Checkpoints: a folder holding `tensors.safetensors` (the parameter store as
//! `param/{name}`, Adam moments, the representation's buffers, densification
//! statistics, the liveness record, f/d observations, the scene record
//! [`maaf_scene::SceneRecord`] as `scene/*`) and
//! `state.json` (model name, iteration, counters, configuration, filter state, and
//! the CRC-32 of the tensors file, checked on every load).
//! Built under a temporary name and swapped in by [`maaf_io::replace_dir`], so a
//! crash never leaves a half-written checkpoint.

use std::collections::HashMap;
use std::path::Path;

use maaf_autodiff::Tensor;
use maaf_autodiff::optim::Moments;
use safetensors::{Dtype, tensor::TensorView};

use super::{DensifyStats, Liveness, Trainer};
use crate::data::Dataset;
use crate::{Error, Plugins};
use maaf_models::params::Rows;
use maaf_scene::checkpoint_read::{BUFFER, Opened, State, bytes_of, tensor};

/// Per Gaussian (u32), the last iteration with an opacity gradient
/// ([`super::Liveness`]); absent in checkpoints written before it existed.
const LAST_GRAD: &str = "liveness/last_grad";
/// Per Gaussian, 1 where the last opacity reset lowered the opacity, else 0.
const LOWERED: &str = "liveness/lowered";

/// Writes the trainer's full state to the folder `dir` atomically (temp folder, then
/// swap; an existing `dir` stays readable until the new one is complete).
pub fn save_checkpoint(trainer: &Trainer, dir: &Path) -> Result<(), Error> {
    let mut named: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
    let mut adam_steps = HashMap::new();
    let colour = trainer.camera_colour.as_ref().map(|c| c.params());
    let stores = std::iter::once(trainer.state.model.params()).chain(colour);
    for (name, value) in stores.flat_map(|s| s.named_tensors()) {
        named.push((
            format!("param/{name}"),
            value.shape().to_vec(),
            bytes_of(value.data()),
        ));
        if let Some(m) = trainer.state.adam.moments(name) {
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
            adam_steps.insert(name.to_string(), m.steps);
        }
    }
    let buffers = trainer
        .state
        .model
        .hooks()
        .map_or_else(Vec::new, |h| h.buffers());
    for (name, value) in buffers {
        named.push((
            format!("{BUFFER}{name}"),
            value.shape().to_vec(),
            bytes_of(value.data()),
        ));
    }
    let n = trainer.num_gaussians();
    let s = &trainer.state.stats;
    named.push(("stats/grad_accum".into(), vec![n], bytes_of(&s.grad_accum)));
    named.push(("stats/denom".into(), vec![n], bytes_of(&s.denom)));
    named.push(("stats/max_radii".into(), vec![n], bytes_of(&s.max_radii)));
    let live = &trainer.state.liveness;
    let lowered: Vec<f32> = live
        .lowered
        .iter()
        .map(|&l| f32::from(u8::from(l)))
        .collect();
    named.push((LOWERED.into(), vec![n], bytes_of(&lowered)));
    let f = trainer.state.observations.num_frames();
    if f > 0 {
        let obs: Vec<u8> = (0..n)
            .flat_map(|i| trainer.state.observations.row(i))
            .flat_map(|v| v.to_le_bytes())
            .collect();
        named.push(("observations".into(), vec![n, f], obs));
    }
    let scene = trainer.scene_record().to_tensors();
    let mut views: Vec<(String, TensorView<'_>)> = named
        .iter()
        .map(|(name, shape, bytes)| {
            TensorView::new(Dtype::F32, shape.clone(), bytes)
                .map(|v| (name.clone(), v))
                .map_err(|e| Error::Input(format!("checkpoint tensor {name}: {e}")))
        })
        .collect::<Result<_, _>>()?;
    let last_grad: Vec<u8> = live
        .last_grad
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    views.push((
        LAST_GRAD.into(),
        TensorView::new(Dtype::U32, vec![n], &last_grad)
            .map_err(|e| Error::Input(format!("checkpoint tensor {LAST_GRAD}: {e}")))?,
    ));
    for (name, dtype, shape, bytes) in &scene {
        views.push((
            name.clone(),
            TensorView::new(*dtype, shape.clone(), bytes)
                .map_err(|e| Error::Input(format!("checkpoint tensor {name}: {e}")))?,
        ));
    }
    let blob = safetensors::serialize(views, None)
        .map_err(|e| Error::Input(format!("checkpoint serialisation: {e}")))?;
    let state = State {
        model: trainer.state.model.name().to_string(),
        iteration: trainer.iteration,
        skipped_steps: trainer.skipped_steps,
        last_reset: trainer.state.last_reset,
        num_gaussians: n,
        config: trainer.config.clone(),
        filter: trainer.state.filter.clone(),
        timings: trainer.timings.clone(),
        adam_steps,
        strategy: trainer.strategy_state(),
        tensors_crc32: Some(format!("{:08x}", crc32fast::hash(&blob))),
        smooths: Some(trainer.sampling_filter().smooths()),
    };
    let json =
        serde_json::to_vec(&state).map_err(|e| Error::Input(format!("checkpoint state: {e}")))?;
    let parent = maaf_io::parent_of(dir);
    std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
    let tmp = maaf_io::temp_sibling(dir);
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    }
    let written = (|| {
        std::fs::create_dir_all(&tmp)?;
        maaf_io::write_atomic(&tmp.join("tensors.safetensors"), &blob)?;
        maaf_io::write_atomic(&tmp.join("state.json"), &json)?;
        maaf_io::replace_dir(&tmp, dir)
    })();
    written.map_err(|e| {
        let _ = std::fs::remove_dir_all(&tmp);
        Error::io(dir, e)
    })
}

/// The iteration a checkpoint folder holds (from its `state.json`), or an error
/// naming the file when it is missing or malformed.
pub fn checkpoint_iteration(dir: &Path) -> Result<usize, Error> {
    Opened::read_state(dir).map(|s| s.iteration)
}

/// Restores a trainer of the built-in representation, filter and strategy the run's
/// config names from a
/// checkpoint folder written by [`save_checkpoint`], on the same data set, for
/// rendering and evaluation: a term of the run's `config.terms` that is not built in
/// is left out of its objective ([`crate::loss::Objective::unregistered`]), and
/// [`super::train_run_with`] refuses to train it; to continue training, load with
/// [`load_checkpoint_with_plugins`]. Errors name the file and the missing or
/// malformed entry.
pub fn load_checkpoint(data: &Dataset, dir: &Path) -> Result<Trainer, Error> {
    let state = Opened::read_state(dir)?;
    let mut trainer = Trainer::from_config(data, state.config.clone(), &Plugins::builtin())?;
    trainer.restore_state(dir, state, false)?;
    Ok(trainer)
}

/// [`load_checkpoint`] with the registries of `plugins`, to continue training: every
/// term, the representation, the filter and the strategy the run's config names
/// must be registered there ([`Plugins::check`]: one line naming what is not, and
/// the checkpoint's `state.json`); the strategy's own state is restored.
pub fn load_checkpoint_with_plugins(
    data: &Dataset,
    dir: &Path,
    plugins: &Plugins,
) -> Result<Trainer, Error> {
    let state = Opened::read_state(dir)?;
    let what = dir.join("state.json").display().to_string();
    plugins.check(&state.config, &what)?;
    let mut trainer = Trainer::from_config(data, state.config.clone(), plugins)?;
    trainer.restore_state(dir, state, false)?;
    Ok(trainer)
}

impl Trainer {
    /// Loads a checkpoint into this trainer (built by [`Trainer::new`] or
    /// [`Trainer::with_model`] on the same data set, with the same kind of
    /// representation): parameters (any Gaussian count), Adam moments, statistics,
    /// observations, filter, iteration, counters and the run's configuration. The
    /// trainer's objective is kept, so custom terms are re-supplied by building the
    /// trainer the same way as the first time.
    pub fn restore(&mut self, dir: &Path) -> Result<(), Error> {
        let state = Opened::read_state(dir)?;
        self.restore_state(dir, state, false).map(drop)
    }

    /// Starts this trainer, built with a branch's own configuration, from another
    /// run's checkpoint: everything [`Self::restore`] loads except the configuration,
    /// which stays this trainer's, so a run continues from a shared prefix with
    /// changed late-stage settings (GroupFlow from its fitting iteration, another
    /// pruning or densification schedule, a longer budget). Shared parameters the
    /// checkpoint lacks (a stage the first run never had, e.g. GroupFlow's node
    /// offsets) keep their initial values and zero Adam moments; their names are
    /// returned. Refused when the representation, the filter kind or the training
    /// scale differ: the restored filter state and observations belong to those.
    pub fn branch_from(&mut self, dir: &Path) -> Result<Vec<String>, Error> {
        let state = Opened::read_state(dir)?;
        let (ours, theirs) = (&self.config, &state.config);
        if ours.filter.kind != theirs.filter.kind || ours.train_scale != theirs.train_scale {
            return Err(Error::Input(format!(
                "{}: a branch keeps the checkpoint's filter kind and training scale ({} at {}), not {} at {}",
                dir.display(),
                theirs.filter.kind.name(),
                theirs.train_scale,
                ours.filter.kind.name(),
                ours.train_scale
            )));
        }
        self.restore_state(dir, state, true)
    }

    /// [`Self::restore`], and with `branch` [`Self::branch_from`]'s leniency and its
    /// own configuration kept: returns the shared parameters that kept their values
    /// (none without `branch`).
    fn restore_state(
        &mut self,
        dir: &Path,
        state: State,
        branch: bool,
    ) -> Result<Vec<String>, Error> {
        if state.model != self.state.model.name() {
            return Err(Error::Input(format!(
                "{}: holds a `{}` model but the trainer was built with `{}` (build the trainer with the same representation)",
                dir.display(),
                state.model,
                self.state.model.name()
            )));
        }
        let opened = Opened::with_state(dir, state)?;
        let st = opened.tensors()?;
        let blob_path = &opened.blob_path;
        // A branch's shared parameters that the checkpoint lacks keep their values.
        let kept: HashMap<String, Tensor<f32>> = self
            .state
            .model
            .params()
            .iter()
            .filter(|p| branch && p.rows == Rows::Shared)
            .filter(|p| st.tensor(&format!("param/{}", p.name)).is_err())
            .map(|p| (p.name.clone(), p.value.clone()))
            .collect();
        let mut fresh: Vec<String> = kept.keys().cloned().collect();
        fresh.sort_unstable();
        opened.load_model(self.state.model.as_mut(), dir, kept)?;
        if let Some(correction) = self.camera_colour.as_mut() {
            for p in correction.params_mut().iter_mut() {
                let key = format!("param/{}", p.name);
                // A branch onto a run without corrections starts them at the identity.
                if branch && st.tensor(&key).is_err() {
                    continue;
                }
                let value = tensor(&st, &key, blob_path)?;
                if value.shape() != p.value.shape() {
                    return Err(Error::Input(format!(
                        "{}: `param/{}` has shape {:?}, the run's training cameras need {:?}",
                        blob_path.display(),
                        p.name,
                        value.shape(),
                        p.value.shape()
                    )));
                }
                p.value = value;
            }
        }
        let n = opened.state.num_gaussians;
        let colour_names = self
            .camera_colour
            .as_ref()
            .map_or_else(Vec::new, |c| c.params().names());
        for name in self
            .state
            .model
            .params()
            .names()
            .into_iter()
            .chain(colour_names)
        {
            if let Some(&steps) = opened.state.adam_steps.get(&name) {
                let m = tensor(&st, &format!("adam_m/{name}"), blob_path)?;
                let v = tensor(&st, &format!("adam_v/{name}"), blob_path)?;
                self.state.adam.set_moments(&name, Moments { m, v, steps });
            }
        }
        self.state.stats = DensifyStats {
            grad_accum: tensor(&st, "stats/grad_accum", blob_path)?.into_vec(),
            denom: tensor(&st, "stats/denom", blob_path)?.into_vec(),
            max_radii: tensor(&st, "stats/max_radii", blob_path)?.into_vec(),
        };
        self.state.liveness = if st.names().contains(&LAST_GRAD) {
            let last_grad = st
                .tensor(LAST_GRAD)
                .ok()
                .filter(|v| v.dtype() == Dtype::U32 && v.shape() == [n])
                .ok_or_else(|| {
                    Error::Input(format!(
                        "{}: tensor `{LAST_GRAD}` is not u32 of shape [{n}]",
                        blob_path.display()
                    ))
                })?;
            let lowered = tensor(&st, LOWERED, blob_path)?;
            if lowered.shape() != [n] {
                return Err(Error::Input(format!(
                    "{}: tensor `{LOWERED}` has shape {:?}, expected [{n}]",
                    blob_path.display(),
                    lowered.shape()
                )));
            }
            Liveness {
                last_grad: last_grad
                    .data()
                    .chunks_exact(4)
                    .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
                lowered: lowered.data().iter().map(|&l| l != 0.0).collect(),
            }
        } else {
            Liveness::alive_at(n, opened.state.iteration)
        };
        self.state.observations = opened.observations(&self.observed, self.observed_slot.len())?;
        drop(st);
        let state = opened.state;
        self.state.filter = state.filter;
        self.filter_ready = true;
        self.iteration = state.iteration;
        self.skipped_steps = state.skipped_steps;
        self.state.last_reset = state.last_reset;
        self.timings = state.timings;
        if !branch {
            self.config = state.config;
        }
        self.load_strategy_state(&state.strategy)
            .map_err(|e| Error::Input(format!("{}: {e}", dir.join("state.json").display())))?;
        Ok(fresh)
    }
}
