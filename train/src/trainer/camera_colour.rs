//! Per-camera colour correction of the training renders (`camera_colour` in the
//! config): real multi-camera rigs differ in exposure and white balance, and a model
//! without it bakes each training camera's colours into view-dependent colour, which
//! a new camera then sees as blotches.
//!
//! Each training camera `c` gets a gain and an offset per channel, and the objective
//! compares `exp(a_c) * I + b_c` with the camera's image (Dynamic 3D Gaussians, Luiten
//! et al. 3DV 2024: `cam_m`, `cam_c`, Adam at 1e-4). `a = b = 0` at the start. Only
//! training renders are corrected: evaluation, validation and every other camera see
//! the model's own colours (the identity), as in the reference.
//!
//! A camera is a distinct set of intrinsics and pose among the training views: the
//! views of one camera of a multi-view video over time share one correction.

use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, Tape, Tensor, Var};
use maaf_models::params::{BoundParams, ParamId, ParamStore, Rows};
use maaf_splat::Camera;

/// Name prefix of the correction's tensors in a checkpoint and in the optimiser.
pub const PREFIX: &str = "camera_colour/";

/// `exp(log_gain) * image + bias` per channel: `image` `[H,W,3]`, `log_gain` and
/// `bias` `[1,3]` (or `[3]`), broadcast over the pixels.
pub fn correct_colour<'t, T: Float>(
    image: Var<'t, T>,
    log_gain: Var<'t, T>,
    bias: Var<'t, T>,
) -> Var<'t, T> {
    image * log_gain.exp() + bias
}

/// The index of each view's camera among the distinct cameras of `cameras` (in order
/// of first appearance), and their number.
pub fn camera_index(cameras: &[Camera]) -> (Vec<usize>, usize) {
    let mut distinct: Vec<&Camera> = Vec::new();
    let index = cameras
        .iter()
        .map(|c| match distinct.iter().position(|d| *d == c) {
            Some(i) => i,
            None => {
                distinct.push(c);
                distinct.len() - 1
            }
        })
        .collect();
    (index, distinct.len())
}

/// The learned corrections of a run's training cameras.
pub struct CameraColour {
    /// Camera of each training view (index into the parameters' rows).
    camera_of_view: Vec<usize>,
    /// `log_gain` and `bias`, `[cameras, 3]` each, constant learning rate.
    params: ParamStore<f32>,
    log_gain: ParamId,
    bias: ParamId,
}

impl CameraColour {
    /// Identity corrections for the distinct cameras of the training views
    /// `cameras`, trained at `lr`.
    pub fn new(cameras: &[Camera], lr: f64) -> Self {
        let (camera_of_view, n) = camera_index(cameras);
        let mut params = ParamStore::new();
        let mut add = |name: &str| {
            params.add(
                &format!("{PREFIX}{name}"),
                Tensor::zeros(&[n, 3]),
                Rows::Shared,
                LrSchedule::Constant(lr),
                0.0,
            )
        };
        let log_gain = add("log_gain");
        let bias = add("bias");
        CameraColour {
            camera_of_view,
            params,
            log_gain,
            bias,
        }
    }

    /// Number of distinct training cameras.
    pub fn cameras(&self) -> usize {
        self.params.value(self.bias).rows()
    }

    /// The parameters (optimiser and checkpoints).
    pub fn params(&self) -> &ParamStore<f32> {
        &self.params
    }

    /// The parameters, mutably.
    pub fn params_mut(&mut self) -> &mut ParamStore<f32> {
        &mut self.params
    }

