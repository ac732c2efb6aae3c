//! The frames the tracking model has finished: each one's centres and unit
//! quaternions (constants from then on), where a render time falls among the frames,
//! and the checkpoint buffers that carry them.

use std::sync::Arc;

use maaf_autodiff::{Float, PerGaussian, Tensor};

/// One frame's centres `[N, 3]` and unit quaternions `[N, 4]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame<T: Float> {
    /// Centres.
    pub means: Tensor<T>,
    /// Unit quaternions (w, x, y, z).
    pub quats: Tensor<T>,
}

impl<T: Float> Frame<T> {
    /// The frame of `means` and the unnormalised `quats` (normalised here).
    pub fn new(means: Tensor<T>, quats: &Tensor<T>) -> Self {
        Frame {
            means,
            quats: normalise_rows(quats),
        }
    }

    /// The constant-velocity guess of the next frame from this one and the one
    /// `before` it (Dynamic 3D Gaussians `initialize_per_timestep`):
    /// `mu' = mu + (mu - mu_before)`, `q' = normalise(q + (q - q_before))`.
    pub fn extrapolate(&self, before: &Frame<T>) -> Frame<T> {
        let step = |now: &Tensor<T>, then: &Tensor<T>| now.zip_map(then, |a, b| a + (a - b));
        Frame {
            means: step(&self.means, &before.means),
            quats: normalise_rows(&step(&self.quats, &before.quats)),
        }
    }
}

impl<T: Float> PerGaussian for Frame<T> {
    fn rows(&self) -> usize {
        self.means.rows()
    }

    fn select_rows(&mut self, index: &[usize]) {
        self.means.select_rows(index);
        self.quats.select_rows(index);
    }
}

/// Each row of `[N, 4]` quaternions divided by its norm.
pub fn normalise_rows<T: Float>(q: &Tensor<T>) -> Tensor<T> {
    let mut out = q.clone();
    for row in out.data_mut().chunks_exact_mut(4) {
        let norm = row
            .iter()
            .map(|&v| v * v)
            .fold(T::zero(), |a, b| a + b)
            .sqrt();
        for v in row {
            *v /= norm;
        }
    }
    out
}

/// Where a time falls among the frame times `t_0 < t_1 < ... < t_c` known so far.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum At {
    /// Frame `f` itself: at its time, or clamped before the first or after the last.
    Frame(usize),
    /// Between frame `f` and `f + 1`, a fraction `a` in (0, 1) of the way.
    Between(usize, f64),
}

/// Where `time` falls among `times` (ascending, at least one).
pub fn locate(times: &[f64], time: f64) -> At {
    let after = times.partition_point(|&t| t <= time);
    match after {
        0 => At::Frame(0),
        a if a == times.len() || times[a - 1] == time => At::Frame(a - 1),
        a => {
            let (t0, t1) = (times[a - 1], times[a]);
            At::Between(a - 1, (time - t0) / (t1 - t0))
        }
    }
}

/// Names of the buffers ([`crate::TrainingHooks::buffers`]): the finished frames'
/// centres `[F, N, 3]`, unit quaternions `[F, N, 4]` and times `[F]` (f32, checked
/// against the run's on load), and the colours at the start of the current frame
/// `[N, 3]` (the colour-consistency term's constant).
pub const BUFFERS: [&str; 4] = [
    "frame_means",
    "frame_quats",
    "frame_times",
    "previous_colour",
];

/// `frames`' `field` stacked into `[F, N, W]`.
pub fn stack<T: Float>(frames: &[Arc<Frame<T>>], field: fn(&Frame<T>) -> &Tensor<T>) -> Tensor<T> {
    let mut shape = vec![frames.len()];
    shape.extend_from_slice(field(&frames[0]).shape());
    let data = frames
        .iter()
        .flat_map(|f| field(f).data().iter().copied())
        .collect();
    Tensor::from_vec(data, &shape)
}

/// The `[F, N, W]` tensor `value` of buffer `name` split into `F` tensors `[N, W]`;
/// an error names the buffer when it is not `[F, rows, width]`.
pub fn unstack<T: Float>(
    name: &str,
    value: &Tensor<T>,
    rows: usize,
    width: usize,
) -> Result<Vec<Tensor<T>>, String> {
    let s = value.shape();
    if s.len() != 3 || s[1] != rows || s[2] != width || s[0] == 0 {
        return Err(format!(
            "buffer `{name}` has shape {s:?}, expected [frames >= 1, {rows}, {width}]"
        ));
    }
    Ok(value
        .data()
        .chunks_exact(rows * width)
        .map(|c| Tensor::from_vec(c.to_vec(), &[rows, width]))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locate_clamps_outside_and_interpolates_between() {
        let times = [0.0, 0.25, 0.5];
        assert_eq!(locate(&times, -1.0), At::Frame(0));
        assert_eq!(locate(&times, 0.0), At::Frame(0));
        assert_eq!(locate(&times, 0.25), At::Frame(1));
        assert_eq!(locate(&times, 0.5), At::Frame(2));
        assert_eq!(locate(&times, 0.9), At::Frame(2));
        assert_eq!(locate(&times, 0.3125), At::Between(1, 0.25));
        assert_eq!(locate(&[0.5], 0.1), At::Frame(0));
    }

    #[test]
    fn extrapolation_continues_the_velocity_and_stays_unit() {
        let q = |v: [f64; 4]| Tensor::<f64>::from_vec(v.to_vec(), &[1, 4]);
        let a = Frame::new(
            Tensor::from_vec(vec![0.0, 0.0, 1.0], &[1, 3]),
            &q([1.0, 0.0, 0.0, 0.0]),
        );
        let b = Frame::new(
            Tensor::from_vec(vec![0.5, 0.0, 1.0], &[1, 3]),
            &q([2.0, 0.2, 0.0, 0.0]),
        );
        let c = b.extrapolate(&a);
        assert_eq!(c.means.data(), &[1.0, 0.0, 1.0]);
        let n: f64 = c.quats.data().iter().map(|v| v * v).sum();
        assert!((n - 1.0).abs() < 1e-15);
        // No velocity against itself: the same frame, to rounding.
        let same = b.extrapolate(&b);
        assert_eq!(same.means, b.means);
        for (x, y) in same.quats.data().iter().zip(b.quats.data()) {
            assert!((x - y).abs() < 1e-15);
        }
    }
}
