//! maaf-scene: what a trained run is and how to read it, without the trainer. The
//! run's configuration ([`TrainConfig`]), the checkpoint reader ([`checkpoint_read`],
//! the one reader behind the trainer's restore and [`TrainedScene::load`]), what a
//! run starts from ([`model_init`]), the pipeline of one forward pass ([`forward`](mod@forward)),
//! and the trained scene as a value.
//!
//! A trained scene: the representation, the filter state it renders with
//! (the motion-aware nu(t) included) and its observations, the run's configuration
//! and iteration (SH degree, 2D filter), and the [`SceneRecord`] (training cameras,
//! background, time range). [`TrainedScene::load`] reads `RUN/model` without the
//! data set, rebuilding the representation through a [`ModelRegistry`];
//! [`TrainedScene::render`] draws any camera at any time through the training
//! pipeline ([`crate::forward::forward`]). Evaluation, rendering and export work on
//! this type; a trainer becomes one with `maaf_train::trainer::Trainer::into_scene`.
//!
//! What the trainer and evaluation share about a run besides the scene: the data set
//! it was trained on ([`run_data`]: `RUN/data.json`, checked before a resume or an
//! evaluation) and the image metrics a render is scored with ([`metrics`]: PSNR,
//! SSIM).
//! `docs/architecture.md` says where this crate sits.

pub mod backdrop;
pub mod budget;
pub mod checkpoint_read;
pub mod config;
mod error;
pub mod forward;
mod init;
pub mod metrics;
mod observed;
mod record;
mod registry;
pub mod run_data;
mod run_dir;
pub mod run_log;
mod term_name;
mod timings;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use maaf_autodiff::{PerGaussian, Tensor};
use maaf_filter::{
    FilterError, FilterRegistry, FilterState, ObservationTable, SamplingFilter, static_nu,
};
use maaf_splat::{Camera, Filter2d, RenderSettings};

pub use budget::WallBudget;
pub use checkpoint_read::Opened;
pub use config::{
    BackdropConfig, CameraColourConfig, DensifyConfig, DensifyGradient, HullTimes, LossRegion,
    MAX_BATCH, OpacityReset, PruneConfig, StaticPoints, TrainConfig,
};
pub use error::{Error, write_atomic};
pub use init::{camera_extent, model_init, training_views};
pub use observed::{centres, observed_views};
pub use record::{RawTensor, SceneRecord};
pub use registry::{ModelLoader, ModelRegistry};
pub use run_dir::repair_run_dir;
pub use term_name::{RESERVED, name_problem};
pub use timings::{PHASE_COUNT, Timings};

use maaf_data::Dataset;
use maaf_models::Representation;

use crate::forward::{forward, gaussians_at};

/// A trained run's model and everything needed to render it (see the module
/// documentation).
pub struct TrainedScene {
    /// The 4D representation, at the run's stage (`set_iteration` applied).
    pub model: Box<dyn Representation<f32>>,
    /// The 3D filter of every Gaussian (static nu, or the motion-aware nu(t) curves).
    pub filter: FilterState,
    /// The f/d observations the motion filter's curves were computed from (no frames
    /// for the other filters).
    pub observations: ObservationTable,
    /// The run's configuration.
    pub config: TrainConfig,
    /// Iterations the model was trained for.
    pub iteration: usize,
    /// Training wall time, seconds ([`Timings::total`]).
    pub train_seconds: f64,
    /// Training cameras and times, initial cloud box, time range, background.
    pub record: SceneRecord,
    /// The run's static background layer (`RUN/backdrop`), drawn behind the model
    /// ([`backdrop`]), when its config has one.
    pub backdrop: Option<Box<TrainedScene>>,
    /// Whether the run's filter smoothed (the 2D Mip filter, [`render_settings`]):
    /// as its checkpoint records it, or for a checkpoint from before that record,
    /// what the built-in filter its config names does (a filter of one's own: that
    /// its state is not "no filter").
    pub smooths: bool,
}

