//! The tape: records ops in program order and sweeps them in reverse.

use std::cell::{Ref, RefCell};
use std::collections::HashMap;
use std::marker::PhantomData;
use std::ops::Range;
use std::time::Instant;

use smallvec::SmallVec;

use crate::grads::Grads;
use crate::op::{BackwardCtx, Op};
use crate::profile::OpProfile;
use crate::{Float, Tensor};

/// A value recorded on a tape. Cheap to copy; all arithmetic on it is recorded.
#[derive(Clone, Copy)]
pub struct Var<'t, T: Float> {
    tape: &'t Tape<T>,
    id: usize,
}

/// A non-finite value found by a tape in `validate` mode, or a loss that is not finite.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TapeError {
    /// A forward output held NaN or Inf.
    #[error(
        "op `{op}` produced a non-finite value {value} in output {output} at flat index {index}"
    )]
    Forward {
        /// Name of the op.
        op: String,
        /// Which output of the op.
        output: usize,
        /// Flat index of the first bad element.
        index: usize,
        /// The bad value, as f64.
        value: f64,
    },
    /// A backward returned a NaN or Inf cotangent.
    #[error(
        "backward of op `{op}` produced a non-finite cotangent {value} for input {input} at flat index {index}"
    )]
    Backward {
        /// Name of the op.
        op: String,
        /// Which input of the op.
        input: usize,
        /// Flat index of the first bad element.
        index: usize,
        /// The bad value, as f64.
        value: f64,
    },
}

struct Node<T> {
    value: Tensor<T>,
    requires_grad: bool,
}

/// Object-safe wrapper around an [`Op`] and the state its forward saved.
trait Recorded<T: Float>: Send + Sync {
    fn name(&self) -> String;
    fn backward(
        &self,
        inputs: &[&Tensor<T>],
        outputs: &[&Tensor<T>],
        grad_outputs: &[Tensor<T>],
        needs_grad: &[bool],
    ) -> Vec<Option<Tensor<T>>>;
}

struct WithSaved<T: Float, O: Op<T>> {
    op: O,
    saved: O::Saved,
    _t: PhantomData<fn() -> T>,
}

impl<T: Float, O: Op<T>> Recorded<T> for WithSaved<T, O> {
    fn name(&self) -> String {
        self.op.name()
    }
    fn backward(
        &self,
        inputs: &[&Tensor<T>],
        outputs: &[&Tensor<T>],
        grad_outputs: &[Tensor<T>],
        needs_grad: &[bool],
    ) -> Vec<Option<Tensor<T>>> {
        let ctx = BackwardCtx {
            inputs,
            outputs,
            saved: &self.saved,
            grad_outputs,
            needs_grad,
        };
        self.op.backward(&ctx)
    }
}

struct Record<T: Float> {
    op: Box<dyn Recorded<T>>,
    inputs: SmallVec<[usize; 4]>,
    outputs: Range<usize>,
}

#[derive(Default)]
struct Inner<T: Float> {
    nodes: Vec<Node<T>>,
    records: Vec<Record<T>>,
    params: HashMap<String, usize>,
    validate: bool,
    first_error: Option<TapeError>,
    profile: Option<OpProfile>,
}

/// A reverse-mode tape over tensors of `T` (docs/architecture.md). Build one per
/// training step: register parameters with [`Tape::param`], compute with [`Var`]
/// methods or [`Tape::apply`], then call [`Tape::backward`].
pub struct Tape<T: Float> {
    inner: RefCell<Inner<T>>,
}

impl<T: Float> Default for Tape<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Float> Tape<T> {
    /// An empty tape.
    pub fn new() -> Self {
        Tape {
            inner: RefCell::new(Inner {
                nodes: Vec::new(),
                records: Vec::new(),
                params: HashMap::new(),
                validate: false,
                first_error: None,
                profile: None,
            }),
        }
    }

    /// Turns on validate mode: every forward output and every cotangent is scanned for
    /// NaN/Inf, and the first one found is reported (op name, output or input, index)
    /// by [`Tape::check_finite`] and [`Tape::backward`].
    pub fn set_validate(&self, on: bool) {
        self.inner.borrow_mut().validate = on;
    }

    /// Turns on profile mode: the wall time of every op's forward and backward is
    /// summed by op name; read it with [`Tape::op_profile`].
    pub fn set_profile(&self, on: bool) {
        self.inner.borrow_mut().profile = on.then(OpProfile::default);
    }

    /// The op times recorded so far in profile mode (`None` when it is off).
    pub fn op_profile(&self) -> Option<OpProfile> {
        self.inner.borrow().profile.clone()
    }

