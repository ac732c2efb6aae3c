//! The training loop (docs/architecture.md): one view per iteration, a fresh tape per
//! step, the pipeline of [`maaf_scene::forward`], the objective as named terms, Adam,
//! densification and filter refreshes outside the tape.
//!
//! A trainer is built from a config ([`Trainer::new`]: the model kind is
//! `config.model`, the extra loss terms `config.terms`, the filter `filter.kind`, the
//! strategy `densify.strategy`; [`Trainer::with_plugins`] with those a program
//! registered) or around any representation ([`Trainer::with_model`]);
//! terms can also be pushed onto [`Trainer::objective`]. [`train_run`] runs either in
//! a run directory.

mod background;
mod best;
mod branch;
pub mod camera_colour;
mod checkpoint;
mod cpu_clock;
mod densify;
mod health;
mod layer;
mod log;
mod phase;
mod prune;
mod refresh;
pub mod region;
mod reset;
mod resume;
mod run;
mod state;
mod step;
mod strategy;
mod timed;
mod validation;
mod views;

use maaf_autodiff::{OpProfile, PerGaussian, Tensor};
use maaf_filter::{CameraTime, ObservationTable, SamplingFilter};
use maaf_splat::Camera;
use views::TrainViews;

pub use best::{BEST_DIR, Chosen};
pub use checkpoint::{
    checkpoint_iteration, load_checkpoint, load_checkpoint_with_plugins, save_checkpoint,
};
pub use densify::{DensifyPlan, DensifyStats, ViewGrad, plan as plan_densify};

pub use branch::{branch_run, branch_run_with_plugins};
pub use prune::{keep_highest, removal_sensitivity, sensitivity_scores};
pub use reset::{Liveness, opacity_caps};
pub use resume::{checkpoints_newest_first, load_newest, truncate_log};
pub use run::{
    BUDGET_FILE, RunSummary, checkpoint_dir, train_run, train_run_with, train_run_with_plugins,
};
pub use state::TrainState;
pub use strategy::{
    DefaultStrategy, RefineStep, SensitivityPruning, StepInfo, Strategy, StrategyMaker,
    StrategyRegistry,
};

use crate::data::Dataset;
use crate::loss::Objective;
use crate::models::Representation;
use crate::{Error, Plugins};
use maaf_scene::{
    DensifyConfig, DensifyGradient, OpacityReset, SceneRecord, Timings, TrainConfig, TrainedScene,
    camera_extent, model_init, observed_views, repair_run_dir,
};

/// A trainer: the per-Gaussian [`TrainState`], the strategy and filter that change
/// it, the objective, the training views and the run's bookkeeping.
pub struct Trainer {
    /// Run configuration.
    pub config: TrainConfig,
    /// The per-Gaussian state: model, Adam moments, filter state, observations,
    /// densification statistics and liveness.
    pub state: TrainState,
    /// What computes [`TrainState::filter`]: the config's filter by name, or a user's
    /// ([`Trainer::set_filter`]).
    sampling: Box<dyn SamplingFilter>,
    /// The densification strategy (the one `densify.strategy` names, or a user's:
    /// [`Trainer::set_strategy`]).
    strategy: Box<dyn Strategy>,
    /// Per-camera colour correction of the training renders (`camera_colour`), when
    /// the config turns it on.
    pub camera_colour: Option<camera_colour::CameraColour>,
    /// Objective (named weighted terms): the photometric loss, the model's
    /// regularisers and the terms `config.terms` names; push further terms here.
    pub objective: Objective<f32>,
    /// Iterations completed.
    pub iteration: usize,
    /// Steps skipped because a value or gradient was not finite.
    pub skipped_steps: usize,
    /// Why the last skipped step was skipped (the tape's message), if any was.
    pub last_skip: Option<String>,
    /// Bounds of the point cloud the representation was built from
    /// ([`crate::data::PointCloud::bounds`] of [`crate::models::ModelInit::cloud`]), saved with every checkpoint
    /// ([`SceneRecord::init_box`]) so that the run's model is rebuilt without its data
    /// set. [`Trainer::new`] sets it; [`Trainer::with_model`] starts from the data
    /// set's scene bounds: set it when the model was built from a [`crate::models::ModelInit`] whose
    /// box it uses beyond its parameters.
    pub init_box: ([f64; 3], [f64; 3]),
    /// Wall time per phase.
    pub timings: Timings,
    /// Wall time per tape op, summed over steps, when set to `Some` (off by default:
    /// the step benchmark turns it on).
    pub op_profile: Option<OpProfile>,
    /// Values of every term at the last step (name, value), for logging.
    pub last_terms: Vec<(String, f64)>,
    /// Whether the filter has been computed (at the first step, unless a checkpoint
    /// restored it).
    filter_ready: bool,
    /// The training views: cameras, times, ground truth and what the config's
    /// options need of them.
    views: TrainViews,
    held_out: Vec<validation::HeldOut>,
    /// The training views the motion filter observes (`camera` is the view's index),
    /// the observation table's frames; none for the other filters.
    observed: Vec<CameraTime>,
    /// Each training view's frame in the observation table, if it is observed.
    observed_slot: Vec<Option<usize>>,
    extent: f64,
    background: [f32; 3],
    /// The run's background layer and its renders behind the training views.
    backdrop: Option<layer::Layer>,
    /// `(min, max)` of the data set's time stamps (the scene record's).
    time_range: (f64, f64),
}

