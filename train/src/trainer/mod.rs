//! The training loop (DESIGN.md section 6): one view per iteration, a fresh tape per
//! step, the filter fold between the representation and the renderer, the objective
//! as named terms, Adam, densification and filter refreshes outside the tape.

mod checkpoint;
mod config;
mod densify;
mod run;
mod timings;

use std::time::Instant;

use maaf_autodiff::optim::{Adam, AdamConfig};
use maaf_autodiff::{PerGaussian, Tape, Tensor};
use maaf_filter::{FilterKind, FilterState, Frame, MotionCurves, ObservationTable, static_nu};
use maaf_splat::{Camera, Filter2d, GaussianVars, RenderSettings, apply_3d_filter, render};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

pub use checkpoint::{load_checkpoint, save_checkpoint};
pub use config::{DensifyConfig, TrainConfig};
pub use densify::{DensifyPlan, DensifyStats, plan as plan_densify};
pub use run::{RunSummary, train_run};
pub use timings::Timings;

use crate::data::{Dataset, View};
use crate::loss::{Objective, TermCtx};
use crate::models::{PointCloud, Representation, SaroModel};

/// What went wrong in a training run.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// Bad data, config or file.
    #[error("{0}")]
    Input(String),
    /// Writing the run directory failed.
    #[error("{path}: {source}")]
    Io {
        /// File or folder.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
}

/// Maps an I/O error on `path` to [`TrainError::Io`] naming the file.
fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> TrainError + '_ {
    move |source| TrainError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// A trainer: the model, its optimiser, the filter and every per-Gaussian container,
/// resized in lock-step by [`PerGaussian::select_rows`].
pub struct Trainer {
    /// Run configuration.
    pub config: TrainConfig,
    /// The 4D representation.
    pub model: Box<dyn Representation<f32>>,
    /// Adam moments per parameter.
    pub adam: Adam<f32>,
    /// Current 3D filter of every Gaussian.
    pub filter: FilterState,
    /// f/d observations recorded from training forward passes (motion filter input).
    pub observations: ObservationTable,
    /// Densification statistics.
    pub stats: DensifyStats,
    /// Objective (named weighted terms).
    pub objective: Objective<f32>,
    /// Iterations completed.
    pub iteration: usize,
    /// Steps skipped because a value or gradient was not finite.
    pub skipped_steps: usize,
    /// Iteration of the last opacity reset (large-screen pruning starts after it).
    pub last_reset: Option<usize>,
    /// Wall time per phase.
    pub timings: Timings,
    /// Values of every term at the last step (name, value), for logging.
    pub last_terms: Vec<(String, f64)>,
    views: Vec<View>,
    gts: Vec<Tensor<f32>>,
    cameras: Vec<Camera>,
    frames: Vec<Frame>,
    extent: f64,
    background: [f32; 3],
}

/// Radius of the sphere around the mean camera centre that holds every camera,
/// times 1.1 (3DGS `getNerfppNorm`): the scene extent that scales position learning
/// rates and the clone/split boundary.
pub fn camera_extent(cameras: &[Camera]) -> f64 {
    let n = cameras.len().max(1) as f64;
    let c = cameras
        .iter()
        .map(|c| c.center())
        .fold(glam::DVec3::ZERO, |a, b| a + b)
        / n;
    1.1 * cameras
        .iter()
        .map(|cam| (cam.center() - c).length())
        .fold(0.0, f64::max)
}

impl Trainer {
    /// A new run: random points in the data set's scene bounds (as SaRO-GS and
    /// Deformable-3DGS initialise synthetic D-NeRF scenes), the SaRO model, Adam and
    /// the initial filter.
    pub fn new(data: &Dataset, config: TrainConfig) -> Result<Self, TrainError> {
        let mut trainer = Self::initial(data, config)?;
        trainer.refresh_filter(true);
        Ok(trainer)
    }

