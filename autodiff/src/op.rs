//! The operation trait every differentiable step implements.

use crate::{Float, Tensor};

/// What an op's backward sees: its inputs, its outputs, the state its forward saved,
/// the cotangent of every output (zeros for outputs nothing depended on) and which
/// inputs need a gradient.
pub struct BackwardCtx<'a, T: Float, S> {
    /// Input values, in the order they were passed to [`crate::Tape::apply`].
    pub inputs: &'a [&'a Tensor<T>],
    /// Output values as the forward returned them.
    pub outputs: &'a [&'a Tensor<T>],
    /// State saved by the forward.
    pub saved: &'a S,
    /// Cotangent dL/d(output) for each output, same shapes as `outputs`.
    pub grad_outputs: &'a [Tensor<T>],
    /// `needs_grad[i]` is true when input `i` leads to a parameter; a backward may
    /// return `None` for inputs where it is false.
    pub needs_grad: &'a [bool],
}

/// A differentiable operation with a hand-written backward (docs/architecture.md, "Where things plug in").
///
/// `forward` maps input tensors to output tensors and returns whatever it wants to
/// keep for the backward as `Saved`. `backward` returns one entry per input: the
/// vector-Jacobian product `sum_o grad_outputs[o]^T d outputs[o] / d inputs[i]`, or
/// `None` when that input needs no gradient. The tape checks the count and the shapes
/// and names the op in every panic. Check a new op with [`crate::check::gradcheck`]
/// and [`crate::check::check_vjp`].
pub trait Op<T: Float>: Send + Sync + 'static {
    /// State kept from forward to backward.
    type Saved: Send + Sync + 'static;

    /// Name shown in errors and reports.
    fn name(&self) -> String;

    /// Computes the outputs from the inputs.
    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, Self::Saved);

    /// Maps output cotangents to input cotangents (one entry per input).
    fn backward(&self, ctx: &BackwardCtx<'_, T, Self::Saved>) -> Vec<Option<Tensor<T>>>;
}
