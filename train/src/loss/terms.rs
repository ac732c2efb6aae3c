//! Named, weighted loss terms and the context they read (docs/architecture.md).

use std::collections::BTreeMap;

use maaf_autodiff::{Float, Tensor, Var};
use maaf_splat::{Camera, GaussianVars};

use super::ssim::ssim;

/// Everything a [`Term`] may read in one training step: the rendered image, alpha and
/// depth, the ground truth, the deformed Gaussians (as `Var`s, before the 3D filter),
/// the camera, the time, the iteration, and named regulariser values provided by the
/// model (e.g. SaRO's `l_sr`). The trainer's context (`Forward::term_ctx`) has all of
/// them; a context built by hand with [`TermCtx::new`] has only the images, and the
/// accessors of the others panic, naming what is missing.
pub struct TermCtx<'t, T: Float> {
    /// Rendered image `[H, W, 3]` on the tape.
    pub render: Var<'t, T>,
    /// Ground-truth image `[H, W, 3]`, a constant on the same tape.
    pub gt: Var<'t, T>,
    /// Training iteration (0-based), for terms with a schedule.
    pub iteration: usize,
    render_extras: Option<(Var<'t, T>, Var<'t, T>)>,
    scene: Option<(GaussianVars<'t, T>, Camera, f64)>,
    extras: BTreeMap<String, Var<'t, T>>,
}

impl<'t, T: Float> TermCtx<'t, T> {
    /// A context for `render`, with `gt` recorded once as a constant on the same tape.
    pub fn new(render: Var<'t, T>, gt: &Tensor<T>) -> Self {
        let gt = render.tape().constant(gt.clone());
        Self::with_gt_var(render, gt)
    }

    /// A context whose ground truth is already on the tape (constant or not).
    pub fn with_gt_var(render: Var<'t, T>, gt: Var<'t, T>) -> Self {
        assert_eq!(
            render.shape(),
            gt.shape(),
            "TermCtx: render and ground truth shapes differ"
        );
        TermCtx {
            render,
            gt,
            iteration: 0,
            render_extras: None,
            scene: None,
            extras: BTreeMap::new(),
        }
    }

    /// The same context at another iteration.
    pub fn at_iteration(mut self, iteration: usize) -> Self {
        self.iteration = iteration;
        self
    }

    /// Adds the render's accumulated opacity `[H, W]` and alpha-weighted depth `[H, W]`.
    pub fn with_render(mut self, alpha: Var<'t, T>, depth: Var<'t, T>) -> Self {
        self.render_extras = Some((alpha, depth));
        self
    }

    /// Adds the deformed Gaussians, the camera and the time of the render.
    pub fn with_scene(mut self, gaussians: GaussianVars<'t, T>, camera: Camera, time: f64) -> Self {
        self.scene = Some((gaussians, camera, time));
        self
    }

    fn missing(what: &str) -> ! {
        panic!(
            "TermCtx: this context has no {what} (it was built with TermCtx::new; the \
             trainer's context from Forward::term_ctx has it)"
        )
    }

    /// Accumulated opacity `1 - T_final` per pixel, `[H, W]`.
    pub fn alpha(&self) -> Var<'t, T> {
        self.render_extras
            .map_or_else(|| Self::missing("alpha"), |r| r.0)
    }

    /// Alpha-weighted camera depth `sum_i z_i alpha_i T_i` per pixel, `[H, W]`.
    pub fn depth(&self) -> Var<'t, T> {
        self.render_extras
            .map_or_else(|| Self::missing("depth"), |r| r.1)
    }

    /// The deformed Gaussians at this step's time, before the 3D filter (the
    /// representation's output: activated scales and opacity).
    pub fn gaussians(&self) -> GaussianVars<'t, T> {
        self.scene
            .as_ref()
            .map_or_else(|| Self::missing("Gaussians"), |s| s.0)
    }

    /// The camera of the render.
    pub fn camera(&self) -> &Camera {
        self.scene
            .as_ref()
            .map_or_else(|| Self::missing("camera"), |s| &s.1)
    }

    /// The time of the render.
    pub fn time(&self) -> f64 {
        self.scene
            .as_ref()
            .map_or_else(|| Self::missing("time"), |s| s.2)
    }

    /// Adds (or replaces) a named value, e.g. a model regulariser (SaRO's `l_sr`).
    pub fn insert(&mut self, name: &str, value: Var<'t, T>) {
        self.extras.insert(name.to_string(), value);
    }

    /// [`TermCtx::insert`] in builder style.
    pub fn with(mut self, name: &str, value: Var<'t, T>) -> Self {
        self.insert(name, value);
        self
    }

    /// The named value, if the model provided it this step.
    pub fn get(&self, name: &str) -> Option<Var<'t, T>> {
        self.extras.get(name).copied()
    }

    /// Names of the provided values, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.extras.keys().map(String::as_str)
    }

    /// A rank-0 constant zero on the context's tape (the value of a term whose input
    /// is absent this step).
    pub fn zero(&self) -> Var<'t, T> {
        self.render.tape().constant(Tensor::scalar(T::zero()))
    }
}