/// Render settings of a run of `config` on `background` at `iteration`: the 2D Mip
/// filter (0.1 px^2 with compensation) whenever the run's 3D filter `smooths`
/// ([`maaf_filter::SamplingFilter::smooths`]), as in the paper; the classic 3DGS
/// dilation (0.3 px^2) otherwise. The SH degree grows by one every
/// `sh_degree_every` iterations up to the model's.
pub fn render_settings(
    config: &TrainConfig,
    background: [f32; 3],
    iteration: usize,
    smooths: bool,
) -> RenderSettings {
    let filter2d = if smooths {
        Filter2d::Mip
    } else {
        Filter2d::Classic
    };
    let grown = iteration / config.sh_degree_every.max(1);
    RenderSettings {
        background: background.map(f64::from),
        filter2d,
        sh_degree: grown.min(config.model.sh_degree()),
        ..RenderSettings::default()
    }
}

/// The folder holding the trained model of `run` (`RUN/model`, or its parked old
/// version when a swap was cut short), or a one-line error for a missing run or model.
pub fn model_dir(run: &Path) -> Result<PathBuf, Error> {
    if !run.is_dir() {
        return Err(Error::Input(format!(
            "{}: run directory does not exist",
            run.display()
        )));
    }
    let model = maaf_io::readable_dir(&run.join("model")).unwrap_or_else(|| run.join("model"));
    if !model.join("state.json").is_file() || !model.join("tensors.safetensors").is_file() {
        let how = if run.join("state.json").is_file() {
            "it is a checkpoint folder; give the run folder that holds it".to_string()
        } else if run.join("config.json").is_file() {
            format!(
                "the run has no model yet (it is being trained, or stopped before writing one: continue it with `maaf train --resume {}`)",
                run.display()
            )
        } else {
            format!("train one with `maaf train --out {}`", run.display())
        };
        return Err(Error::Input(format!(
            "{}: no trained model (expected {}/state.json and tensors.safetensors); {how}",
            run.display(),
            model.display(),
        )));
    }
    Ok(model)
}

/// The built-in filter the run's config names, whose `observes` (and, for a
/// checkpoint that does not record it, `smooths`) the trainer used; `None` for a
/// program's own filter, whose code a trained scene does not have: what it did is
/// read from its checkpoint instead (it observed if the checkpoint holds
/// observations; it smoothed as recorded, or unless its state is no filter).
fn builtin_filter(config: &TrainConfig) -> Option<Box<dyn SamplingFilter>> {
    FilterRegistry::builtin().for_config(&config.filter).ok()
}

impl TrainedScene {
    /// Loads the trained model of `run` (`RUN/model`) without its data set. A run
    /// whose checkpoints predate the scene record needs its data set
    /// ([`Self::load_with`]); the error says so.
    pub fn load(run: &Path, registry: &ModelRegistry) -> Result<Self, Error> {
        Self::load_with(run, registry, None)
    }

    /// [`Self::load`], taking what a checkpoint without a scene record lacks from
    /// `data` (the data set the run was trained on) when given.
    pub fn load_with(
        run: &Path,
        registry: &ModelRegistry,
        data: Option<&Dataset>,
    ) -> Result<Self, Error> {
        Self::from_checkpoint(&model_dir(run)?, registry, data)
    }

    /// [`Self::load`], calling `fallback` with the run's configuration for the scene
    /// record only when the checkpoint has none (a run saved before it existed: the
    /// caller opens the data set then, [`SceneRecord::of_data`]).
    pub fn load_or(
        run: &Path,
        registry: &ModelRegistry,
        fallback: impl FnOnce(&TrainConfig) -> Result<SceneRecord, Error>,
    ) -> Result<Self, Error> {
        Self::from_checkpoint_or(&model_dir(run)?, registry, fallback)
    }

    /// Loads a checkpoint folder (`RUN/model` or `RUN/checkpoints/iter_N`), taking the
    /// scene record from `data` when the checkpoint has none
    /// ([`Self::from_checkpoint_or`]).
    pub fn from_checkpoint(
        dir: &Path,
        registry: &ModelRegistry,
        data: Option<&Dataset>,
    ) -> Result<Self, Error> {
        Self::from_checkpoint_or(dir, registry, |config| match data {
            Some(data) => SceneRecord::of_data(data, config),
            None => Err(Error::Input(format!(
                "{}: saved before checkpoints recorded their training cameras: this run loads only with its data set (--data DIR)",
                dir.display()
            ))),
        })
    }

