//! Configuration of the tracking representation: the frame schedule, the neighbour
//! regularisers and the learning rates (Dynamic 3D Gaussians `train.py`,
//! `loss.py` `LOSS_WEIGTHS`, `initialize_optimizer`).

use serde::{Deserialize, Serialize};

use super::schedule::FrameSchedule;

/// Learning rates (Dynamic 3D Gaussians `initialize_optimizer`), constant over the
/// run; opacity and log-scale are frozen after frame 0
/// (`initialize_post_first_timestep`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackLr {
    /// Centres, times the scene extent (1.6e-4; the reference's scene radius is the
    /// same 1.1 x camera radius).
    pub position: f64,
    /// RGB colour (2.5e-3); the higher SH bands, when `sh_degree` > 0, a twentieth.
    pub colour: f64,
    /// Quaternion (1e-3).
    pub rotation: f64,
    /// Opacity logit (0.05), frame 0 only.
    pub opacity: f64,
    /// Log-scale (1e-3), frame 0 only.
    pub scaling: f64,
}

impl Default for TrackLr {
    fn default() -> Self {
        TrackLr {
            position: 1.6e-4,
            colour: 2.5e-3,
            rotation: 1e-3,
            opacity: 0.05,
            scaling: 1e-3,
        }
    }
}

/// Configuration of the tracking representation (`"model": {"kind": "track"}`;
/// missing fields take the defaults, which are the reference's but for
/// `first_frame_iterations`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackConfig {
    /// Share of the run's `iterations` that trains frame 0, in (0, 1]:
    /// `round(share * iterations)` (at least 1); the rest is split evenly over the
    /// later frames, the remainder one iteration more each to the first of them (the
    /// reference: 10 000 for frame 0, 2 000 for each later frame).
    pub first_frame_iterations: f64,
    /// Neighbours of each Gaussian in the regularisers (20).
    pub knn: usize,
    /// `lambda` of the neighbour weights `exp(-lambda |mu_j0 - mu_i0|^2)`, in inverse
    /// squared world units (2000, the reference's, for Panoptic's metres).
    pub neighbour_falloff: f64,
    /// Weight of the local-rigidity term (4).
    pub rigidity: f64,
    /// Weight of the rotation-similarity term (4).
    pub rotation: f64,
    /// Weight of the isometry term (2).
    pub isometry: f64,
    /// Weight of the colour-consistency term (0.01).
    pub colour_consistency: f64,
    /// SH degree, 0..=3 (0: one RGB colour per Gaussian, the reference's).
    pub sh_degree: usize,
    /// Learning rates.
    pub lr: TrackLr,
}

impl Default for TrackConfig {
    fn default() -> Self {
        TrackConfig {
            first_frame_iterations: 0.2,
            knn: 20,
            neighbour_falloff: 2000.0,
            rigidity: 4.0,
            rotation: 4.0,
            isometry: 2.0,
            colour_consistency: 0.01,
            sh_degree: 0,
            lr: TrackLr::default(),
        }
    }
}

impl TrackConfig {
    /// SH coefficients per colour channel, `(degree + 1)^2`.
    pub fn sh_coeffs(&self) -> usize {
        (self.sh_degree + 1) * (self.sh_degree + 1)
    }

    /// The last iteration of frame 0 in a run of `iterations`: densification and the
    /// opacity reset must end by then.
    pub fn first_frame_end(&self, iterations: usize) -> usize {
        FrameSchedule::first_frame_end(self.first_frame_iterations, iterations)
    }

    /// Checks every value, naming the field and its allowed range.
    pub fn validate(&self) -> Result<(), String> {
        let bad = |field: &str, range: &str, v: &dyn std::fmt::Display| {
            Err(format!("model.{field} = {v}: must be {range}"))
        };
        let share = self.first_frame_iterations;
        if !(share.is_finite() && share > 0.0 && share <= 1.0) {
            return bad("first_frame_iterations", "in (0, 1]", &share);
        }
        if self.knn > 256 {
            return bad("knn", "in 0..=256", &self.knn);
        }
        if self.sh_degree > 3 {
            return bad("sh_degree", "in 0..=3", &self.sh_degree);
        }
        let l = &self.lr;
        let non_negative = [
            ("neighbour_falloff", self.neighbour_falloff),
            ("rigidity", self.rigidity),
            ("rotation", self.rotation),
            ("isometry", self.isometry),
            ("colour_consistency", self.colour_consistency),
            ("lr.position", l.position),
            ("lr.colour", l.colour),
            ("lr.rotation", l.rotation),
            ("lr.opacity", l.opacity),
            ("lr.scaling", l.scaling),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "a finite number >= 0", &v);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_bad_value_names_its_key() {
        TrackConfig::default().validate().expect("defaults");
        type Change = fn(&mut TrackConfig);
        let cases: [(&str, Change); 6] = [
            ("first_frame_iterations", |c| c.first_frame_iterations = 0.0),
            ("first_frame_iterations", |c| c.first_frame_iterations = 1.5),
            ("knn", |c| c.knn = 1000),
            ("sh_degree", |c| c.sh_degree = 4),
            ("neighbour_falloff", |c| c.neighbour_falloff = -1.0),
            ("lr.scaling", |c| c.lr.scaling = f64::NAN),
        ];
        for (key, change) in cases {
            let mut c = TrackConfig::default();
            change(&mut c);
            let msg = c.validate().expect_err(key);
            assert!(msg.starts_with(&format!("model.{key} = ")), "{msg}");
        }
        let c: Result<TrackConfig, _> = serde_json::from_str(r#"{"k": 3}"#);
        assert!(c.is_err(), "unknown keys are refused");
    }
}
