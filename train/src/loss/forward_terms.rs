//! The training side of one forward pass ([`maaf_scene::forward`]): the context a
//! loss term sees, the objective on the render, and the mean over a batch of views.

use maaf_autodiff::{Float, Tensor, Var};
use maaf_scene::forward::Forward;

use super::{Evaluated, Objective, TermCtx};

/// What the trainer evaluates on a [`Forward`]: implemented for it, so a training
/// step and the end-to-end gradient check call `fwd.objective(..)` on the pass.
pub trait ForwardTerms<'t, T: Float> {
    /// The context a loss term sees: render, alpha, depth, the ground truth `gt`
    /// (recorded as a constant), the deformed Gaussians, camera, time, `iteration`
    /// (0-based) and the regularisers by name.
    fn term_ctx(&self, gt: &Tensor<T>, iteration: usize) -> TermCtx<'t, T>;

    /// The objective on this render against `gt` at `iteration` (0-based).
    fn objective(
        &self,
        objective: &Objective<T>,
        gt: &Tensor<T>,
        iteration: usize,
    ) -> Evaluated<'t, T>;
}

impl<'t, T: Float> ForwardTerms<'t, T> for Forward<'t, T> {
    fn term_ctx(&self, gt: &Tensor<T>, iteration: usize) -> TermCtx<'t, T> {
        let mut ctx = TermCtx::new(self.render.image, gt)
            .at_iteration(iteration)
            .with_render(self.render.alpha, self.render.depth)
            .with_scene(self.deformed, self.camera.clone(), self.time);
        for (name, value) in &self.regularisers {
            ctx.insert(name, *value);
        }
        ctx
    }

    fn objective(
        &self,
        objective: &Objective<T>,
        gt: &Tensor<T>,
        iteration: usize,
    ) -> Evaluated<'t, T> {
        objective.evaluate(&self.term_ctx(gt, iteration))
    }
}

/// The objective of a batch of views: the mean of their totals, so the gradient is
/// the mean of the views' gradients (SaRO-GS `set_batch_gradient`); one view is its
/// own total, unchanged.
///
/// # Panics
/// If `totals` is empty.
pub fn batch_mean<'t, T: Float>(totals: &[Var<'t, T>]) -> Var<'t, T> {
    match totals {
        [] => panic!("batch_mean: no views"),
        [one] => *one,
        [first, rest @ ..] => {
            let sum = rest.iter().fold(*first, |acc, &v| acc + v);
            sum.scale(1.0 / totals.len() as f64)
        }
    }
}
