//! Which training views the motion filter observes, and canonical centres as
//! points: shared by the trainer's filter refreshes and a trained scene's load.

use maaf_autodiff::Tensor;
use maaf_filter::{CameraTime, observed_frames};

/// Rows of an `[N, 3]` tensor as points (the observation table's input).
pub fn centres(t: &Tensor<f32>) -> Vec<[f32; 3]> {
    t.data()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}

/// The training views (by their times) a filter that `observes` reads: at most
/// `max_views` by [`observed_frames`], none for a filter that reads no observation;
/// and each view's frame in the observation table.
pub fn observed_views(
    view_times: &[f64],
    observes: bool,
    max_views: usize,
) -> (Vec<CameraTime>, Vec<Option<usize>>) {
    let mut slot = vec![None; view_times.len()];
    if !observes {
        return (Vec::new(), slot);
    }
    let all: Vec<CameraTime> = view_times
        .iter()
        .enumerate()
        .map(|(i, &t)| CameraTime {
            camera: i,
            time: t as f32,
        })
        .collect();
    let kept = observed_frames(&all, max_views);
    for (frame, &v) in kept.iter().enumerate() {
        slot[v] = Some(frame);
    }
    (kept.iter().map(|&v| all[v]).collect(), slot)
}
