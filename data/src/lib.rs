//! maaf-data: the D-NeRF and Plenoptic Video loaders, multi-scale ground truth, the built-in synthetic dynamic
//! scene generator and the data-set summary (docs/conventions.md).
//!
//! - [`dnerf`]: `transforms_{train,val,test}.json` parsing, OpenGL to OpenCV cameras.
//! - [`n3dv`]: Plenoptic Video `poses_bounds.npy` and `camXX/images/`, LLFF to OpenCV.
//! - [`shell`]: initial static points on a capture dome's wall and floor.
//! - [`dynamic3dgs`]: the Dynamic 3D Gaussians layout (CMU Panoptic): `train_meta.json`,
//!   `test_meta.json`, per-frame intrinsics and world-to-camera matrices.
//! - [`visual_hull`]: initial points carved from foreground masks when none ship.
//! - [`median_mask`]: moving pixels by background subtraction against a temporal median.
//! - [`downsample`]: integer box downsampling of premultiplied RGBA, then compositing.
//! - [`dataset`]: [`Dataset`], views at any integer-ratio scale, cached per scale,
//!   composited on a [`Background`].
//! - [`format`]: layouts of one's own ([`DataFormat`]) that [`Dataset::open_with`]
//!   reads after the built-in ones.
//! - [`synthetic`]: the procedural alias-prone scene behind `maaf generate`.
//! - [`inspect`]: the summary behind `maaf inspect`.
//! - [`points`]: the initial point cloud a data set may ship (`points3d.ply`).
//! - [`PointCloud`]: the coloured points a representation starts from.

mod background;
pub mod bounds;
pub mod dataset;
pub mod dnerf;
pub mod downsample;
pub mod dynamic3dgs;
pub mod error;
pub mod flow;
pub mod format;
pub mod image;
pub mod inspect;
pub mod median_mask;
pub mod n3dv;
mod point_cloud;
pub mod points;
pub mod shell;
pub mod synthetic;
pub mod visual_hull;

pub use background::{BLACK, Background, WHITE};
pub use bounds::Aabb;
pub use dataset::{Dataset, DatasetOptions, Format, InitialCloud, MaskSource, View};
pub use dnerf::{Frame, Split, SplitMeta};
pub use error::DataError;
pub use format::{DataFormat, FormatRegistry};
pub use image::Image;
pub use point_cloud::PointCloud;
