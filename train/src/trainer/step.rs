//! One training iteration: forward (the shared pipeline), objective, backward, Adam,
//! statistics (each timed as its own phase, [`maaf_scene::Timings`]), then
//! densification and filter refresh when due.

use maaf_autodiff::{Grads, Tape, Tensor, Var};
use maaf_models::params::BoundParams;
use maaf_splat::RenderSettings;
use maaf_splat::compositing::drawable;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_pcg::Pcg64;

use super::phase::PhaseClock;
use super::region::{background_target, crop, share};
use super::strategy::{RefineStep, StepInfo};
use super::views::TrainViews;
use super::{DensifyGradient, TrainConfig, Trainer, ViewGrad};
use crate::loss::{Evaluated, ForwardTerms, batch_mean};
use maaf_scene::LossRegion;
use maaf_scene::backdrop::over_backdrop;
use maaf_scene::centres;
use maaf_scene::forward::{Forward, forward_bound};

impl Trainer {
    /// Render settings at `iteration` ([`maaf_scene::render_settings`], the 2D filter
    /// chosen by whether the trainer's filter smooths,
    /// [`maaf_filter::SamplingFilter::smooths`]).
    pub fn render_settings(&self, iteration: usize) -> RenderSettings {
        maaf_scene::render_settings(
            &self.config,
            self.background,
            iteration,
            self.sampling.smooths(),
        )
    }

