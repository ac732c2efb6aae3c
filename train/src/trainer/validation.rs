//! Validation during training: a few held-back views rendered every `val_every`
//! iterations, their mean PSNR logged as `val_psnr` in `log.csv`, so quality can be
//! drawn against training time without a separate evaluation (speed against accuracy
//! as curves). Outside the tape and the optimiser: the run is unchanged.

use maaf_autodiff::Tensor;
use maaf_splat::Camera;

use super::Trainer;
use crate::Error;
use crate::data::{Dataset, Split};
use maaf_scene::metrics::psnr;
use maaf_scene::render_over;

/// A held-back view at the training scale.
pub(super) struct HeldOut {
    camera: Camera,
    time: f64,
    gt: Tensor<f32>,
}

/// `count` views evenly spaced over the validation split (the test split when the
/// data set has no validation views, unless `choose`: views that choose the run's
/// model must not be the ones it is measured on), at `scale`; empty when `count` is 0.
pub(super) fn held_out_views(
    data: &Dataset,
    count: usize,
    scale: f64,
    choose: bool,
) -> Result<Vec<HeldOut>, Error> {
    if count == 0 {
        return Ok(Vec::new());
    }
    let split = if data.len(Split::Val) > 0 {
        Split::Val
    } else if choose {
        return Err(Error::Input(format!(
            "{}: keep_best chooses the model on validation views and this data set has none (the test views would then both choose and measure it)",
            data.root().display()
        )));
    } else {
        Split::Test
    };
    let len = data.len(split);
    let count = count.min(len);
    (0..count)
        .map(|k| {
            let view = data
                .view(split, k * len / count, scale)
                .map_err(|e| Error::Input(e.to_string()))?;
            Ok(HeldOut {
                camera: view.camera.clone(),
                time: view.time,
                gt: view.image.to_tensor(),
            })
        })
        .collect()
}

impl Trainer {
    /// Mean PSNR (dB) of the held-back views rendered now, with the render settings
    /// of the current iteration; `None` without held-back views.
    pub fn validation_psnr(&self) -> Option<f64> {
        if self.held_out.is_empty() {
            return None;
        }
        let settings = self.render_settings(self.iteration.max(1));
        let sum: f64 = self
            .held_out
            .iter()
            .map(|v| {
                let image = render_over(
                    self.state.model.as_ref(),
                    &self.state.filter,
                    self.backdrop(),
                    &v.camera,
                    v.time,
                    &settings,
                );
                psnr(&image, &v.gt).unwrap_or(f64::NAN)
            })
            .sum();
        Some(sum / self.held_out.len() as f64)
    }
}
