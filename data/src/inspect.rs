//! `maaf inspect`: a summary of a data set, so a user can check it before training.
//!
//! Opening goes through [`Dataset::open`], so every error is the loader's; with
//! `decode = true` every image is also decoded once (in parallel) to catch PNGs whose
//! header reads but whose pixels do not.

use std::path::Path;

use rayon::prelude::*;
use serde::Serialize;

use super::dataset::{Dataset, DatasetOptions, MaskSource, scale_factor};
use super::dnerf::Split;
use super::error::DataError;
use super::format::FormatRegistry;
use super::image::decode_rgba;

/// Summary of one split.
#[derive(Clone, Debug, Serialize)]
pub struct SplitSummary {
    /// Split name (`train`, `val`, `test`, `video`).
    pub split: String,
    /// Number of views.
    pub views: usize,
    /// Source image width, pixels.
    pub width: u32,
    /// Source image height, pixels.
    pub height: u32,
    /// Focal length at the source resolution, pixels (of the first view).
    pub focal_px: f64,
    /// Smallest and largest `fx` over the views (multi-view rigs mix lenses).
    pub focal_range_px: [f64; 2],
    /// Distinct cameras (intrinsics and pose) among the views.
    pub cameras: usize,
    /// Views with a foreground mask (Dynamic 3D Gaussians `seg/`).
    pub masks: usize,
    /// Horizontal field of view, degrees.
    pub fov_x_deg: f64,
    /// Smallest and largest time stamp.
    pub time_range: [f64; 2],
    /// Distinct time stamps (ring rigs repeat each time over several cameras).
    pub distinct_times: usize,
    /// Smallest and largest distance from a camera centre to the scene-bounds centre.
    pub camera_distance_range: [f64; 2],
    /// Views carrying a forward-flow file.
    pub flow_frames: usize,
}

/// Summary of a data set.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Data folder.
    pub root: String,
    /// Per-split summaries, in the order train, val, test, video.
    pub splits: Vec<SplitSummary>,
    /// Time range over all splits.
    pub time_range: [f64; 2],
    /// Scene bounds `[min, max]` used for initialisation.
    pub scene_bounds: [[f64; 3]; 2],
    /// Where the bounds come from: `json` (`scene_bounds` key) or `cameras` (estimated).
    pub scene_bounds_source: String,
    /// Scales (relative to the training images) with exact box-downsampled ground
    /// truth, largest first, down to 1/16.
    pub scales: Vec<f64>,
    /// Number of images decoded to check them (0 when decoding was skipped).
    pub images_decoded: usize,
    /// Points in the folder's `points3d.ply` (the initial point cloud), if it has one.
    pub init_points: Option<usize>,
    /// Whether those points carry times (`t`).
    pub init_points_timed: bool,
    /// Where the moving-pixel masks of the test views come from: `none`, `files` or
    /// `temporal median`.
    pub test_masks: String,
}

