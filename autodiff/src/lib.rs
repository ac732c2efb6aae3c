//! maaf-autodiff: a small reverse-mode tape for tensors of f32 or f64.
//!
//! A [`Tape`] records operations in program order; [`Tape::backward`] sweeps it in
//! reverse, accumulating cotangents (so fan-out is handled), and returns [`Grads`]
//! keyed by node and by parameter name. Every operation, primitive or user-defined,
//! implements [`Op`]: a forward over input slices that returns outputs plus a saved
//! state, and a backward that maps output cotangents to input cotangents.
//! [`check`] verifies a backward against central finite differences ([`check::gradcheck`])
//! or against a reference built from primitives ([`check::check_vjp`]).
//!
//! ```
//! use maaf_autodiff::{Tape, Tensor};
//! let tape = Tape::<f64>::new();
//! let x = tape.param("x", Tensor::from_vec(vec![1.0, 2.0, 3.0], &[3]));
//! let loss = x.square().sum();
//! let grads = tape.backward(loss).unwrap();
//! assert_eq!(grads.param("x").unwrap().data(), &[2.0, 4.0, 6.0]);
//! ```

pub mod check;
mod float;
mod grads;
pub mod nn;
pub mod op;
pub mod ops;
pub mod optim;
mod per_gaussian;
pub mod profile;
pub mod scalar;
mod tape;
mod tensor;

pub use float::{Float, MatMut, MatRef};
pub use grads::Grads;
pub use op::{BackwardCtx, Op};
pub use per_gaussian::PerGaussian;
pub use profile::{OpProfile, OpTime};
pub use tape::{Tape, TapeError, Var};
pub use tensor::Tensor;
