//! What the tracking model tells the trainer beyond modelling: its finished frames
//! (state outside the store, resized with the rows and carried in checkpoints), the
//! one time each iteration trains on, and the Adam moments a new frame restarts.

use std::sync::Arc;

use maaf_autodiff::{Float, PerGaussian, Tensor};

use super::TrackModel;
use super::frames::{BUFFERS, Frame, stack, unstack};
use crate::{TrainingHooks, TrainingTime};

impl<T: Float> TrackModel<T> {
    /// The frame iteration `iteration` trains: the schedule's, or the current one if
    /// the model is past it (loaded from a run with another schedule).
    fn frame_at(&self, iteration: usize) -> usize {
        self.schedule.frame_of(iteration).max(self.current_frame())
    }

    /// Restores the finished frames and the previous colours from the four buffers
    /// (all present in `pending`); the neighbours are found again unless frame 0 is
    /// the one they were found on.
    fn restore(&mut self, pending: Vec<(String, Tensor<T>)>) -> Result<(), String> {
        let n = self.params.value(self.ids.xyz).rows();
        let get = |name: &str| {
            pending
                .iter()
                .find(|(k, _)| k == name)
                .map(|(_, v)| v)
                .ok_or_else(|| format!("track: buffer `{name}` is missing"))
        };
        let means = unstack(BUFFERS[0], get(BUFFERS[0])?, n, 3)?;
        let quats = unstack(BUFFERS[1], get(BUFFERS[1])?, n, 4)?;
        let times = get(BUFFERS[2])?;
        let colour = get(BUFFERS[3])?;
        let f = means.len();
        let want: Vec<T> = self
            .schedule
            .times()
            .iter()
            .take(f)
            .map(|&t| T::of(t))
            .collect();
        if quats.len() != f || times.data() != want.as_slice() || f >= self.schedule.frames() {
            return Err(format!(
                "track: the checkpoint's {f} finished frames (times {:?}, {} quaternion frames) are not the first of this run's {} frames (times {:?})",
                times.data(),
                quats.len(),
                self.schedule.frames(),
                self.schedule.times()
            ));
        }
        if colour.shape() != [n, 3] {
            return Err(format!(
                "buffer `{}` has shape {:?}, expected [{n}, 3]",
                BUFFERS[3],
                colour.shape()
            ));
        }
        if self.finished.len() > f {
            return Err(format!(
                "track: the checkpoint finished {f} frames, but this run's schedule is already at frame {} (model.first_frame_iterations or iterations changed since)",
                self.finished.len()
            ));
        }
        let frames: Vec<Arc<Frame<T>>> = means
            .into_iter()
            .zip(quats)
            .map(|(means, quats)| Arc::new(Frame { means, quats }))
            .collect();
        if self.finished.first().map(|f| &f.means) != Some(&frames[0].means) {
            self.neighbours = Some(Arc::new(self.find_neighbours(&frames[0])));
        }
        self.finished = frames;
        self.previous_colour = Some(Arc::new(colour.clone()));
        Ok(())
    }
}

/// The finished frames (per-Gaussian state outside the store), the frame schedule's
/// training times and the restart of the current frame's optimiser moments.
impl<T: Float> TrainingHooks<T> for TrackModel<T> {
    /// Resizes the finished frames and the previous colours; the neighbours are found
    /// again on the selected frame-0 centres (densification happens only in frame 0,
    /// so this runs only when a program's strategy changes the rows later).
    fn select_state_rows(&mut self, index: &[usize]) {
        for frame in &mut self.finished {
            Arc::make_mut(frame).select_rows(index);
        }
        if let Some(colour) = &mut self.previous_colour {
            Arc::make_mut(colour).select_rows(index);
        }
        if let Some(first) = self.finished.first().cloned() {
            self.neighbours = Some(Arc::new(self.find_neighbours(&first)));
        }
    }

    /// The finished frames' centres and quaternions (what it renders with).
    fn state_scalars(&self) -> usize {
        self.finished
            .iter()
            .map(|f| f.means.len() + f.quats.len())
            .sum()
    }

    /// [`BUFFERS`]: the finished frames' centres, quaternions and times, and the
    /// previous colours; none in frame 0.
    fn buffers(&self) -> Vec<(String, Tensor<T>)> {
        let Some(colour) = &self.previous_colour else {
            return Vec::new();
        };
        let f = self.finished.len();
        let times = self.schedule.times()[..f]
            .iter()
            .map(|&t| T::of(t))
            .collect();
        vec![
            (BUFFERS[0].into(), stack(&self.finished, |f| &f.means)),
            (BUFFERS[1].into(), stack(&self.finished, |f| &f.quats)),
            (BUFFERS[2].into(), Tensor::from_vec(times, &[f])),
            (BUFFERS[3].into(), (**colour).clone()),
        ]
    }

    /// Collects the buffers; the frames are restored once all four have arrived. An
    /// error names the buffer, or the frames when they are not this run's.
    fn load_buffer(&mut self, name: &str, value: Tensor<T>) -> Result<(), String> {
        if !BUFFERS.contains(&name) {
            return Err(format!("track has no buffer `{name}`"));
        }
        self.pending.retain(|(k, _)| k != name);
        self.pending.push((name.to_string(), value));
        if self.pending.len() < BUFFERS.len() {
            return Ok(());
        }
        let pending = std::mem::take(&mut self.pending);
        self.restore(pending)
    }

    /// The time of the frame `iteration` trains, from that frame's first iteration.
    fn training_time(&self, iteration: usize) -> Option<TrainingTime> {
        let f = self.frame_at(iteration);
        Some(TrainingTime {
            time: self.schedule.times()[f],
            since: self.schedule.start(f).min(iteration),
        })
    }

    /// `xyz` and `rotation` at the first iteration of every frame after the first
    /// (Dynamic 3D Gaussians `update_params_and_optimizer` zeroes `exp_avg` and
    /// `exp_avg_sq` when it writes the constant-velocity guess).
    fn reset_moments(&self, iteration: usize) -> Vec<String> {
        let f = self.frame_at(iteration);
        if f == 0 || iteration != self.schedule.start(f) {
            return Vec::new();
        }
        [self.ids.xyz, self.ids.rotation]
            .map(|id| self.params.param(id).name.clone())
            .to_vec()
    }
}