    /// The freshly initialised trainer without its first filter refresh; a checkpoint
    /// load overwrites the filter and the observations, so it starts from here.
    fn initial(data: &Dataset, config: TrainConfig) -> Result<Self, TrainError> {
        config
            .filter
            .validate()
            .map_err(|e| TrainError::Input(format!("filter config: {e}")))?;
        let views = data
            .train_views(config.train_scale)
            .map_err(|e| TrainError::Input(e.to_string()))?;
        if views.is_empty() {
            return Err(TrainError::Input(format!(
                "{}: no training views",
                data.root().display()
            )));
        }
        let bounds = data.scene_bounds();
        let mut rng = Pcg64::seed_from_u64(config.seed);
        let points: Vec<[f64; 3]> = (0..config.init_points)
            .map(|_| std::array::from_fn(|a| rng.random_range(bounds.min[a]..bounds.max[a])))
            .collect();
        let colours = (0..config.init_points)
            .map(|_| std::array::from_fn(|_| rng.random_range(0.0..1.0)))
            .collect();
        let cameras: Vec<Camera> = views.iter().map(|v| v.camera.clone()).collect();
        let extent = camera_extent(&cameras);
        let model = SaroModel::<f32>::from_point_cloud(
            &PointCloud { points, colours },
            config.model.clone(),
            extent,
            config.seed,
        );
        Ok(Self::assemble(
            data,
            config,
            Box::new(model),
            views,
            cameras,
            extent,
        ))
    }

    fn assemble(
        data: &Dataset,
        config: TrainConfig,
        model: Box<dyn Representation<f32>>,
        views: Vec<View>,
        cameras: Vec<Camera>,
        extent: f64,
    ) -> Self {
        let n = model.num_gaussians();
        let frames: Vec<Frame> = views
            .iter()
            .enumerate()
            .map(|(i, v)| Frame {
                camera: i,
                time: v.time as f32,
            })
            .collect();
        let gts = views.iter().map(|v| v.image.to_tensor()).collect();
        let objective = Objective::photometric(config.lambda_dssim).with(
            crate::loss::Provided::new(crate::loss::L_SR, config.model.lambda_sr),
        );
        Trainer {
            adam: Adam::new(AdamConfig::default()),
            filter: FilterState::None { rows: n },
            observations: ObservationTable::for_frames(&frames, n),
            stats: DensifyStats::new(n),
            objective,
            iteration: 0,
            skipped_steps: 0,
            last_reset: None,
            timings: Timings::default(),
            last_terms: Vec::new(),
            background: data.background(),
            config,
            model,
            views,
            gts,
            cameras,
            frames,
            extent,
        }
    }

    /// Number of Gaussians.
    pub fn num_gaussians(&self) -> usize {
        self.model.num_gaussians()
    }

