//! The points a run starts from, when the data folder gives any
//! ([`Dataset::initial_cloud`]): its shipped `points3d.ply`, or the visual hull of the
//! training views' foreground masks with static points around it.

use super::{Dataset, spread};
use crate::PointCloud;
use crate::dnerf::Split;
use crate::error::DataError;
use crate::points::{POINTS_FILE, read_points};
use crate::visual_hull::{HullOptions, HullStep, HullView, hull_cloud};

/// The points a run starts from ([`Dataset::initial_cloud`]).
#[derive(Clone, Debug)]
pub struct InitialCloud {
    /// The points.
    pub cloud: PointCloud,
    /// How many of them (the first ones) lie on visual hulls; 0 for a shipped cloud.
    pub hull_points: usize,
    /// One line saying where the points come from.
    pub description: String,
    /// One line to print as a warning: the visual hull put no point into the cloud.
    pub warning: Option<String>,
}

impl Dataset {
    /// The initial point cloud the folder ships (`points3d.ply`,
    /// [`crate::points`]), read now; `None` when there is none.
    pub fn point_cloud(&self) -> Result<Option<PointCloud>, DataError> {
        let path = self.root.join(POINTS_FILE);
        if path.exists() {
            read_points(&path).map(Some)
        } else {
            Ok(None)
        }
    }

    /// The points a run starts from when the folder ships a point cloud or can carve
    /// one, with a line saying which: `points3d.ply` subsampled to `budget`; else, when
    /// the training images have foreground masks (the Dynamic 3D Gaussians layout),
    /// [`hull_cloud`] over at most `HullOptions::steps` evenly spread training times with
    /// `hull_fraction` of the budget on the hulls and the rest static, with `shell` on
    /// the capture dome's wall and floor ([`crate::shell`]), or with `first_time` the
    /// whole hull share on the earliest training time (a model that starts from one
    /// frame); `None` otherwise (the trainer then draws random points).
    pub fn initial_cloud(
        &self,
        budget: usize,
        hull_fraction: f64,
        shell: bool,
        first_time: bool,
        seed: u64,
    ) -> Result<Option<InitialCloud>, DataError> {
        if let Some(cloud) = self.point_cloud()? {
            let n = cloud.len();
            let cloud = cloud.subsample(budget, seed);
            let description = format!("{} of the {n} points of {POINTS_FILE}", cloud.len());
            return Ok(Some(InitialCloud {
                cloud,
                hull_points: 0,
                description,
                warning: None,
            }));
        }
        if self.train_masks.is_empty() {
            return Ok(None);
        }
        let start = std::time::Instant::now();
        let train = self.split(Split::Train)?;
        let mut times: Vec<f64> = train.frames.iter().map(|f| f.time).collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        if first_time {
            times.truncate(1);
        }
        let options = HullOptions {
            dynamic_fraction: hull_fraction,
            shell,
            ..HullOptions::default()
        };
        let picked = spread(&times, options.steps);
        let steps: Vec<HullStep> = picked
            .iter()
            .map(|&time| HullStep {
                time,
                views: train
                    .frames
                    .iter()
                    .filter(|f| f.time == time)
                    .filter_map(|f| {
                        self.train_mask(&f.file).map(|m| HullView {
                            camera: f.camera.clone(),
                            image: f.file.clone(),
                            mask: m.to_path_buf(),
                        })
                    })
                    .collect(),
            })
            .collect();
        let mut centres: Vec<glam::DVec3> =
            train.frames.iter().map(|f| f.camera.center()).collect();
        centres.dedup();
        let (cloud, dynamic) = hull_cloud(&steps, &centres, budget, &options, seed)?;
        let description = format!(
            "{} points: {dynamic} on the visual hulls of the foreground masks at {} times (at most {:.0} % of the budget), {} static {} ({:.1} s)",
            cloud.len(),
            steps.len(),
            100.0 * options.dynamic_fraction,
            cloud.len() - dynamic,
            if shell {
                "on the capture dome's wall and floor (random in the box where rays miss it)"
            } else {
                "at random in the box of the cameras and the hulls"
            },
            start.elapsed().as_secs_f64()
        );
        let warning = (dynamic == 0 && hull_fraction > 0.0 && budget > 0).then(|| {
            format!(
                "the visual hull of the foreground masks put no point into the initial cloud (no region is seen in the foreground of {} cameras at once: small or coarse masks?); training starts from random static points only",
                options.min_views
            )
        });
        Ok(Some(InitialCloud {
            cloud,
            hull_points: dynamic,
            description,
            warning,
        }))
    }
}
