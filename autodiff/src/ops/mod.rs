//! Primitive ops. Each file holds one family, forward and backward side by side, with
//! its finite-difference tests inline.

pub mod binary;
mod blocks;
pub mod dense;
pub mod matmul;
pub mod mlp;
pub mod reduce;
pub mod shape;
pub mod unary;

pub use shape::concat;
