//! maaf: alias-free 4D Gaussian splatting of dynamic scenes on the CPU.
//!
//! This facade re-exports the member crates (docs/architecture.md):
//! [`autodiff`] (reverse-mode tape and gradient checks), [`splat`] (differentiable
//! Gaussian rasterization), [`filter`] (Mip-Splatting and motion-aware smoothing
//! filters), [`scene`] (a trained run as a value), [`eval`] (evaluation, metrics and
//! reports) and [`train`] (data, 4D representations, training), and
//! holds the whole `maaf` command line as a library ([`cli::Maaf`]): a program of a
//! few lines gets every command plus loss terms of its own.
//!
//! The library leaves the global allocator to the program; the `maaf` binary uses
//! mimalloc ([`alloc`]).

pub mod alloc;
pub mod cli;

pub use maaf_autodiff as autodiff;
pub use maaf_eval as eval;
pub use maaf_filter as filter;
pub use maaf_scene as scene;
pub use maaf_splat as splat;
pub use maaf_train as train;