impl Trainer {
    /// A new run of the representation `config.model` describes, with the built-in
    /// terms, representations, filters and strategies ([`Plugins::builtin`]); a name
    /// the config gives that is not built in is refused ([`Trainer::with_plugins`]
    /// supplies others). Values the data decides (SaRO's `duration`) are resolved
    /// into the config, so `config.json` records them.
    pub fn new(data: &Dataset, config: TrainConfig) -> Result<Self, Error> {
        Self::with_plugins(data, config, &Plugins::builtin())
    }

    /// [`Trainer::new`] with the terms, representations, filters and strategies of
    /// `plugins`: everything the config names must be registered there
    /// ([`Plugins::check`]). A custom representation is built by its factory from
    /// the config (its options: `config.model.options()`) and the initial cloud.
    pub fn with_plugins(
        data: &Dataset,
        config: TrainConfig,
        plugins: &Plugins,
    ) -> Result<Self, Error> {
        plugins.check(&config, "config")?;
        Self::from_config(data, config, plugins)
    }

    /// [`Trainer::with_plugins`] without the check of the terms: a term no registry
    /// knows is left out of the objective ([`Objective::unregistered`]), which is what
    /// a model loaded for rendering needs ([`load_checkpoint`]); training refuses it.
    fn from_config(
        data: &Dataset,
        mut config: TrainConfig,
        plugins: &Plugins,
    ) -> Result<Self, Error> {
        config.validate()?;
        let init = model_init(data, &config)?;
        config.model.resolve(&init);
        let model = plugins
            .models
            .build(config.model.kind(), &config, &init)
            .map_err(Error::Input)?;
        let mut trainer = Self::assemble(data, config, model, plugins)?;
        trainer.init_box = init.cloud.bounds();
        Ok(trainer)
    }

    /// A new run of any representation: the model is used as given (its config is
    /// the caller's; `config.model` is then only recorded, not used). The filter,
    /// objective, densification, checkpoints and evaluation work unchanged. The
    /// objective is the photometric loss plus the model's declared regularisers and
    /// the built-in terms `config.terms` names (any other name is refused), the
    /// filter and strategy the built-in ones the config names.
    pub fn with_model(
        data: &Dataset,
        config: TrainConfig,
        model: Box<dyn Representation<f32>>,
    ) -> Result<Self, Error> {
        let plugins = Plugins::builtin();
        plugins.terms.check(&config.terms, "config: terms")?;
        Self::assemble(data, config, model, &plugins)
    }