    /// Entry `k` (1-based) of the sequence of training views: views are visited in a
    /// seeded random order that is reshuffled every epoch; the order depends only on
    /// the seed and `k`, so a resumed run sees the same sequence.
    fn view_at(&self, k: usize) -> usize {
        let n = self.views.times.len();
        let epoch = (k - 1) / n;
        let mut order: Vec<usize> = (0..n).collect();
        let mut rng = Pcg64::seed_from_u64(
            self.config.seed ^ (epoch as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
        );
        order.shuffle(&mut rng);
        order[(k - 1) % n]
    }

    /// One training iteration: [`Self::update`] then [`Self::schedule`]. The first
    /// step of a fresh run computes the filter first.
    pub fn step(&mut self) {
        self.update();
        self.schedule();
    }

    /// The training views (indices into the train split) of `iteration` (1-based):
    /// `batch` consecutive entries of the seeded epoch order (SaRO-GS draws its
    /// batches from a shuffled loader the same way), or of the views at the one time
    /// the model trains on then (`trainer/timed.rs`).
    pub fn views_at(&self, iteration: usize) -> Vec<usize> {
        if let Some(at) = self
            .state
            .model
            .hooks()
            .and_then(|h| h.training_time(iteration))
        {
            return self.views_at_time(iteration, at);
        }
        (0..self.config.batch)
            .map(|slot| self.view_at(self.entry(iteration, slot)))
            .collect()
    }

    /// Entry (1-based) of the sequence of training views that the `slot`-th view
    /// (0-based) of `iteration` (1-based) takes.
    pub(super) fn entry(&self, iteration: usize, slot: usize) -> usize {
        (iteration - 1) * self.config.batch + slot + 1
    }

    /// The gradient step of the next iteration: bind, then per view deform, filter,
    /// render and objective ([`Self::forward_batch`]); backward of the views' mean
    /// objective, Adam ([`Self::optimise`]), statistics ([`Self::after_step`]);
    /// advances `iteration`. What it trained is the model to validate at this
    /// iteration, before [`Self::schedule`] densifies or resets opacities.
    pub fn update(&mut self) {
        let mut clock = PhaseClock::start();
        self.ensure_filter();
        let it = self.iteration + 1;
        self.state.model.set_iteration(it);
        self.restart_moments(it);
        let views = self.views_at(it);
        let tape = Tape::new();
        tape.set_validate(self.config.validate);
        tape.set_profile(self.op_profile.is_some());
        let settings = self.render_settings(it);
        clock.lap();

        let params = self.state.model.params().bind(&tape);
        let bound = self.state.model.bind(&params);
        let bind_seconds = clock.lap();
        let batch = self.forward_batch(&tape, bound.as_ref(), &settings, it, views);
        let deform: f64 = batch.fwds.iter().map(|f| f.deform_seconds).sum();
        self.timings.field_mlp += bind_seconds + deform;
        let forward_seconds = clock.lap() - deform;
        let evals: Vec<_> = (batch.fwds.iter().zip(&batch.gts))
            .map(|(fwd, gt)| fwd.objective(&self.objective, gt, it - 1))
            .collect();
        let total = batch.mean_total(&evals);
        self.timings.render_forward += forward_seconds + clock.lap();

        let abs_stat =
            self.config.densify.gradient == DensifyGradient::Abs && it <= self.config.densify.until;
        let (grads, abs_grads) = checked_backward(&tape, total, &batch, abs_stat);
        self.timings.backward += clock.lap();
        match grads {
            Ok(grads) => {
                self.optimise(&grads, it);
                self.timings.optimiser += clock.lap();
                self.after_step(&grads, &batch, &abs_grads, it);
                self.last_terms = mean_terms(&evals);
                self.timings.statistics += clock.lap();
            }
            Err(e) => {
                // A NaN/Inf in the loss or a gradient: the update is skipped so nothing
                // non-finite reaches the parameters (or a checkpoint); counted and logged.
                self.skipped_steps += 1;
                log::warn!("iteration {it}: step skipped: {e}");
                self.last_skip = Some(e);
                self.timings.optimiser += clock.lap();
            }
        }
        if let (Some(total), Some(step)) = (self.op_profile.as_mut(), tape.op_profile()) {
            total.merge(&step);
        }
        drop(batch);
        drop(bound);
        drop(params);
        self.iteration = it;
        clock.finish(&mut self.timings);
    }

    /// Adam on every parameter with a gradient, each at its learning rate of
    /// `iteration` and with the model's per-row scale of it
    /// ([`crate::models::TrainingHooks::lr_row_scale`]), then on the camera colour
    /// correction's parameters.
    fn optimise(&mut self, grads: &Grads<f32>, iteration: usize) {
        let densifying = iteration <= self.config.densify.until;
        let state = &mut self.state;
        let hooks = state.model.hooks();
        let scales: Vec<_> = (state.model.params().iter())
            .map(|p| hooks.and_then(|h| h.lr_row_scale(&p.name, densifying)))
            .collect();
        for (p, scale) in state.model.params_mut().iter_mut().zip(scales) {
            if let Some(gr) = grads.param(&p.name) {
                let lr = p.lr.at(iteration - 1);
                let decay = p.weight_decay;
                (state.adam).step_rows(&p.name, &mut p.value, gr, lr, decay, scale.as_deref());
            }
        }
        for p in self
            .camera_colour
            .iter_mut()
            .flat_map(|c| c.params_mut().iter_mut())
        {
            if let Some(gr) = grads.param(&p.name) {
                let lr = p.lr.at(iteration - 1);
                state
                    .adam
                    .step_rows(&p.name, &mut p.value, gr, lr, 0.0, None);
            }
        }
    }

    /// What a step that was not skipped leaves besides the parameters: the
    /// strategy's statistics ([`super::Strategy::after_backward`]), the liveness
    /// record and, through the filter's own hook
    /// ([`maaf_filter::SamplingFilter::observe`]), the observations of the observed
    /// views.
    fn after_step(
        &mut self,
        grads: &Grads<f32>,
        batch: &Batch<'_>,
        abs_grads: &[Option<Tensor<f32>>],
        iteration: usize,
    ) {
        // Each view's screen-space gradient is that of its own objective (SaRO-GS
        // backpropagates every view's loss before averaging), i.e. `batch` times its
        // share of the mean.
        let seen: Vec<ViewGrad> = (batch.fwds.iter().zip(abs_grads))
            .map(|(fwd, abs)| ViewGrad {
                grad: grads.wrt(fwd.render.means2d),
                abs_grad: abs.as_ref(),
                radii: &fwd.render.radii,
                width: fwd.camera.width,
                height: fwd.camera.height,
            })
            .collect();
        let info = StepInfo {
            iteration,
            views: &seen,
            loss_scale: batch.fwds.len() as f32,
        };
        self.strategy.after_backward(&mut self.state, &info);
        let state = &mut self.state;
        let opacity = state.model.canonical_ids().opacity_logits;
        if let Some(g) = grads.param(&state.model.params().param(opacity).name) {
            state.liveness.record(g.data(), iteration);
        }
        for (fwd, &vi) in batch.fwds.iter().zip(&batch.views) {
            let Some(frame) = self.observed_slot[vi] else {
                continue;
            };
            let centres = centres(&fwd.deformed.means.value());
            // A Gaussian absent at this time is not observed in this frame.
            let present = drawable(fwd.deformed.opacity.value().data());
            let recorded = self.sampling.observe(
                &mut state.observations,
                frame,
                &fwd.camera,
                &centres,
                &present,
                &self.config.filter,
            );
            if let Err(e) = recorded {
                log::warn!("iteration {iteration}: observation not recorded: {e}");
            }
        }
    }

    /// What the schedule does after the gradient step of iteration `iteration`: the
    /// densification strategy's refinement ([`super::Strategy::refine`]:
    /// densification, pruning and opacity reset), then the filter refresh, when due.
    pub fn schedule(&mut self) {
        let it = self.iteration;
        let mut clock = PhaseClock::start();
        let settings = self.render_settings(it);
        let step = refine_step(it, &self.config, self.extent, &self.views, &settings);
        let densified = self.strategy.refine(&mut self.state, &step);
        self.timings.densification += clock.lap();
        let refresh = &self.config.filter.refresh;
        if refresh.due(it as u64, self.config.iterations as u64, densified) {
            self.refresh_filter();
        }
        self.timings.filter_refresh += clock.lap();
        clock.finish(&mut self.timings);
    }

    /// The pruning score of every Gaussian with the settings of `iteration`
    /// ([`super::sensitivity_scores`] over the training views).
    pub fn sensitivity_scores(&self, iteration: usize) -> Result<Vec<f64>, String> {
        let settings = self.render_settings(iteration);
        let step = refine_step(iteration, &self.config, self.extent, &self.views, &settings);
        super::sensitivity_scores(&self.state, &step)
    }
}

/// The record a strategy's refinement gets after `iteration` (from the trainer's
/// fields, so the state and the strategy stay free to borrow mutably).
fn refine_step<'a>(
    iteration: usize,
    config: &'a TrainConfig,
    extent: f64,
    views: &'a TrainViews,
    settings: &'a RenderSettings,
) -> RefineStep<'a> {
    RefineStep {
        iteration,
        config,
        extent,
        cameras: &views.cameras,
        times: &views.times,
        settings,
    }
}

