//! Which frame each iteration trains (Dynamic 3D Gaussians `train.py`: the first
//! timestep for `INITIAL_TIMESTEP_ITERATIONS`, then each later one for
//! `TIMESTEP_ITERATIONS`, in time order).

/// The frames (the distinct training times, ascending) and the iterations each one
/// trains: frame 0 the first `round(share * iterations)` (at least 1), the rest split
/// evenly over the later frames, the remainder one more each to the first ones.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSchedule {
    times: Vec<f64>,
    /// Last iteration (1-based, inclusive) of each frame.
    ends: Vec<usize>,
}

impl FrameSchedule {
    /// Iterations of frame 0 in a run of `iterations`: `round(share * iterations)`, at
    /// least 1 and at most `iterations`.
    pub fn first_frame_end(share: f64, iterations: usize) -> usize {
        ((share * iterations as f64).round() as usize).clamp(1, iterations.max(1))
    }

    /// The schedule of `times` (distinct, ascending, at least one) over `iterations`;
    /// an error, naming the key, when a later frame would get no iteration.
    pub fn new(times: Vec<f64>, iterations: usize, share: f64) -> Result<Self, String> {
        if times.is_empty() {
            return Err("model.kind track: the data has no training time".into());
        }
        let later = times.len() - 1;
        let first = Self::first_frame_end(share, iterations);
        let rest = iterations.saturating_sub(first);
        if later > 0 && rest < later {
            return Err(format!(
                "model.first_frame_iterations = {share}: of iterations = {iterations}, frame 0 takes {first} and leaves {rest} for {later} later frames (each needs at least one): lower it or raise iterations"
            ));
        }
        let ends = match rest.checked_div(later) {
            Some(each) => {
                let extra = rest % later;
                let mut ends = vec![first];
                for f in 0..later {
                    ends.push(ends[f] + each + usize::from(f < extra));
                }
                ends
            }
            // A single frame takes the whole run.
            None => vec![iterations.max(1)],
        };
        Ok(FrameSchedule { times, ends })
    }

    /// The frame times.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.times.len()
    }

    /// The frame iteration `iteration` (1-based) trains; the last frame past the end.
    pub fn frame_of(&self, iteration: usize) -> usize {
        self.ends
            .partition_point(|&end| end < iteration)
            .min(self.frames() - 1)
    }

    /// The first iteration of frame `frame`.
    pub fn start(&self, frame: usize) -> usize {
        match frame {
            0 => 1,
            f => self.ends[f - 1] + 1,
        }
    }

    /// The last iteration of frame 0 (its densification must end by then).
    pub fn first_end(&self) -> usize {
        self.ends[0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_zero_takes_its_share_and_the_rest_is_split_evenly() {
        let times = vec![0.0, 0.1, 0.2, 0.3];
        // 100 iterations, 0.25 to frame 0: 25, then 75 = 25 x 3.
        let s = FrameSchedule::new(times.clone(), 100, 0.25).expect("valid");
        assert_eq!(s.ends, [25, 50, 75, 100]);
        assert_eq!((s.frame_of(1), s.frame_of(25), s.frame_of(26)), (0, 0, 1));
        assert_eq!((s.frame_of(100), s.frame_of(500)), (3, 3));
        assert_eq!((s.start(0), s.start(1), s.start(3)), (1, 26, 76));
        // 101 iterations, 0.3: 30, then 71 = 24 + 24 + 23 (the remainder first).
        let s = FrameSchedule::new(times.clone(), 101, 0.3).expect("valid");
        assert_eq!(s.ends, [30, 54, 78, 101]);
        let msg = FrameSchedule::new(times, 10, 0.9).expect_err("too few");
        assert!(msg.contains("model.first_frame_iterations = 0.9"), "{msg}");
        let one = FrameSchedule::new(vec![0.5], 40, 0.2).expect("one frame");
        assert_eq!((one.ends.clone(), one.frame_of(40)), (vec![40], 0));
    }
}