    /// The trainer around `model`, its objective built by [`Objective::for_run`], its
    /// filter and strategy the ones the config names in `plugins`.
    fn assemble(
        data: &Dataset,
        config: TrainConfig,
        model: Box<dyn Representation<f32>>,
        plugins: &Plugins,
    ) -> Result<Self, Error> {
        config.validate()?;
        if data.background() != config.background.rgb() {
            return Err(Error::Input(format!(
                "{}: the data set is composited on {} but the config's background is {}; open it on the config's (DatasetOptions {{ background: config.background.rgb() }})",
                data.root().display(),
                crate::data::Background(data.background()),
                config.background
            )));
        }
        let views = TrainViews::load(data, &config)?;
        let extent = camera_extent(&views.cameras);
        let n = model.rows();
        let sampling = plugins
            .filters
            .for_config(&config.filter)
            .map_err(|e| Error::Input(e.to_string()))?;
        let (observed, observed_slot) =
            observed_views(&views.times, sampling.observes(), config.filter.max_views);
        if observed.len() < views.len() && sampling.observes() {
            ::log::info!(
                "motion filter: observing {} of {} training views (filter.max_views), {} B per Gaussian",
                observed.len(),
                views.len(),
                4 * observed.len()
            );
        }
        let bounds = data.scene_bounds();
        let objective = Objective::for_run(
            config.lambda_dssim,
            model.as_ref(),
            &config.terms,
            &plugins.terms,
        )?;
        let strategy = plugins.strategies.build(&config)?;
        let held_out = validation::held_out_views(
            data,
            config.val_views,
            config.train_scale,
            config.keep_best,
        )?;
        let camera_colour = config
            .camera_colour
            .enabled
            .then(|| camera_colour::CameraColour::new(&views.cameras, config.camera_colour.lr));
        Ok(Trainer {
            camera_colour,
            state: TrainState::new(model, ObservationTable::for_frames(&observed, n)),
            sampling,
            strategy,
            objective,
            iteration: 0,
            skipped_steps: 0,
            last_skip: None,
            init_box: (bounds.min.to_array(), bounds.max.to_array()),
            time_range: data.time_range(),
            timings: Timings::default(),
            op_profile: None,
            last_terms: Vec::new(),
            filter_ready: false,
            background: data.background(),
            config,
            views,
            held_out,
            observed,
            observed_slot,
            extent,
            backdrop: None,
        })
    }

    /// Number of Gaussians.
    pub fn num_gaussians(&self) -> usize {
        self.state.model.rows()
    }

    /// About how many bytes a training step of this model holds at `gaussians`
    /// Gaussians: per Gaussian, its parameter row four times (values, gradient, two
    /// Adam moments) plus about four more per view of the batch (the step's deformed
    /// Gaussians and network activations), its f/d observations and densification
    /// statistics. Measured on SaRO at batch 1: 2.0 kB per Gaussian, 7.8 parameter
    /// rows. Used to refuse a size the machine cannot hold before allocating it.
    pub fn step_bytes(&self, gaussians: usize) -> u64 {
        let row: usize = self
            .state
            .model
            .params()
            .iter()
            .filter(|p| p.rows == maaf_models::params::Rows::PerGaussian)
            .map(|p| p.value.shape().iter().skip(1).product::<usize>())
            .sum();
        let floats =
            row * (4 + 4 * self.config.batch.max(1)) + self.state.observations.num_frames() + 3;
        (gaussians as u64).saturating_mul(4 * floats as u64)
    }

    /// Refuses to train or time `gaussians` Gaussians when [`Self::step_bytes`] is
    /// more than the memory available ([`maaf_io::memory::check`]).
    pub fn check_memory(&self, gaussians: usize) -> Result<(), Error> {
        maaf_io::memory::check(
            self.step_bytes(gaussians),
            &format!("a training step of {gaussians} Gaussians"),
        )
        .map_err(Error::Input)
    }

    /// Training cameras (at the training scale).
    pub fn cameras(&self) -> &[Camera] {
        &self.views.cameras
    }

    /// The deformed, filtered Gaussians at `time` as plain tensors
    /// `[means, scales, quats, opacity, sh]`: what the renderer draws.
    pub fn frame_at(&self, time: f64) -> [Tensor<f32>; 5] {
        maaf_scene::forward::gaussians_at(self.state.model.as_ref(), &self.state.filter, time)
    }

    /// What a checkpoint of this run records besides the model
    /// ([`SceneRecord`]): the training cameras and times, the initial cloud's box,
    /// the data set's time range and background.
    pub fn scene_record(&self) -> SceneRecord {
        SceneRecord {
            cameras: self.views.cameras.clone(),
            times: self.views.times.clone(),
            init_box: self.init_box,
            time_range: self.time_range,
            background: self.background,
        }
    }

    /// The trained scene this trainer holds: its model, filter state and
    /// observations, configuration, iteration and scene record, as
    /// [`TrainedScene::load`] reads them from a checkpoint of it.
    pub fn into_scene(self) -> TrainedScene {
        let record = self.scene_record();
        TrainedScene {
            smooths: self.sampling.smooths(),
            train_seconds: self.timings.total()
                + self
                    .backdrop
                    .as_ref()
                    .map_or(0.0, |l| l.scene.train_seconds),
            model: self.state.model,
            filter: self.state.filter,
            observations: self.state.observations,
            config: self.config,
            iteration: self.iteration,
            record,
            backdrop: self.backdrop.map(|l| Box::new(l.scene)),
        }
    }
}
