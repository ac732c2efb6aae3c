//! maaf-splat: differentiable 3D Gaussian splatting on the CPU.
//!
//! Conventions (docs/conventions.md): cameras use OpenCV axes (x right, y down,
//! z forward), a world-to-camera 4x4 matrix and pinhole intrinsics in pixels with
//! pixel centres at `(x + 0.5, y + 0.5)`. Gaussians are `means [N,3]`, activated
//! `scales [N,3]`, `quats [N,4]` (w,x,y,z, normalised inside), activated
//! `opacity [N]` and `sh [N,K,3]`.
//!
//! The pipeline ([`render()`]) is four ops, each with a hand-written backward next to
//! its forward and generic over f32/f64: [`cov3d::QuatScaleToCov`],
//! [`project::ProjectEwa`] (frustum clamp, 2D filter), [`sh::ShColor`] and
//! [`rasterize::Rasterize`] (16x16 tiles, per-tile depth sort, deterministic parallel
//! backward). [`apply_3d_filter`] folds the Mip-Splatting 3D filter into scales and
//! opacity. [`reference`](mod@reference) holds slow independent versions used as test oracles.

// Index loops are the clearest way to write the small matrix algebra here.
#![allow(clippy::needless_range_loop)]

pub mod binning;
mod blend;
pub mod camera;
pub mod compositing;
pub mod cov3d;
pub mod filter3d;
pub mod gaussians;
pub mod lanes;
pub mod math;
pub mod output;
pub mod ply;
pub mod project;
pub mod rasterize;
pub mod reference;
pub mod render;
pub mod sh;

pub use camera::{Camera, CameraError};
pub use compositing::AlphaCutoff;
pub use filter3d::apply_3d_filter;
pub use gaussians::{Gaussians, render_gaussians};
pub use lanes::SplatFloat;
pub use math::quat_to_rotmat;
pub use ply::{PlyError, VertexTable, read_ply, read_vertex_table, write_baked_ply, write_ply};
pub use project::Filter2d;
pub use render::{
    GaussianVars, RenderOutput, RenderSettings, RenderedFrame, Window, render, render_tensors,
};