    /// Loads a checkpoint folder: rebuilds the representation its `state.json` names
    /// through `registry` from the run's configuration and
    /// [`SceneRecord::model_init`], then loads its tensors, buffers, filter and
    /// observations with the trainer's own reader. `fallback` gives the scene record
    /// of a checkpoint without one. Errors name the folder.
    pub fn from_checkpoint_or(
        dir: &Path,
        registry: &ModelRegistry,
        fallback: impl FnOnce(&TrainConfig) -> Result<SceneRecord, Error>,
    ) -> Result<Self, Error> {
        let opened = Opened::open(dir)?;
        let record = match opened.scene_record()? {
            Some(record) => record,
            None => fallback(&opened.state.config)?,
        };
        let config = &opened.state.config;
        let init = record.model_init(config);
        let mut model = registry
            .build(&opened.state.model, config, &init)
            .map_err(|e| Error::Input(format!("{}: {e}", dir.display())))?;
        opened.load_model(model.as_mut(), dir, HashMap::new())?;
        let builtin = builtin_filter(config);
        let observes = match &builtin {
            Some(filter) => filter.observes(),
            None => opened.tensors()?.names().contains(&"observations"),
        };
        let (observed, _) = observed_views(&record.times, observes, config.filter.max_views);
        let observations = opened.observations(&observed, record.times.len())?;
        let backdrop = if config.backdrop.enabled() {
            let layer = backdrop::backdrop_dir_of(dir);
            Some(Box::new(Self::load(&layer, registry)?))
        } else {
            None
        };
        let state = opened.state;
        let layer_seconds = backdrop.as_ref().map_or(0.0, |b| b.train_seconds);
        let smooths = state.smooths.unwrap_or_else(|| {
            builtin.map_or_else(
                || !matches!(state.filter, FilterState::None { .. }),
                |filter| filter.smooths(),
            )
        });
        Ok(TrainedScene {
            smooths,
            model,
            filter: state.filter,
            observations,
            config: state.config,
            iteration: state.iteration,
            train_seconds: state.timings.total() + layer_seconds,
            record,
            backdrop,
        })
    }

    /// Number of Gaussians.
    pub fn num_gaussians(&self) -> usize {
        self.model.rows()
    }

    /// Number of stored model scalars: the parameters plus the state the model keeps
    /// outside its store ([`TrainingHooks::state_scalars`](maaf_models::TrainingHooks::state_scalars), e.g. GroupFlow's tables).
    pub fn num_scalars(&self) -> usize {
        let extra = self.model.hooks().map_or(0, |h| h.state_scalars());
        self.model.params().num_scalars() + extra
    }

    /// The settings the run renders with ([`render_settings`] at its iteration, on
    /// its background).
    pub fn render_settings(&self) -> RenderSettings {
        render_settings(
            &self.config,
            self.record.background,
            self.iteration,
            self.smooths,
        )
    }

    /// Renders the scene at `time` from `camera` (float `[H, W, 3]`) with the run's
    /// settings.
    pub fn render(&self, camera: &Camera, time: f64) -> Tensor<f32> {
        self.render_with(camera, time, &self.render_settings())
    }

    /// Renders the scene at `time` from `camera` with `settings`, through the training
    /// pipeline ([`forward()`]) with the parameters as constants.
    pub fn render_with(
        &self,
        camera: &Camera,
        time: f64,
        settings: &RenderSettings,
    ) -> Tensor<f32> {
        render_over(
            self.model.as_ref(),
            &self.filter,
            self.backdrop.as_deref(),
            camera,
            time,
            settings,
        )
    }