    /// Binds the corrections on `tape` (once per step).
    pub fn bind<'t>(&self, tape: &'t Tape<f32>) -> BoundParams<'t, f32> {
        self.params.bind(tape)
    }

    /// The render of training view `view` with its camera's correction applied
    /// ([`correct_colour`]).
    pub fn apply<'t>(
        &self,
        bound: &BoundParams<'t, f32>,
        view: usize,
        image: Var<'t, f32>,
    ) -> Var<'t, f32> {
        let row = [self.camera_of_view[view]];
        correct_colour(
            image,
            bound.get(self.log_gain).gather_rows(&row),
            bound.get(self.bias).gather_rows(&row),
        )
    }

    /// Per camera, the gain `exp(a)` and offset `b` of each channel (for the run's
    /// summary).
    pub fn table(&self) -> Vec<[f32; 6]> {
        let a = self.params.value(self.log_gain).data();
        let b = self.params.value(self.bias).data();
        (0..self.cameras())
            .map(|c| {
                [
                    a[3 * c].exp(),
                    a[3 * c + 1].exp(),
                    a[3 * c + 2].exp(),
                    b[3 * c],
                    b[3 * c + 1],
                    b[3 * c + 2],
                ]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::check::tests_support::random_tensor;
    use maaf_autodiff::check::{GradcheckConfig, gradcheck};

    fn camera(tx: f64) -> Camera {
        let mut w2c = [[0.0; 4]; 4];
        for (i, row) in w2c.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        w2c[0][3] = tx;
        Camera::new(8, 6, 10.0, 10.0, 4.0, 3.0, w2c).expect("valid camera")
    }

    #[test]
    fn views_of_one_camera_share_a_correction() {
        let cams = [
            camera(0.0),
            camera(1.0),
            camera(0.0),
            camera(2.0),
            camera(1.0),
        ];
        assert_eq!(camera_index(&cams), (vec![0, 1, 0, 2, 1], 3));
    }

    #[test]
    fn correction_matches_a_per_pixel_loop() {
        let tape = Tape::<f64>::new();
        let image = random_tensor::<f64>(&[2, 3, 3], 0.0, 1.0, 1);
        let a = random_tensor::<f64>(&[1, 3], -0.5, 0.5, 2);
        let b = random_tensor::<f64>(&[1, 3], -0.2, 0.2, 3);
        let out = correct_colour(
            tape.constant(image.clone()),
            tape.constant(a.clone()),
            tape.constant(b.clone()),
        )
        .value();
        for p in 0..6 {
            for ch in 0..3 {
                let want = a.data()[ch].exp() * image.data()[3 * p + ch] + b.data()[ch];
                assert!((out.data()[3 * p + ch] - want).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn correction_gradient_matches_finite_differences() {
        let inputs = [
            random_tensor::<f64>(&[3, 4, 3], 0.0, 1.0, 4),
            random_tensor::<f64>(&[1, 3], -0.5, 0.5, 5),
            random_tensor::<f64>(&[1, 3], -0.2, 0.2, 6),
        ];
        let r = gradcheck(
            |_, v| correct_colour(v[0], v[1], v[2]),
            &inputs,
            &GradcheckConfig::default().with_tol(1e-9, 1e-7),
        );
        assert!(r.passed(), "{r}");
    }

    #[test]
    fn apply_uses_the_view_cameras_row() {
        let cams = [camera(0.0), camera(1.0), camera(0.0)];
        let mut cc = CameraColour::new(&cams, 1e-4);
        let gain = cc.params.id("camera_colour/log_gain").expect("declared");
        cc.params.value_mut(gain).data_mut()[3..6].copy_from_slice(&[0.1, 0.2, 0.3]);
        let tape = Tape::new();
        let bound = cc.bind(&tape);
        let image = Tensor::from_vec(vec![0.5f32; 2 * 2 * 3], &[2, 2, 3]);
        let first = cc
            .apply(&bound, 2, tape.constant(image.clone()))
            .value()
            .clone();
        assert_eq!(first.data(), image.data(), "camera 0 is the identity");
        let second = cc.apply(&bound, 1, tape.constant(image)).value().clone();
        assert!((second.data()[2] - 0.5 * 0.3f32.exp()).abs() < 1e-6);
    }
}
