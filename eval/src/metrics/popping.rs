//! Popping of single Gaussians in a fixed-camera video: how much of each frame step's
//! change comes from Gaussians that appear or vanish within that one step.
//!
//! The flow-warped metrics ([`super::temporal`]) say *that* a step of a video changes
//! more than the motion explains; this says whether single primitives cause it. With
//! the visible weight of Gaussian `k` in frame `t`,
//!
//! `W_k(t) = sum_p alpha_k(p) T_k(p)`   (pixels; `T_k` the transmittance in front of it),
//!
//! i.e. how many pixels' worth of colour it contributes, a Gaussian *pops* in the step
//! `t -> t + 1` when its weight changes by at least [`POP_RATIO`] of the larger of the
//! two while that larger one is at least [`MIN_POP_PIXELS`]:
//!
//! `|W_k(t + 1) - W_k(t)| >= POP_RATIO * max(W_k(t), W_k(t + 1)) >= POP_RATIO * MIN_POP_PIXELS`.
//!
//! A Gaussian that halves or doubles its contribution within one frame step (temporal
//! opacity switching it on or off, a smoothing filter whose nu(t) jumps, a sudden
//! scale change, an occluder arriving in one step) pops; one that fades over several
//! steps does not. Per step the measure reports the number of popping Gaussians and
//! their *popped mass* `sum_{k pops} |W_k(t + 1) - W_k(t)| / (H W)`: the fraction of the
//! image whose colour changed hands through pops. Weights are measured at the
//! rendered scale, so a Gaussian of one pixel at 1x counts 16 pixels at 4x.

/// Relative change of a Gaussian's visible weight within one step that counts as a
/// pop: 1/2 (it at least halves or doubles).
pub const POP_RATIO: f64 = 0.5;

/// Smallest visible weight, in pixels, of the larger of the two frames for a change to
/// count: a Gaussian that never covers a whole pixel cannot visibly pop.
pub const MIN_POP_PIXELS: f64 = 1.0;

/// Popping of one video: per step `t_j -> t_{j+1}`, the number of popping Gaussians and
/// their popped mass (fraction of the frame's pixels). Built one step at a time
/// ([`PoppingMetrics::push_step`]), so only two frames' weights need to be in memory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PoppingMetrics {
    /// Popping Gaussians per step, `T - 1` values.
    pub pops: Vec<usize>,
    /// Popped mass per step, `T - 1` values on \[0, 1] (up to rounding).
    pub mass: Vec<f64>,
}

impl PoppingMetrics {
    /// Appends the step between two frames whose visible weights are `now[k]` and
    /// `next[k]` (the same Gaussians in both), for frames of `pixels` pixels.
    ///
    /// # Panics
    /// When the frames hold different numbers of Gaussians or `pixels` is 0.
    pub fn push_step(&mut self, now: &[f64], next: &[f64], pixels: usize) {
        assert!(pixels > 0, "popping: frames have no pixels");
        assert_eq!(
            now.len(),
            next.len(),
            "popping: every frame must hold the same Gaussians"
        );
        let mut count = 0;
        let mut moved = 0.0;
        for (&a, &b) in now.iter().zip(next) {
            let high = a.max(b);
            let change = (b - a).abs();
            if high >= MIN_POP_PIXELS && change >= POP_RATIO * high {
                count += 1;
                moved += change;
            }
        }
        self.pops.push(count);
        self.mass.push(moved / pixels as f64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every step of the frames whose visible weights are `weights[t][k]`.
    fn popping(weights: &[Vec<f64>], pixels: usize) -> PoppingMetrics {
        let mut m = PoppingMetrics::default();
        for pair in weights.windows(2) {
            m.push_step(&pair[0], &pair[1], pixels);
        }
        m
    }

    #[test]
    fn counts_halving_and_appearing_gaussians_but_not_fades_or_specks() {
        // Gaussian 0: steady; 1: appears (0 -> 40 px); 2: fades 30 -> 20 -> 14 (never
        // halves in a step); 3: a speck 0.9 -> 0 (below one pixel); 4: halves exactly
        // 8 -> 4 in the second step.
        let w = vec![
            vec![50.0, 0.0, 30.0, 0.9, 8.0],
            vec![50.0, 40.0, 20.0, 0.0, 8.0],
            vec![50.0, 40.0, 14.0, 0.0, 4.0],
        ];
        let m = popping(&w, 100);
        assert_eq!(m.pops, vec![1, 1]);
        assert!((m.mass[0] - 0.40).abs() < 1e-12, "{:?}", m.mass);
        assert!((m.mass[1] - 0.04).abs() < 1e-12, "{:?}", m.mass);
    }

    #[test]
    fn a_still_video_does_not_pop() {
        let w = vec![vec![3.0, 7.5, 0.0]; 4];
        let m = popping(&w, 10);
        assert_eq!(m.pops, vec![0, 0, 0]);
        assert_eq!(m.mass, vec![0.0, 0.0, 0.0]);
    }
}