    /// Training cameras (at the training scale).
    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }

    /// Render settings at `iteration`: the 2D Mip filter (0.1 px^2 with compensation)
    /// whenever a 3D filter is on, as in the paper; the classic 3DGS dilation
    /// (0.3 px^2) otherwise. SH degree grows by one every `sh_degree_every` iterations.
    pub fn render_settings(&self, iteration: usize) -> RenderSettings {
        let filter2d = if self.config.filter.kind == FilterKind::None {
            Filter2d::Classic
        } else {
            Filter2d::Mip
        };
        let grown = iteration / self.config.sh_degree_every.max(1);
        RenderSettings {
            background: self.background.map(f64::from),
            filter2d,
            sh_degree: grown.min(self.config.model.sh_degree),
            ..RenderSettings::default()
        }
    }

    /// The view trained at `iteration` (1-based): views are visited in a seeded random
    /// order that is reshuffled every epoch; the order depends only on the seed and the
    /// iteration, so a resumed run sees the same sequence.
    fn view_at(&self, iteration: usize) -> usize {
        let n = self.views.len();
        let epoch = (iteration - 1) / n;
        let mut order: Vec<usize> = (0..n).collect();
        let mut rng = Pcg64::seed_from_u64(
            self.config.seed ^ (epoch as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
        );
        order.shuffle(&mut rng);
        order[(iteration - 1) % n]
    }

    /// One training iteration: deform, filter, render, objective, backward, Adam,
    /// statistics, then densification and filter refresh when due.
    pub fn step(&mut self) {
        let it = self.iteration + 1;
        self.model.set_iteration(it);
        let vi = self.view_at(it);
        let (time, camera) = (self.views[vi].time, self.cameras[vi].clone());
        let tape = Tape::new();
        tape.set_validate(self.config.validate);

        let t0 = Instant::now();
        let bound = self.model.bind(&tape);
        let g = bound.deform(time);
        let regularisers = bound.regularisers();
        let t1 = Instant::now();

        let n = self.model.num_gaussians();
        let (scales, opacity) = if self.config.filter.kind == FilterKind::None {
            (g.scales, g.opacity)
        } else {
            let var = Tensor::from_vec(self.filter.variance_at(time as f32), &[n]);
            apply_3d_filter(g.scales, g.opacity, &var)
        };
        let gv = GaussianVars {
            means: g.means,
            scales,
            quats: g.quats,
            opacity,
            sh: g.sh,
        };
        let out = render(&tape, &gv, &camera, &self.render_settings(it));
        let mut ctx = TermCtx::new(out.image, &self.gts[vi]).at_iteration(it - 1);
        for r in &regularisers {
            ctx.insert(&r.name, r.value);
        }
        let eval = self.objective.evaluate(&ctx);
        let t2 = Instant::now();

        let grads = tape.backward(eval.total);
        let t3 = Instant::now();
        let finite = |t: &Tensor<f32>| t.first_non_finite().is_none();
        let grads = grads.map_err(|e| e.to_string()).and_then(|gr| {
            let ok = eval.total.value().item().is_finite()
                && gr
                    .param_names()
                    .iter()
                    .all(|p| gr.param(p).is_none_or(finite));
            if ok {
                Ok(gr)
            } else {
                Err("non-finite loss or gradient".to_string())
            }
        });
        match grads {
            Ok(grads) => {
                for slot in self.model.params_mut() {
                    if let Some(gr) = grads.param(&slot.name) {
                        self.adam.set_group(&slot.name, slot.lr.clone());
                        self.adam.step(&slot.name, slot.value, gr, it - 1);
                    }
                }
                self.stats.record(
                    grads.wrt(out.means2d),
                    &out.radii,
                    camera.width,
                    camera.height,
                );
                let centres: Vec<[f32; 3]> = g
                    .means
                    .value()
                    .data()
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect();
                // The frame index is valid and the row count matches by construction.
                let _ =
                    self.observations
                        .record_centres(vi, &camera, &centres, &self.config.filter);
                self.last_terms = eval
                    .terms
                    .iter()
                    .map(|t| (t.name.clone(), t.value))
                    .collect();
                self.last_terms.push(("total".into(), eval.total_value()));
            }
            Err(e) => {
                // A NaN/Inf in the loss or a gradient: the update is skipped so nothing
                // non-finite reaches the parameters (or a checkpoint); counted and logged.
                self.skipped_steps += 1;
                log_line(&format!("iteration {it}: step skipped: {e}"));
            }
        }
        drop(ctx);
        drop(bound);
        let t4 = Instant::now();
        self.timings.field_mlp += (t1 - t0).as_secs_f64();
        self.timings.render_forward += (t2 - t1).as_secs_f64();
        self.timings.backward += (t3 - t2).as_secs_f64();
        self.timings.optimiser += (t4 - t3).as_secs_f64();
        self.iteration = it;

        let densified = self.maybe_densify(it);
        let t5 = Instant::now();
        self.timings.densification += (t5 - t4).as_secs_f64();
        if self
            .config
            .filter
            .refresh
            .due(it as u64, self.config.iterations as u64, densified)
        {
            self.refresh_filter(false);
        }
        self.timings.filter_refresh += t5.elapsed().as_secs_f64();
    }

    /// Densify / prune / reset opacity when the schedule says so; returns whether the
    /// set of Gaussians changed.
    fn maybe_densify(&mut self, it: usize) -> bool {
        let d = self.config.densify.clone();
        let mut changed = false;
        // Nothing at the last iteration: a run shorter than the schedule must not end
        // on an opacity reset or an unrefined densification.
        if it >= self.config.iterations {
            return false;
        }
        if it >= d.from && it <= d.until && d.every > 0 && it.is_multiple_of(d.every) {
            let big_screen = self.last_reset.is_some();
            let seed = self.config.seed ^ (it as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
            let plan = plan_densify(
                self.model.as_ref(),
                &self.stats,
                &d,
                self.extent,
                big_screen,
                seed,
            );
            self.apply_plan(&plan);
            changed = plan.cloned + plan.split + plan.pruned > 0;
        }
        if d.opacity_reset_every > 0 && it <= d.until && it.is_multiple_of(d.opacity_reset_every) {
            for name in self.model.reset_opacity(0.01) {
                if let Some(m) = self.adam.moments_mut(&name) {
                    m.m.data_mut().fill(0.0);
                    m.v.data_mut().fill(0.0);
                }
            }
            self.last_reset = Some(it);
        }
        changed
    }

    /// Applies a densification plan to the model, its Adam moments, the filter state,
    /// the observations and the statistics with one index list.
    pub fn apply_plan(&mut self, plan: &DensifyPlan) {
        let n_old = self.model.num_gaussians();
        let mut names = Vec::new();
        for slot in self.model.params_mut() {
            if slot.per_gaussian {
                names.push(slot.name.clone());
            }
        }
        self.model.select_rows(&plan.index);
        if !plan.new_rows.is_empty() {
            let k = plan.new_rows.len();
            self.model.set_rows(
                &plan.new_rows,
                &Tensor::from_vec(plan.new_means.clone(), &[k, 3]),
                &Tensor::from_vec(plan.new_scales.clone(), &[k, 3]),
            );
        }
        for name in names {
            if let Some(m) = self.adam.moments_mut(&name)
                && m.rows() == n_old
            {
                m.select_rows(&plan.index);
            }
        }
        self.filter.select_rows(&plan.index);
        self.observations.select_rows(&plan.index);
        self.stats = DensifyStats::new(plan.index.len());
    }

    /// Recomputes the 3D filter (outside the tape): static nu from the canonical
    /// centres for `mip3d`, nu(t) from the recorded observations for `motion`. At the
    /// start (no observations yet) the motion filter runs a full observation pass.
    pub fn refresh_filter(&mut self, at_start: bool) {
        let n = self.model.num_gaussians();
        let cfg = &self.config.filter;
        let centres = |t: &Tensor<f32>| -> Vec<[f32; 3]> {
            t.data()
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        };
        self.filter = match cfg.kind {
            FilterKind::None => FilterState::None { rows: n },
            FilterKind::Mip3d => {
                let canon = centres(&self.model.canonical().means);
                match static_nu(&canon, &self.cameras, cfg) {
                    Ok(nu) => FilterState::Mip3d { s3d: cfg.s3d, nu },
                    Err(e) => {
                        log_line(&format!("filter refresh skipped: {e}"));
                        return;
                    }
                }
            }
            FilterKind::Motion => {
                if at_start {
                    // One deformation pass over every distinct training time (the field
                    // is queried once), then the observation pass looks centres up.
                    let mut times: Vec<f32> = self.frames.iter().map(|f| f.time).collect();
                    times.sort_by(f32::total_cmp);
                    times.dedup();
                    let at: Vec<f64> = times.iter().map(|&t| f64::from(t)).collect();
                    let all = self.model.centres_at_times(&at);
                    let result =
                        self.observations
                            .observe_all(&self.frames, &self.cameras, cfg, |t| {
                                let k = times.partition_point(|&x| x < t).min(all.len() - 1);
                                centres(&all[k])
                            });
                    if let Err(e) = result {
                        log_line(&format!("observation pass failed: {e}"));
                    }
                }
                match MotionCurves::refresh(&self.observations, cfg) {
                    Ok(curves) => FilterState::Motion {
                        s3d: cfg.s3d,
                        curves,
                    },
                    Err(e) => {
                        log_line(&format!("filter refresh skipped: {e}"));
                        return;
                    }
                }
            }
        };
    }

    /// The deformed, filtered Gaussians at `time` as plain tensors, ready for
    /// [`maaf_splat::render_tensors`] (evaluation and rendering of a trained run).
    pub fn frame_at(&self, time: f64) -> [Tensor<f32>; 5] {
        frame_at(
            self.model.as_ref(),
            &self.filter,
            self.config.filter.kind,
            time,
        )
    }
}

/// The deformed Gaussians of `model` at `time` with `filter` folded in:
/// `[means, scales, quats, opacity, sh]` as plain tensors.
pub fn frame_at(
    model: &dyn Representation<f32>,
    filter: &FilterState,
    kind: FilterKind,
    time: f64,
) -> [Tensor<f32>; 5] {
    let tape = Tape::new();
    let g = model.bind(&tape).deform(time);
    let n = model.num_gaussians();
    let (scales, opacity) = if kind == FilterKind::None {
        (g.scales, g.opacity)
    } else {
        apply_3d_filter(
            g.scales,
            g.opacity,
            &Tensor::from_vec(filter.variance_at(time as f32), &[n]),
        )
    };
    let take = |v: maaf_autodiff::Var<'_, f32>| v.value().clone();
    [
        take(g.means),
        take(scales),
        take(g.quats),
        take(opacity),
        take(g.sh),
    ]
}

/// Progress and warnings go to stderr, one line each.
fn log_line(msg: &str) {
    eprintln!("maaf: {msg}");
}
