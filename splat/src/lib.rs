//! maaf-splat: differentiable 3D Gaussian splatting on the CPU.
//!
//! Conventions (DESIGN.md section 3): cameras use OpenCV axes (x right, y down,
//! z forward), a world-to-camera 4x4 matrix and pinhole intrinsics in pixels with
//! pixel centres at `(x + 0.5, y + 0.5)`.

pub mod camera;

pub use camera::{Camera, CameraError};