/// One iteration's views, drawn: per view its forward pass, the target its objective
/// compares it with and the share of the view's pixels they cover.
struct Batch<'t> {
    views: Vec<usize>,
    fwds: Vec<Forward<'t, f32>>,
    gts: Vec<Tensor<f32>>,
    shares: Vec<f64>,
    /// The camera colour correction's parameters on the tape, when it is on.
    _colour: Option<BoundParams<'t, f32>>,
}

impl<'t> Batch<'t> {
    /// The views' mean objective; a rectangle's objective counts as the whole view's
    /// with no error outside it (scaled by its share of the pixels).
    fn mean_total(&self, evals: &[Evaluated<'t, f32>]) -> Var<'t, f32> {
        let totals: Vec<_> = (evals.iter().zip(&self.shares))
            .map(|(e, &share)| {
                if share < 1.0 {
                    e.total.scale(share)
                } else {
                    e.total
                }
            })
            .collect();
        batch_mean(&totals)
    }
}

/// Per view of a batch, the gradient of the absolute screen means, when requested.
type AbsGrads = Vec<Option<Tensor<f32>>>;

/// Backward of `total` with the screen means' absolute gradients requested when
/// `abs_stat`; the gradients, or why they cannot be used (the tape's error, a
/// non-finite loss, or the first parameter whose gradient is not finite), and each
/// view's absolute gradient.
fn checked_backward(
    tape: &Tape<f32>,
    total: Var<'_, f32>,
    batch: &Batch<'_>,
    abs_stat: bool,
) -> (Result<Grads<f32>, String>, AbsGrads) {
    if abs_stat {
        for fwd in &batch.fwds {
            fwd.render.abs_means2d.request();
        }
    }
    let grads = tape.backward(total);
    let abs_grads = (batch.fwds.iter())
        .map(|fwd| fwd.render.abs_means2d.take())
        .collect();
    let finite = |t: &Tensor<f32>| t.first_non_finite().is_none();
    let grads = grads.map_err(|e| e.to_string()).and_then(|gr| {
        let loss = total.value().item();
        if !loss.is_finite() {
            return Err(format!("non-finite loss ({loss})"));
        }
        match (gr.param_names().into_iter()).find(|p| !gr.param(p).is_none_or(finite)) {
            Some(name) => Err(format!("non-finite gradient of `{name}`")),
            None => Ok(gr),
        }
    });
    (grads, abs_grads)
}

impl Trainer {
    /// The forward passes of `views` as iteration `iteration` draws them
    /// ([`Self::view_pass`]), with the camera colour correction applied to each
    /// render and, for `loss_region = background`, each target replaced by its
    /// background part ([`background_target`]).
    fn forward_batch<'t>(
        &self,
        tape: &'t Tape<f32>,
        bound: &dyn maaf_models::Bound<'t, f32>,
        settings: &RenderSettings,
        iteration: usize,
        views: Vec<usize>,
    ) -> Batch<'t> {
        let mut fwds = Vec::with_capacity(views.len());
        let mut gts = Vec::with_capacity(views.len());
        let mut shares = Vec::with_capacity(views.len());
        for (slot, &vi) in views.iter().enumerate() {
            let (fwd, gt, share) = self.view_pass(bound, settings, iteration, slot, vi);
            fwds.push(fwd);
            gts.push(gt);
            shares.push(share);
        }
        let colour = self.camera_colour.as_ref().map(|c| c.bind(tape));
        if let (Some(correction), Some(bound)) = (&self.camera_colour, &colour) {
            for (fwd, &vi) in fwds.iter_mut().zip(&views) {
                fwd.render.image = correction.apply(bound, vi, fwd.render.image);
            }
        }
        if self.config.loss_region == LossRegion::Background {
            for ((fwd, gt), &vi) in fwds.iter().zip(&mut gts).zip(&views) {
                *gt = background_target(gt, &fwd.render.image.value(), &self.views.masks[vi]);
            }
        }
        Batch {
            views,
            fwds,
            gts,
            shares,
            _colour: colour,
        }
    }

