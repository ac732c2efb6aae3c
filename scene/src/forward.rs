//! One forward pass of the pipeline (docs/architecture.md): deform at t, fold the 3D
//! filter in, render; then, for training, the objective on that render
//! (`maaf_train::loss::ForwardTerms`, the trainer's side of the same pass).
//!
//! This is the only place the pipeline is written: `Trainer::step`, evaluation
//! rendering and the end-to-end gradient check all call [`forward`], so the check
//! checks the step that trains.
//!
//! ```text
//! bound    = model.bind(params)                       // time-independent work, once per step
//! deformed = bound.deform(t)                          // GaussianVars, per view
//! filtered = fold_filter(deformed, filter, t)         // Sigma + var(t) I, opacity compensation
//! render   = maaf_splat::render(filtered, camera)     // image, alpha, depth, means2d, radii
//! loss     = objective(TermCtx{render, gt, deformed, camera, t, iteration, regularisers})
//! ```

use std::time::Instant;

use maaf_autodiff::{Float, Tensor, Var};
use maaf_filter::{FilterKind, FilterState};
use maaf_splat::{Camera, GaussianVars, RenderOutput, RenderSettings, SplatFloat, apply_3d_filter};

use maaf_models::params::BoundParams;
use maaf_models::{Bound, Representation};

/// What one forward pass at (camera, time) produced.
pub struct Forward<'t, T: Float> {
    /// The representation's Gaussians at `time`, before the 3D filter.
    pub deformed: GaussianVars<'t, T>,
    /// What the renderer drew: `deformed` with the 3D filter folded in.
    pub filtered: GaussianVars<'t, T>,
    /// The render (image, alpha, depth, screen means, radii).
    pub render: RenderOutput<'t, T>,
    /// The representation's regularisers this step, by name.
    pub regularisers: Vec<(String, Var<'t, T>)>,
    /// The camera.
    pub camera: Camera,
    /// The time.
    pub time: f64,
    /// Wall seconds spent binding and deforming (field and MLPs).
    pub deform_seconds: f64,
    /// Wall seconds spent in the filter fold and the renderer.
    pub render_seconds: f64,
}

/// The 3D smoothing filter folded into `g` at `time`: `Sigma' = Sigma + var I` with
/// the opacity compensation `sqrt(det Sigma / det Sigma')` (paper Eq. 2-3; the
/// variance is `s / nu^2`, static or nu(t), from `filter`). No filter: `g` unchanged.
pub fn fold_filter<'t, T: Float>(
    g: GaussianVars<'t, T>,
    filter: &FilterState,
    time: f64,
) -> GaussianVars<'t, T> {
    if filter.kind() == FilterKind::None {
        return g;
    }
    let var: Vec<T> = filter
        .variance_at(time as f32)
        .into_iter()
        .map(|v| T::of(f64::from(v)))
        .collect();
    let n = var.len();
    let (scales, opacity) = apply_3d_filter(g.scales, g.opacity, &Tensor::from_vec(var, &[n]));
    GaussianVars {
        scales,
        opacity,
        ..g
    }
}

/// The Gaussians of `model` (bound through `params`) at `time`, before the 3D
/// filter, and the regularisers of the binding.
pub fn deform<'t, T: Float>(
    model: &dyn Representation<T>,
    params: &BoundParams<'t, T>,
    time: f64,
) -> (GaussianVars<'t, T>, Vec<(String, Var<'t, T>)>) {
    let bound = model.bind(params);
    (bound.deform(time), bound.regularisers())
}

/// The deformed, filtered Gaussians of `model` at `time` as plain tensors
/// `[means, scales, quats, opacity, sh]` (what the renderer draws; evaluation,
/// export and tests read them).
pub fn gaussians_at<T: Float>(
    model: &dyn Representation<T>,
    filter: &FilterState,
    time: f64,
) -> [Tensor<T>; 5] {
    frame(model, Some(filter), time)
}

/// The deformed Gaussians of `model` at `time` before the 3D filter, as plain tensors
/// `[means, scales, quats, opacity, sh]` (what [`fold_filter`] receives).
pub fn deformed_at<T: Float>(model: &dyn Representation<T>, time: f64) -> [Tensor<T>; 5] {
    frame(model, None, time)
}

/// The Gaussians of `model` at `time` on a tape of constants, with `filter` folded in
/// when given.
fn frame<T: Float>(
    model: &dyn Representation<T>,
    filter: Option<&FilterState>,
    time: f64,
) -> [Tensor<T>; 5] {
    let tape = maaf_autodiff::Tape::new();
    let params = model.params().bind_constants(&tape);
    let (g, _) = deform(model, &params, time);
    let g = match filter {
        Some(filter) => fold_filter(g, filter, time),
        None => g,
    };
    [g.means, g.scales, g.quats, g.opacity, g.sh].map(|v| v.value().clone())
}

/// Deforms `model` (bound through `params`) at `time`, folds `filter` in and renders
/// from `camera`: the pipeline of a training step, of evaluation and of the
/// end-to-end gradient check.
pub fn forward<'t, T: SplatFloat>(
    model: &dyn Representation<T>,
    params: &BoundParams<'t, T>,
    filter: &FilterState,
    camera: &Camera,
    time: f64,
    settings: &RenderSettings,
) -> Forward<'t, T> {
    let t0 = Instant::now();
    let bound = model.bind(params);
    let bind_seconds = t0.elapsed().as_secs_f64();
    let mut out = forward_bound(bound.as_ref(), filter, camera, time, settings);
    out.deform_seconds += bind_seconds;
    out
}

/// [`forward`] from a model already bound on the tape: a batch of views at several
/// times shares one binding (and the regulariser values it computed), so the
/// time-independent work of the representation is done once per training iteration.
pub fn forward_bound<'t, T: SplatFloat>(
    bound: &dyn Bound<'t, T>,
    filter: &FilterState,
    camera: &Camera,
    time: f64,
    settings: &RenderSettings,
) -> Forward<'t, T> {
    let t0 = Instant::now();
    let deformed = bound.deform(time);
    let t1 = Instant::now();
    let filtered = fold_filter(deformed, filter, time);
    let tape = deformed.means.tape();
    let render = maaf_splat::render(tape, &filtered, camera, settings);
    Forward {
        deformed,
        filtered,
        render,
        regularisers: bound.regularisers(),
        camera: camera.clone(),
        time,
        deform_seconds: (t1 - t0).as_secs_f64(),
        render_seconds: t1.elapsed().as_secs_f64(),
    }
}