/// One named, weighted part of the objective: the objective adds
/// `weight() * value(ctx)` and logs `value(ctx)` under `name()`.
///
/// Implement it for a new loss or regulariser (about ten lines; see
/// `examples/custom_loss_gradcheck.rs`) and add it with [`super::Objective::with`].
pub trait Term<T: Float>: Send + Sync {
    /// Name used in logs (`log.csv` column); unique within an objective.
    fn name(&self) -> &str;
    /// Weight of the term in the total.
    fn weight(&self) -> f64;
    /// The unweighted value, a rank-0 (or one-element) `Var` on the context's tape.
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T>;
}

/// Mean absolute error `L1 = mean_{i,c} |render - gt|` over pixels and channels
/// (3DGS `l1_loss`).
#[derive(Clone, Debug)]
pub struct L1 {
    /// Weight in the objective (`1 - lambda_dssim = 0.8` for 3DGS / SaRO-GS).
    pub weight: f64,
}

impl<T: Float> Term<T> for L1 {
    fn name(&self) -> &str {
        "l1"
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        (ctx.render - ctx.gt).abs().mean()
    }
}

/// Structural dissimilarity `D-SSIM = 1 - SSIM(render, gt)` with the 3DGS training
/// SSIM ([`super::ssim()`]: 11 x 11 Gaussian window, sigma 1.5, zero-padded "same",
/// mean over pixels and channels).
#[derive(Clone, Debug)]
pub struct DSsim {
    /// Weight in the objective (`lambda_dssim = 0.2` for 3DGS / SaRO-GS).
    pub weight: f64,
}

impl<T: Float> Term<T> for DSsim {
    fn name(&self) -> &str {
        "dssim"
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        (-ssim(ctx.render, ctx.gt)).add_scalar(1.0)
    }
}

/// A regulariser the model computes itself and hands over through
/// [`TermCtx::insert`] under `key` (e.g. SaRO-GS's `l_sr` with weight 8e-6; the
/// trainer adds one per name the representation declares). Its value is 0 on steps where the model does not provide it (e.g. the
/// static warm-up stage, where `L_SR` is inactive).
#[derive(Clone, Debug)]
pub struct Provided {
    /// Log name and context key.
    pub key: String,
    /// Weight in the objective.
    pub weight: f64,
}

impl Provided {
    /// The term reading `key` with `weight`.
    pub fn new(key: &str, weight: f64) -> Self {
        Provided {
            key: key.to_string(),
            weight,
        }
    }
}

impl<T: Float> Term<T> for Provided {
    fn name(&self) -> &str {
        &self.key
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        ctx.get(&self.key).unwrap_or_else(|| ctx.zero())
    }
}

/// A term written as a closure: `Objective::with_fn("alpha_l1", 0.01, |ctx| ctx.alpha().mean())`.
pub struct FnTerm<F> {
    name: String,
    weight: f64,
    f: F,
}

impl<F> FnTerm<F> {
    /// The term `weight * f(ctx)`, logged as `name`.
    pub fn new<T: Float>(name: &str, weight: f64, f: F) -> Self
    where
        F: for<'a, 't> Fn(&'a TermCtx<'t, T>) -> Var<'t, T> + Send + Sync,
    {
        FnTerm {
            name: name.to_string(),
            weight,
            f,
        }
    }
}

impl<T: Float, F> Term<T> for FnTerm<F>
where
    F: for<'a, 't> Fn(&'a TermCtx<'t, T>) -> Var<'t, T> + Send + Sync,
{
    fn name(&self) -> &str {
        &self.name
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        (self.f)(ctx)
    }
}