    /// The forward pass of training view `view` as the `slot`-th view of `iteration`
    /// and what its objective compares it with: the view's camera, with
    /// `loss_region = foreground` on the window around its mask only
    /// ([`super::region::window_around`]); the model drawn on the view's background, or on
    /// black over the background layer's render ([`maaf_scene::backdrop`]); the
    /// ground truth (recomposited with `random_background`) on the same pixels; and
    /// the share of the view's pixels they cover.
    fn view_pass<'t>(
        &self,
        bound: &dyn maaf_models::Bound<'t, f32>,
        settings: &RenderSettings,
        iteration: usize,
        slot: usize,
        view: usize,
    ) -> (Forward<'t, f32>, Tensor<f32>, f64) {
        let (background, target) = self.view_target(iteration, slot, view);
        let window = self.views.crops.get(view).copied().flatten();
        let camera = &self.views.cameras[view];
        let background = match self.backdrop {
            Some(_) => [0.0; 3],
            None => background.map(f64::from),
        };
        let settings = RenderSettings {
            background,
            window,
            ..settings.clone()
        };
        let time = self.views.times[view];
        let mut fwd = forward_bound(bound, &self.state.filter, camera, time, &settings);
        if let Some(layer) = &self.backdrop {
            let image = layer.image(view);
            let behind = window.map_or_else(|| image.clone(), |w| crop(image, &w));
            fwd.render.image = over_backdrop(fwd.render.image, fwd.render.alpha, behind);
        }
        let gt = target.unwrap_or_else(|| self.views.gts[view].clone());
        match window {
            Some(w) => (fwd, crop(&gt, &w), share(&w, camera.width, camera.height)),
            None => (fwd, gt, 1.0),
        }
    }
}

/// The mean over the views of each objective term and of the total, by name (the
/// terms of one iteration's log row).
fn mean_terms(evals: &[Evaluated<'_, f32>]) -> Vec<(String, f64)> {
    let n = evals.len() as f64;
    let mut terms: Vec<(String, f64)> = evals[0]
        .terms
        .iter()
        .map(|t| (t.name.clone(), 0.0))
        .chain(std::iter::once(("total".to_string(), 0.0)))
        .collect();
    for e in evals {
        let values = e.terms.iter().map(|t| t.value).chain([e.total_value()]);
        for (slot, v) in terms.iter_mut().zip(values) {
            slot.1 += v / n;
        }
    }
    terms
}
