//! What a run starts from: its training views at the config's scale, the camera
//! extent, and the initial cloud every representation is built from
//! ([`model_init`]); a trained scene rebuilds an old run's initial cloud with it
//! ([`crate::SceneRecord::of_data`]).

use maaf_data::{Dataset, View};
use maaf_models::{ModelInit, PointCloud};
use maaf_splat::Camera;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use crate::config::{HullTimes, StaticPoints};
use crate::{Error, TrainConfig};

/// Radius of the sphere around the mean camera centre that holds every camera,
/// times 1.1 (3DGS `getNerfppNorm`): the scene extent that scales position learning
/// rates and the clone/split boundary.
pub fn camera_extent(cameras: &[Camera]) -> f64 {
    let n = cameras.len().max(1) as f64;
    let c = cameras
        .iter()
        .map(|c| c.center())
        .fold(glam::DVec3::ZERO, |a, b| a + b)
        / n;
    1.1 * cameras
        .iter()
        .map(|cam| (cam.center() - c).length())
        .fold(0.0, f64::max)
}

/// The training views of `data` at the config's scale, or an error naming the folder.
pub fn training_views(data: &Dataset, config: &TrainConfig) -> Result<Vec<View>, Error> {
    let views = data
        .train_views(config.train_scale)
        .map_err(|e| Error::Input(e.to_string()))?;
    if views.is_empty() {
        return Err(Error::Input(format!(
            "{}: no training views",
            data.root().display()
        )));
    }
    Ok(views)
}

/// What a representation of a run on `data` is initialised from: the data set's own
/// point cloud (`points3d.ply`, [`maaf_data::points`]) subsampled to at most
/// `init_points`, as 3DGS-family loaders use it when present, or the visual hull of
/// its foreground masks ([`Dataset::initial_cloud`]); otherwise
/// `init_points` random points in the data set's scene bounds with random colours
/// (as SaRO-GS and Deformable-3DGS initialise synthetic D-NeRF scenes). Plus the
/// camera extent, the seed, the distinct training times and the run's iterations.
/// The same for every representation, so a user's model starts from the same cloud
/// as the built-in one.
pub fn model_init(data: &Dataset, config: &TrainConfig) -> Result<ModelInit, Error> {
    let views = training_views(data, config)?;
    let cloud = match data
        .initial_cloud(
            config.init_points,
            config.hull_fraction,
            config.static_points == StaticPoints::Shell,
            config.hull_times == HullTimes::First,
            config.seed,
        )
        .map_err(|e| Error::Input(e.to_string()))?
    {
        Some(init) => {
            log::info!("initial points: {}", init.description);
            if let Some(warning) = &init.warning {
                log::warn!("{warning}");
            }
            init.cloud
        }
        None => random_cloud(data, config),
    };
    let cameras: Vec<Camera> = views.iter().map(|v| v.camera.clone()).collect();
    let mut times: Vec<f64> = views.iter().map(|v| v.time).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    Ok(ModelInit {
        cloud,
        extent: camera_extent(&cameras),
        seed: config.seed,
        times,
        iterations: config.iterations,
    })
}

/// `init_points` points uniform in the data set's scene bounds, colours uniform in
/// \[0, 1], from the run's seed.
fn random_cloud(data: &Dataset, config: &TrainConfig) -> PointCloud {
    let bounds = data.scene_bounds();
    let mut rng = Pcg64::seed_from_u64(config.seed);
    let points: Vec<[f64; 3]> = (0..config.init_points)
        .map(|_| std::array::from_fn(|a| rng.random_range(bounds.min[a]..bounds.max[a])))
        .collect();
    let colours = (0..config.init_points)
        .map(|_| std::array::from_fn(|_| rng.random_range(0.0..1.0)))
        .collect();
    PointCloud {
        points,
        colours,
        times: None,
    }
}
