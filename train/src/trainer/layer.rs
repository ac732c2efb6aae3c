//! The trainer's side of a background layer (`maaf_scene::backdrop`): the trained
//! layer, and its render from every training camera, made once, under which every
//! training render of the model is composited.

use maaf_autodiff::Tensor;
use maaf_scene::TrainedScene;

use super::Trainer;
use super::camera_colour::camera_index;

/// A fixed background layer and its renders from the training cameras.
pub struct Layer {
    /// The trained layer.
    pub scene: TrainedScene,
    /// Its render from each distinct training camera, at the training scale, on the
    /// data set's background.
    images: Vec<Tensor<f32>>,
    /// The distinct camera of each training view (index into `images`).
    camera_of_view: Vec<usize>,
}

impl Layer {
    /// The layer's render behind training view `view`.
    pub fn image(&self, view: usize) -> &Tensor<f32> {
        &self.images[self.camera_of_view[view]]
    }
}

impl Trainer {
    /// Puts the trained background layer `scene` behind the model: it is rendered
    /// once from every distinct training camera (on the data set's background) and
    /// every training render of the model is composited over it from then on, as
    /// validation and evaluation do.
    pub fn set_backdrop(&mut self, scene: TrainedScene) {
        let (camera_of_view, n) = camera_index(&self.views.cameras);
        let mut first = vec![None; n];
        for (view, &c) in camera_of_view.iter().enumerate() {
            first[c].get_or_insert(view);
        }
        let settings = maaf_splat::RenderSettings {
            background: self.background.map(f64::from),
            ..scene.render_settings()
        };
        let images = first
            .into_iter()
            .flatten()
            .map(|view| {
                scene.render_with(&self.views.cameras[view], self.views.times[view], &settings)
            })
            .collect();
        self.backdrop = Some(Layer {
            scene,
            images,
            camera_of_view,
        });
    }

    /// The background layer, when the run has one.
    pub fn backdrop(&self) -> Option<&TrainedScene> {
        self.backdrop.as_ref().map(|l| &l.scene)
    }
}