    /// A named leaf that needs a gradient; read it back with [`Grads::param`].
    /// Panics if the name is already used on this tape.
    pub fn param(&self, name: &str, value: Tensor<T>) -> Var<'_, T> {
        let id = self.push_leaf(value, true);
        let previous = self.inner.borrow_mut().params.insert(name.to_string(), id);
        assert!(
            previous.is_none(),
            "Tape::param: parameter `{name}` registered twice"
        );
        Var { tape: self, id }
    }

    /// An anonymous leaf that needs a gradient (read it with [`Grads::wrt`]).
    pub fn var(&self, value: Tensor<T>) -> Var<'_, T> {
        let id = self.push_leaf(value, true);
        Var { tape: self, id }
    }

    /// A constant leaf: it never receives a gradient.
    pub fn constant(&self, value: Tensor<T>) -> Var<'_, T> {
        let id = self.push_leaf(value, false);
        Var { tape: self, id }
    }

    fn push_leaf(&self, value: Tensor<T>, requires_grad: bool) -> usize {
        let mut inner = self.inner.borrow_mut();
        if inner.validate
            && inner.first_error.is_none()
            && let Some(index) = value.first_non_finite()
        {
            inner.first_error = Some(TapeError::Forward {
                op: "leaf".into(),
                output: 0,
                index,
                value: value.data()[index].to_f64(),
            });
        }
        inner.nodes.push(Node {
            value,
            requires_grad,
        });
        inner.nodes.len() - 1
    }

    /// Number of values recorded so far.
    pub fn len(&self) -> usize {
        self.inner.borrow().nodes.len()
    }

    /// True when nothing is recorded.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Runs `op` forward on `inputs` and records it; returns one [`Var`] per output.
    pub fn apply<O: Op<T>>(&self, op: O, inputs: &[Var<'_, T>]) -> Vec<Var<'_, T>> {
        for v in inputs {
            assert!(
                std::ptr::eq(v.tape, self),
                "op `{}`: input from another tape",
                op.name()
            );
        }
        let started = self.inner.borrow().profile.is_some().then(Instant::now);
        let (outputs, saved) = {
            let inner = self.inner.borrow();
            let values: SmallVec<[&Tensor<T>; 4]> =
                inputs.iter().map(|v| &inner.nodes[v.id].value).collect();
            op.forward(&values)
        };
        let mut inner = self.inner.borrow_mut();
        if let (Some(t0), Some(profile)) = (started, inner.profile.as_mut()) {
            profile.add_forward(op.name(), t0.elapsed().as_secs_f64());
        }
        let requires_grad = inputs.iter().any(|v| inner.nodes[v.id].requires_grad);
        if inner.validate && inner.first_error.is_none() {
            for (output, t) in outputs.iter().enumerate() {
                if let Some(index) = t.first_non_finite() {
                    inner.first_error = Some(TapeError::Forward {
                        op: op.name(),
                        output,
                        index,
                        value: t.data()[index].to_f64(),
                    });
                    break;
                }
            }
        }
        let start = inner.nodes.len();
        for value in outputs {
            inner.nodes.push(Node {
                value,
                requires_grad,
            });
        }
        let end = inner.nodes.len();
        if requires_grad {
            inner.records.push(Record {
                op: Box::new(WithSaved {
                    op,
                    saved,
                    _t: PhantomData,
                }),
                inputs: inputs.iter().map(|v| v.id).collect(),
                outputs: start..end,
            });
        }
        (start..end).map(|id| Var { tape: self, id }).collect()
    }

    /// [`Tape::apply`] for an op with exactly one output.
    pub fn apply1<O: Op<T>>(&self, op: O, inputs: &[Var<'_, T>]) -> Var<'_, T> {
        let name = op.name();
        let out = self.apply(op, inputs);
        assert_eq!(
            out.len(),
            1,
            "op `{name}` returned {} outputs, expected 1",
            out.len()
        );
        out[0]
    }

    /// The first non-finite value seen in validate mode, if any.
    pub fn check_finite(&self) -> Result<(), TapeError> {
        match &self.inner.borrow().first_error {
            Some(e) => Err(e.clone()),
            None => Ok(()),
        }
    }

    /// Reverse sweep from a one-element `loss` seeded with 1.
    pub fn backward(&self, loss: Var<'_, T>) -> Result<Grads<T>, TapeError> {
        let n = loss.value().len();
        assert_eq!(
            n, 1,
            "Tape::backward: loss must have one element, it has {n}"
        );
        let seed = Tensor::full(&loss.shape(), T::one());
        self.backward_from(&[(loss, seed)])
    }

    /// Reverse sweep seeded with the given cotangents (vector-Jacobian products of
    /// several outputs at once). Cotangents always accumulate, so a value used twice
    /// receives the sum of both paths.
    pub fn backward_from(&self, seeds: &[(Var<'_, T>, Tensor<T>)]) -> Result<Grads<T>, TapeError> {
        self.check_finite()?;
        let mut profile = self.inner.borrow_mut().profile.take();
        let result = self.sweep(seeds, &mut profile);
        self.inner.borrow_mut().profile = profile;
        result
    }

    /// The reverse sweep of [`Tape::backward_from`]; adds backward times to `profile`.
    fn sweep(
        &self,
        seeds: &[(Var<'_, T>, Tensor<T>)],
        profile: &mut Option<OpProfile>,
    ) -> Result<Grads<T>, TapeError> {
        let inner = self.inner.borrow();
        let mut grads: Vec<Option<Tensor<T>>> = (0..inner.nodes.len()).map(|_| None).collect();
        for (var, seed) in seeds {
            let node = &inner.nodes[var.id];
            assert_eq!(
                node.value.shape(),
                seed.shape(),
                "backward: seed shape mismatch"
            );
            if let Some(index) = seed.first_non_finite() {
                return Err(TapeError::Backward {
                    op: "seed".into(),
                    input: 0,
                    index,
                    value: seed.data()[index].to_f64(),
                });
            }
            if node.requires_grad {
                accumulate(&mut grads[var.id], seed.clone());
            }
        }
        for record in inner.records.iter().rev() {
            if record.outputs.clone().all(|o| grads[o].is_none()) {
                continue;
            }
            let needs_grad: SmallVec<[bool; 4]> = record
                .inputs
                .iter()
                .map(|&i| inner.nodes[i].requires_grad)
                .collect();
            // Move the output cotangents out (no copy) and put them back afterwards so
            // `Grads::wrt` still sees them; missing ones become zeros.
            let grad_outputs: Vec<Tensor<T>> = record
                .outputs
                .clone()
                .map(|o| {
                    grads[o]
                        .take()
                        .unwrap_or_else(|| Tensor::zeros(inner.nodes[o].value.shape()))
                })
                .collect();
            let inputs: SmallVec<[&Tensor<T>; 4]> = record
                .inputs
                .iter()
                .map(|&i| &inner.nodes[i].value)
                .collect();
            let outputs: SmallVec<[&Tensor<T>; 4]> = record
                .outputs
                .clone()
                .map(|o| &inner.nodes[o].value)
                .collect();
            let name = || record.op.name();
            let started = profile.is_some().then(Instant::now);
            let input_grads = record
                .op
                .backward(&inputs, &outputs, &grad_outputs, &needs_grad);
            if let (Some(t0), Some(p)) = (started, profile.as_mut()) {
                p.add_backward(name(), t0.elapsed().as_secs_f64());
            }
            for (o, g) in record.outputs.clone().zip(grad_outputs) {
                grads[o] = Some(g);
            }
            assert_eq!(
                input_grads.len(),
                inputs.len(),
                "backward of op `{}` returned {} gradients for {} inputs",
                name(),
                input_grads.len(),
                inputs.len()
            );
            for (k, (g, &input)) in input_grads.into_iter().zip(&record.inputs).enumerate() {
                let Some(g) = g else { continue };
                if !needs_grad[k] {
                    continue;
                }
                assert_eq!(
                    g.shape(),
                    inner.nodes[input].value.shape(),
                    "backward of op `{}`: gradient {k} has the wrong shape",
                    name()
                );
                if inner.validate
                    && let Some(index) = g.first_non_finite()
                {
                    return Err(TapeError::Backward {
                        op: name(),
                        input: k,
                        index,
                        value: g.data()[index].to_f64(),
                    });
                }
                accumulate(&mut grads[input], g);
            }
        }
        Ok(Grads {
            by_node: grads,
            params: inner.params.clone(),
        })
    }
}

/// Adds `g` into `slot`; the first cotangent of a value is moved in, not copied.
fn accumulate<T: Float>(slot: &mut Option<Tensor<T>>, g: Tensor<T>) {
    match slot {
        Some(acc) => acc.add_assign(&g),
        None => *slot = Some(g),
    }
}

impl<'t, T: Float> Var<'t, T> {
    /// The tape this value lives on.
    pub fn tape(&self) -> &'t Tape<T> {
        self.tape
    }

    /// Node index on the tape.
    pub fn id(&self) -> usize {
        self.id
    }

    /// The value (borrowed from the tape).
    pub fn value(&self) -> Ref<'t, Tensor<T>> {
        Ref::map(self.tape.inner.borrow(), |inner| {
            &inner.nodes[self.id].value
        })
    }

    /// The shape of the value.
    pub fn shape(&self) -> SmallVec<[usize; 4]> {
        self.value().shape().into()
    }

    /// Whether a gradient flows into this value.
    pub fn requires_grad(&self) -> bool {
        self.tape.inner.borrow().nodes[self.id].requires_grad
    }

    /// The same value as a constant: no gradient flows back through it.
    pub fn detach(self) -> Var<'t, T> {
        let value = self.value().clone();
        self.tape.constant(value)
    }
}
