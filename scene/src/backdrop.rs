//! A run's static background layer (`backdrop` in the config,
//! [`crate::BackdropConfig`]): a trained run of its own in `RUN/backdrop/`, held
//! fixed while the run's model is trained over it, and drawn under that model
//! wherever the scene is rendered.
//!
//! The two layers are composited front to back: the model is rendered on black and
//! the layer's render `B` fills what the model leaves transparent,
//!
//! ```text
//! C = C_model + T_model B,   T_model = 1 - alpha_model
//! ```
//!
//! so the layer is always behind the model (a moving foreground in front of a static
//! room), and a step renders only the model's Gaussians: `B` of a training camera is
//! rendered once.

use std::path::{Path, PathBuf};

use maaf_autodiff::{Float, Tensor, Var};

/// Folder of a run's background layer inside the run folder.
pub const BACKDROP_DIR: &str = "backdrop";

/// The layer folder of the run that holds the checkpoint folder `dir`
/// (`RUN/model` or `RUN/checkpoints/iter_N`): `RUN/backdrop`.
pub fn backdrop_dir_of(dir: &Path) -> PathBuf {
    let parent = dir.parent().unwrap_or(dir);
    let run = if parent.file_name().is_some_and(|n| n == "checkpoints") {
        parent.parent().unwrap_or(parent)
    } else {
        parent
    };
    run.join(BACKDROP_DIR)
}

/// `image + (1 - alpha) backdrop`: a render drawn on black (`image` `[H,W,3]`, its
/// accumulated opacity `alpha` `[H,W]`) over the constant `backdrop` `[H,W,3]`.
pub fn over_backdrop<'t, T: Float>(
    image: Var<'t, T>,
    alpha: Var<'t, T>,
    backdrop: Tensor<T>,
) -> Var<'t, T> {
    let shape = alpha.shape();
    let transmittance = alpha
        .scale(-1.0)
        .add_scalar(1.0)
        .reshape(&[shape[0], shape[1], 1]);
    image + transmittance * image.tape().constant(backdrop)
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::Tape;
    use maaf_autodiff::check::tests_support::random_tensor;
    use maaf_autodiff::check::{GradcheckConfig, gradcheck};

    #[test]
    fn composite_matches_a_per_pixel_loop() {
        let tape = Tape::<f64>::new();
        let image = random_tensor::<f64>(&[3, 2, 3], 0.0, 1.0, 1);
        let alpha = random_tensor::<f64>(&[3, 2], 0.0, 1.0, 2);
        let back = random_tensor::<f64>(&[3, 2, 3], 0.0, 1.0, 3);
        let out = over_backdrop(
            tape.constant(image.clone()),
            tape.constant(alpha.clone()),
            back.clone(),
        )
        .value();
        for p in 0..6 {
            for c in 0..3 {
                let i = 3 * p + c;
                let want = image.data()[i] + (1.0 - alpha.data()[p]) * back.data()[i];
                assert!((out.data()[i] - want).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn composite_gradient_matches_finite_differences() {
        let back = random_tensor::<f64>(&[4, 3, 3], 0.0, 1.0, 6);
        let inputs = [
            random_tensor::<f64>(&[4, 3, 3], 0.0, 1.0, 4),
            random_tensor::<f64>(&[4, 3], 0.0, 1.0, 5),
        ];
        let r = gradcheck(
            |_, v| over_backdrop(v[0], v[1], back.clone()),
            &inputs,
            &GradcheckConfig::default().with_tol(1e-9, 1e-7),
        );
        assert!(r.passed(), "{r}");
    }

    #[test]
    fn layer_folder_is_found_from_either_checkpoint_folder() {
        let run = Path::new("/runs/r");
        assert_eq!(backdrop_dir_of(&run.join("model")), run.join("backdrop"));
        assert_eq!(
            backdrop_dir_of(&run.join("checkpoints/iter_001000")),
            run.join("backdrop")
        );
    }
}
