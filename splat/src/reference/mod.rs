//! Slow, obviously-correct reference implementations (docs/conventions.md), written
//! independently of the fast path: no tiles, no binning, no shared kernels.
//!
//! * [`render`]: per-pixel, per-Gaussian forward oracle over all Gaussians in global
//!   `(depth, index)` order, with the same rules as the fast path (used to test it
//!   to 1e-5 in f32).
//! * [`tape`]: the same stages built from differentiable primitives of
//!   `maaf-autodiff`, used as `check_vjp` references for the hand-written backwards
//!   (the rasterizer only in [`crate::AlphaCutoff::Smooth`] mode, which primitives can
//!   express).

mod composite;
mod stages;
pub mod tape;

pub use composite::render;
pub use stages::{Projected2d, RefSplat, covariance, project, sh_colour};
