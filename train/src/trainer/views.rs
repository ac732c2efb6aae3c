//! The training views as the trainer holds them: per view its camera, time and
//! ground truth (the images live only here: a multi-view video's thousands of views
//! are not held twice), and what the config's options need of it besides.

use std::sync::Arc;

use maaf_autodiff::Tensor;
use maaf_splat::{Camera, Window};

use super::region;
use crate::Error;
use crate::data::{Dataset, Image, Split};
use maaf_scene::{LossRegion, TrainConfig, training_views};

/// The training split at the training scale, one entry per view in every list that
/// is not empty.
pub(super) struct TrainViews {
    /// Cameras (at the training scale).
    pub cameras: Vec<Camera>,
    /// Time of each view.
    pub times: Vec<f64>,
    /// Ground truth of each view.
    pub gts: Vec<Tensor<f32>>,
    /// Coverage (alpha) of each view with transparency, kept only for
    /// `random_background` ([`super::background`]).
    pub coverage: Vec<Option<Arc<Image>>>,
    /// Foreground coverage of each view, kept only for `loss_region = background`.
    pub masks: Vec<Image>,
    /// The rectangle around each view's foreground, only for `loss_region =
    /// foreground` (`None`: the whole view).
    pub crops: Vec<Option<Window>>,
}

impl TrainViews {
    /// The training views of `data` as `config` trains on them. The data set's
    /// cached images are evicted once copied: keeping both would double the images'
    /// memory for the whole run.
    pub fn load(data: &Dataset, config: &TrainConfig) -> Result<Self, Error> {
        let views = training_views(data, config)?;
        let cameras = views.iter().map(|v| v.camera.clone()).collect();
        let times = views.iter().map(|v| v.time).collect();
        let gts = views.iter().map(|v| v.image.to_tensor()).collect();
        let coverage = views
            .iter()
            .map(|v| v.coverage.clone().filter(|_| config.random_background))
            .collect();
        drop(views);
        data.evict(Split::Train);
        let masks = match config.loss_region {
            LossRegion::All => Vec::new(),
            _ => region::training_masks(data, config.train_scale)?,
        };
        let crops = match config.loss_region {
            LossRegion::Foreground => masks
                .iter()
                .map(|m| region::window_around(m, config.focus_margin))
                .collect(),
            _ => Vec::new(),
        };
        let masks = match config.loss_region {
            LossRegion::Background => masks,
            _ => Vec::new(),
        };
        Ok(TrainViews {
            cameras,
            times,
            gts,
            coverage,
            masks,
            crops,
        })
    }

    /// Number of training views.
    pub fn len(&self) -> usize {
        self.cameras.len()
    }
}