    /// The deformed, filtered Gaussians at `time` as plain tensors
    /// `[means, scales, quats, opacity, sh]`: what the renderer draws, the background
    /// layer's after the model's (its SH padded with zero bands to the model's).
    pub fn gaussians_at(&self, time: f64) -> [Tensor<f32>; 5] {
        let own = self.model_gaussians_at(time);
        match &self.backdrop {
            Some(layer) => stack_gaussians(own, layer.gaussians_at(time)),
            None => own,
        }
    }

    /// [`Self::gaussians_at`] of the model alone, without the background layer: one
    /// row per row of [`Self::filter`].
    pub fn model_gaussians_at(&self, time: f64) -> [Tensor<f32>; 5] {
        gaussians_at(self.model.as_ref(), &self.filter, time)
    }

    /// Training cameras, at the training scale, one per training view.
    pub fn cameras(&self) -> &[Camera] {
        &self.record.cameras
    }

    /// The training cameras' extent ([`camera_extent`]).
    pub fn extent(&self) -> f64 {
        camera_extent(&self.record.cameras)
    }

    /// Mip-Splatting's static nu (paper Eq. 2) of the canonical centres from the
    /// training cameras, with the run's filter settings.
    pub fn static_nu(&self) -> Result<Vec<f32>, FilterError> {
        let ids = self.model.canonical_ids();
        let centres = centres(self.model.params().value(ids.means));
        static_nu(&centres, &self.record.cameras, &self.config.filter)
    }
}

/// The rows of `a` followed by those of `b` (`[means, scales, quats, opacity, sh]`);
/// the SH of the one with fewer coefficients is padded with zero bands.
fn stack_gaussians(a: [Tensor<f32>; 5], b: [Tensor<f32>; 5]) -> [Tensor<f32>; 5] {
    let k = a[4].shape()[1].max(b[4].shape()[1]);
    let pad = |sh: &Tensor<f32>| -> Vec<f32> {
        let have = sh.shape()[1];
        sh.data()
            .chunks_exact(3 * have)
            .flat_map(|row| {
                row.iter()
                    .copied()
                    .chain(std::iter::repeat_n(0.0, 3 * (k - have)))
            })
            .collect()
    };
    let [am, as_, aq, ao, ash] = a;
    let [bm, bs, bq, bo, bsh] = b;
    let cat = |x: Tensor<f32>, y: Tensor<f32>| {
        let mut shape = x.shape().to_vec();
        shape[0] += y.shape()[0];
        let mut data = x.into_vec();
        data.extend_from_slice(y.data());
        Tensor::from_vec(data, &shape)
    };
    let n = ash.shape()[0] + bsh.shape()[0];
    let mut sh = pad(&ash);
    sh.extend(pad(&bsh));
    [
        cat(am, bm),
        cat(as_, bs),
        cat(aq, bq),
        cat(ao, bo),
        Tensor::from_vec(sh, &[n, k, 3]),
    ]
}

/// Renders `model` with `filter` at `time` from `camera` with `settings` through the
/// training pipeline ([`forward()`]) with the parameters as constants; over the
/// background layer `backdrop` when given ([`backdrop::over_backdrop`]: the model on
/// black, the layer on `settings.background` and window with its own SH degree and 2D
/// filter).
pub fn render_over(
    model: &dyn Representation<f32>,
    filter: &FilterState,
    backdrop: Option<&TrainedScene>,
    camera: &Camera,
    time: f64,
    settings: &RenderSettings,
) -> Tensor<f32> {
    let back = backdrop.map(|layer| {
        let own = RenderSettings {
            background: settings.background,
            window: settings.window,
            ..layer.render_settings()
        };
        layer.render_with(camera, time, &own)
    });
    let settings = RenderSettings {
        background: if back.is_some() {
            [0.0; 3]
        } else {
            settings.background
        },
        ..settings.clone()
    };
    let tape = maaf_autodiff::Tape::new();
    let params = model.params().bind_constants(&tape);
    let out = forward(model, &params, filter, camera, time, &settings);
    let image = match back {
        Some(b) => backdrop::over_backdrop(out.render.image, out.render.alpha, b),
        None => out.render.image,
    };
    // The binding ends the borrow of the tape before the tape is dropped.
    #[allow(clippy::let_and_return)]
    let image = image.value().clone();
    image
}