/// Opens `root` (a built-in layout, else one of `formats`) and summarises it; decodes
/// every image when `decode` is true.
pub fn inspect(root: &Path, decode: bool, formats: &FormatRegistry) -> Result<Summary, DataError> {
    let data = Dataset::open_with(root, DatasetOptions::default(), formats)?;
    let bounds = data.scene_bounds();
    let centre = bounds.center();
    let mut splits = Vec::new();
    let mut images_decoded = 0;
    for meta in data.splits() {
        let times: Vec<f64> = meta.frames.iter().map(|f| f.time).collect();
        let mut distinct = times.clone();
        distinct.sort_by(f64::total_cmp);
        distinct.dedup();
        let dists: Vec<f64> = meta
            .frames
            .iter()
            .map(|f| (f.camera.center() - centre).length())
            .collect();
        let fx: Vec<f64> = meta.frames.iter().map(|f| f.camera.fx).collect();
        let mut cameras: Vec<&maaf_splat::Camera> = Vec::new();
        for f in &meta.frames {
            if !cameras.contains(&&f.camera) {
                cameras.push(&f.camera);
            }
        }
        let range = |v: &[f64]| {
            [
                v.iter().copied().fold(f64::INFINITY, f64::min),
                v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            ]
        };
        if decode {
            meta.frames
                .par_iter()
                .map(|f| decode_rgba(&f.file).map(|_| ()))
                .collect::<Result<Vec<()>, DataError>>()?;
            images_decoded += meta.frames.len();
        }
        splits.push(SplitSummary {
            split: meta.split.name().into(),
            views: meta.frames.len(),
            width: meta.width,
            height: meta.height,
            focal_px: meta.focal,
            focal_range_px: range(&fx),
            cameras: cameras.len(),
            masks: meta
                .frames
                .iter()
                .filter(|f| data.train_mask(&f.file).is_some())
                .count(),
            fov_x_deg: meta.camera_angle_x.to_degrees(),
            time_range: range(&times),
            distinct_times: distinct.len(),
            camera_distance_range: range(&dists),
            flow_frames: meta.frames.iter().filter(|f| f.flow.is_some()).count(),
        });
    }
    let train = data.split(Split::Train)?;
    let scales = (0..=4)
        .map(|p| 1.0 / f64::from(1u32 << p))
        .filter(|&s| scale_factor(s, train.width, train.height).is_ok())
        .collect();
    let (t0, t1) = data.time_range();
    let cloud = data.point_cloud()?;
    Ok(Summary {
        root: root.display().to_string(),
        splits,
        time_range: [t0, t1],
        scene_bounds: [bounds.min.to_array(), bounds.max.to_array()],
        scene_bounds_source: if train.scene_bounds.is_some() {
            "json"
        } else {
            "cameras"
        }
        .into(),
        scales,
        images_decoded,
        init_points: cloud.as_ref().map(|c| c.len()),
        init_points_timed: cloud.as_ref().is_some_and(|c| c.times.is_some()),
        test_masks: match data.mask_source() {
            MaskSource::None => "none",
            MaskSource::Files(_) => "files",
            MaskSource::TemporalMedian { .. } => "temporal median",
        }
        .into(),
    })
}

impl Summary {
    /// The summary as pretty-printed JSON (the field names above).
    pub fn to_json_string(&self) -> String {
        // Plain numbers and strings always serialise.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Human-readable multi-line summary.
    pub fn to_text(&self) -> String {
        let mut s = format!("data set {}\n", self.root);
        for sp in &self.splits {
            s += &format!(
                "  {:<5} {:>4} views  {} cameras  {}x{}  f = {}  t in [{:.4}, {:.4}] ({} distinct)  camera distance {:.3}..{:.3}{}{}\n",
                sp.split,
                sp.views,
                sp.cameras,
                sp.width,
                sp.height,
                if sp.focal_range_px[1] - sp.focal_range_px[0] > 0.05 {
                    format!(
                        "{:.1}..{:.1} px",
                        sp.focal_range_px[0], sp.focal_range_px[1]
                    )
                } else {
                    format!("{:.1} px (fov {:.1} deg)", sp.focal_px, sp.fov_x_deg)
                },
                sp.time_range[0],
                sp.time_range[1],
                sp.distinct_times,
                sp.camera_distance_range[0],
                sp.camera_distance_range[1],
                if sp.flow_frames > 0 {
                    format!("  flow for {} frames", sp.flow_frames)
                } else {
                    String::new()
                },
                if sp.masks > 0 {
                    format!("  {} foreground masks", sp.masks)
                } else {
                    String::new()
                }
            );
        }
        let [lo, hi] = self.scene_bounds;
        s += &format!(
            "  time range [{}, {}]\n  scene bounds [{:.3}, {:.3}, {:.3}] .. [{:.3}, {:.3}, {:.3}] (from {})\n",
            self.time_range[0],
            self.time_range[1],
            lo[0],
            lo[1],
            lo[2],
            hi[0],
            hi[1],
            hi[2],
            self.scene_bounds_source
        );
        let scales: Vec<String> = self.scales.iter().map(|v| format!("{v}")).collect();
        s += &format!("  exact ground-truth scales: {}\n", scales.join(", "));
        s += &match self.init_points {
            Some(n) => format!(
                "  initial points: {n} in {}{}\n",
                super::points::POINTS_FILE,
                if self.init_points_timed {
                    ", with times"
                } else {
                    ""
                }
            ),
            None if self.splits.iter().any(|sp| sp.split == "train" && sp.masks > 0) => "  initial points: none shipped; training carves them from the foreground masks (visual hull) plus random static points\n".into(),
            None => "  initial points: none shipped (training starts from random points in the scene bounds)\n".into(),
        };
        s += &format!("  moving pixels of the test views: {}\n", self.test_masks);
        if self.images_decoded > 0 {
            s += &format!("  all {} images decode\n", self.images_decoded);
        }
        s
    }
}
