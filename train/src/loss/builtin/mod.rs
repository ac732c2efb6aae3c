//! The regularisers a config names with a weight, no code (`"terms": {"NAME":
//! weight}`, docs/config.md): each is a [`Term`](super::Term) with its formula, its
//! reference and a slow loop twin in its tests. [`super::TermRegistry::builtin`]
//! registers all of them.

pub mod depth_tv;
pub mod opacity_entropy;
pub mod scale_anisotropy;

pub use depth_tv::{DepthTv, depth_tv};
pub use opacity_entropy::{OpacityEntropy, opacity_entropy};
pub use scale_anisotropy::{ScaleAnisotropy, scale_anisotropy};
