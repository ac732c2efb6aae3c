//! `maaf eval --temporal`: temporal stability of a fixed-camera video of the run at one
//! evaluation scale (paper Tab. 3 and supplementary), with the exact flow when the data
//! set has one and always with the run's own model flow ([`super::flow`]).
//!
//! The video: the data set's `video` split (one fixed camera; the built-in generator
//! writes it with exact forward flow) when it has at least two frames, else test camera
//! 0 at every distinct test time, ascending (no exact flow then). Frames are rendered
//! through the evaluation pipeline ([`TrainedScene::render_with`]); the metrics are
//! [`crate::metrics::temporal::temporal_metrics`].

use maaf_autodiff::Tensor;
use maaf_data::{Dataset, Split};
use maaf_lpips::Lpips;
use maaf_scene::TrainedScene;
use maaf_splat::Camera;

use super::eval_json::{PoppingResult, ScaleResult, TemporalResult};
use super::flow::model_flow;
use super::popping::visible_weights;
use crate::Error;
use crate::metrics::popping::PoppingMetrics;
use crate::metrics::temporal::temporal_metrics;

/// The fixed-camera video to measure: camera, label, frame times, exact flows.
struct Video {
    camera: Camera,
    label: String,
    times: Vec<f64>,
    exact: Option<Vec<Tensor<f32>>>,
}

/// The video at `source` scale (relative to the source images).
fn video(data: &Dataset, source: f64) -> Result<Video, Error> {
    let input = |e: maaf_data::DataError| Error::Input(e.to_string());
    if data.len(Split::Video) >= 2 {
        let times = data.times(Split::Video);
        let mut exact = Vec::with_capacity(times.len() - 1);
        for j in 0..times.len() - 1 {
            match data.flow(j, source).map_err(input)? {
                Some(f) => exact.push(f.to_tensor()),
                None => break,
            }
        }
        return Ok(Video {
            camera: data.camera(Split::Video, 0, source).map_err(input)?,
            label: "video 0".into(),
            exact: (exact.len() + 1 == times.len()).then_some(exact),
            times,
        });
    }
    let mut times = data.times(Split::Test);
    times.sort_by(f64::total_cmp);
    times.dedup();
    if times.len() < 2 {
        return Err(Error::Input(format!(
            "{}: --temporal needs a video split or at least 2 distinct test times",
            data.root().display()
        )));
    }
    Ok(Video {
        camera: data.camera(Split::Test, 0, source).map_err(input)?,
        label: "test 0".into(),
        times,
        exact: None,
    })
}

/// Renders the video of `scene` at `source` scale and measures it with the exact
/// flow (when the data set has one) and with model flow: one [`TemporalResult`] per
/// flow, exact first, and the popping of its single Gaussians
/// ([`super::popping::visible_weights`], [`crate::metrics::popping`]).
pub fn evaluate_temporal(
    scene: &TrainedScene,
    data: &Dataset,
    source: f64,
    lpips: Option<&Lpips>,
) -> Result<(Vec<TemporalResult>, PoppingResult), Error> {
    let v = video(data, source)?;
    let settings = crate::eval_settings(scene, data);
    let frames: Vec<Tensor<f32>> = v
        .times
        .iter()
        .map(|&t| scene.render_with(&v.camera, t, &settings))
        .collect();
    // LPIPS needs frames of at least its network's min_size pixels; smaller scales get
    // W-LPIPS null.
    let side = v.camera.width.min(v.camera.height) as usize;
    let lpips = lpips.filter(|m| side >= m.net().min_size());
    // One pair of deformed frames in memory at a time (a large run's SH is big).
    let mut model = Vec::with_capacity(v.times.len() - 1);
    let pixels = v.camera.width as usize * v.camera.height as usize;
    let mut pops = PoppingMetrics::default();
    let mut now = scene.gaussians_at(v.times[0]);
    let mut now_weights = visible_weights(&now, &v.camera, &settings);
    for &t in &v.times[1..] {
        let next = scene.gaussians_at(t);
        model.push(model_flow(&now, &next, &v.camera, &settings));
        let next_weights = visible_weights(&next, &v.camera, &settings);
        pops.push_step(&now_weights, &next_weights, pixels);
        (now, now_weights) = (next, next_weights);
    }
    let mut out = Vec::new();
    for (name, flows) in [("exact", v.exact.as_ref()), ("model", Some(&model))] {
        let Some(flows) = flows else { continue };
        let m = temporal_metrics(&frames, flows, lpips)
            .map_err(|e| Error::Input(format!("{} flow: {e}", name)))?;
        out.push(TemporalResult {
            flow: name.into(),
            camera: v.label.clone(),
            times: v.times.clone(),
            warp_error: m.warp_error,
            w_ssim: m.w_ssim,
            w_lpips: m.w_lpips,
            per_step: m.per_step.iter().map(|s| s.warp_error).collect(),
        });
    }
    let popping = PoppingResult {
        camera: v.label,
        times: v.times,
        pops: pops.pops,
        mass: pops.mass,
    };
    Ok((out, popping))
}

/// Copies the first temporal entry (exact flow when there is one) into the scale's
/// `warp_error`, `w_ssim`, `w_lpips` and `flow` fields.
pub fn set_primary(result: &mut ScaleResult) {
    if let Some(t) = result.temporal.first() {
        result.warp_error = Some(t.warp_error);
        result.w_ssim = Some(t.w_ssim);
        result.w_lpips = t.w_lpips;
        result.flow = Some(t.flow.clone());
    }
}
