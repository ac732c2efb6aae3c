//! A wall-clock budget for a run (`budget`, `maaf train --budget 10m`) and the
//! schedule scaled by one factor, which the trainer's planner chooses so that the run
//! fits the budget (`maaf_train::budget`).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::TrainConfig;
use maaf_models::scaled_count;

/// A wall time, written `90s`, `10m`, `1.5h` or `1h30m` (a bare number is seconds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallBudget {
    seconds: f64,
}

impl WallBudget {
    /// The budget in seconds.
    pub fn seconds(self) -> f64 {
        self.seconds
    }

    fn positive(seconds: f64) -> Option<Self> {
        (seconds.is_finite() && seconds > 0.0).then_some(WallBudget { seconds })
    }
}

impl FromStr for WallBudget {
    type Err = String;

    /// Parses `[number unit]...` with units `h`, `m`, `s` (a bare number: seconds).
    fn from_str(text: &str) -> Result<Self, String> {
        let bad =
            || format!("budget `{text}`: expected a wall time such as 90s, 10m, 1.5h or 1h30m");
        let trimmed = text.trim();
        if let Ok(seconds) = trimmed.parse::<f64>() {
            return Self::positive(seconds).ok_or_else(bad);
        }
        let mut seconds = 0.0;
        let mut number = String::new();
        for c in trimmed.chars() {
            let unit = match c {
                'h' => 3600.0,
                'm' => 60.0,
                's' => 1.0,
                c if c.is_ascii_digit() || c == '.' => {
                    number.push(c);
                    continue;
                }
                _ => return Err(bad()),
            };
            let value: f64 = number.parse().map_err(|_| bad())?;
            seconds += value * unit;
            number.clear();
        }
        if !number.is_empty() {
            return Err(bad());
        }
        Self::positive(seconds).ok_or_else(bad)
    }
}

impl fmt::Display for WallBudget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}s", self.seconds)
    }
}

impl Serialize for WallBudget {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

impl<'de> Deserialize<'de> for WallBudget {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Text {
            Seconds(f64),
            Written(String),
        }
        match Text::deserialize(d)? {
            Text::Seconds(s) => Self::positive(s)
                .ok_or_else(|| serde::de::Error::custom(format!("budget {s}: must be > 0"))),
            Text::Written(t) => t.parse().map_err(serde::de::Error::custom),
        }
    }
}

impl TrainConfig {
    /// The schedule scaled by `s` (0.5: half as long): the iterations and every window
    /// counted in iterations (densification from and until, the opacity reset period,
    /// pruning's window, the SH degree period, the first filter refresh, checkpoints,
    /// validations to the nearest multiple of `log_every`, and the representation's
    /// own: [`maaf_models::ModelConfig::scale_schedule`]) and the Gaussian cap, at
    /// least the initial points. The densification and refresh periods stay: each
    /// densification still averages that many views' gradients. Without the budget
    /// (the result is the schedule a budget chose).
    pub fn scaled_schedule(&self, s: f64) -> TrainConfig {
        let mut c = self.clone();
        c.budget = None;
        c.iterations = scaled_count(c.iterations, s).max(2);
        c.sh_degree_every = scaled_count(c.sh_degree_every, s);
        c.checkpoint_every = scaled_count(c.checkpoint_every, s);
        if c.val_every > 0 {
            c.val_every = scaled_count(c.val_every, s).div_ceil(c.log_every) * c.log_every;
        }
        let d = &mut c.densify;
        d.from = scaled_count(d.from, s);
        d.until = scaled_count(d.until, s).max(d.from);
        if d.opacity_reset_every > 0 {
            d.opacity_reset_every = scaled_count(d.opacity_reset_every, s);
        }
        d.max_gaussians = scaled_count(d.max_gaussians, s).max(c.init_points);
        let p = &mut c.prune;
        p.from = scaled_count(p.from, s);
        p.until = scaled_count(p.until, s).max(p.from);
        c.filter.refresh.start = scaled_count(c.filter.refresh.start as usize, s) as u64;
        c.model.scale_schedule(s);
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wall_times_parse_in_every_written_form() {
        for (text, seconds) in [
            ("90s", 90.0),
            ("10m", 600.0),
            ("1.5h", 5400.0),
            ("1h30m", 5400.0),
            ("2m30s", 150.0),
            ("45", 45.0),
        ] {
            let b: WallBudget = text.parse().expect(text);
            assert_eq!(b.seconds(), seconds, "{text}");
        }
        for text in ["", "10x", "m", "0s", "-5", "10m5"] {
            let err = text.parse::<WallBudget>().expect_err(text);
            assert!(err.contains("expected a wall time"), "{text}: {err}");
        }
        let b: WallBudget = serde_json::from_str("\"10m\"").expect("string");
        assert_eq!(b.seconds(), 600.0);
        let b: WallBudget = serde_json::from_str("600").expect("number");
        assert_eq!(serde_json::to_string(&b).expect("writes"), "\"600s\"");
    }

    #[test]
    fn a_scaled_schedule_compresses_every_window_by_one_factor() {
        let mut c: TrainConfig =
            serde_json::from_str(include_str!("../../configs/dnerf.json")).expect("preset");
        c.budget = Some("10m".parse().expect("budget"));
        let h = c.scaled_schedule(0.25);
        assert_eq!(h.budget, None);
        assert_eq!(h.iterations, 5000);
        assert_eq!((h.densify.from, h.densify.until), (125, 3750));
        assert_eq!(h.densify.every, c.densify.every);
        assert_eq!(h.densify.opacity_reset_every, 500);
        assert_eq!(h.densify.max_gaussians, 15_000);
        assert_eq!(h.sh_degree_every, 250);
        assert_eq!(h.filter.refresh.start, 150);
        assert_eq!(h.filter.refresh.every, c.filter.refresh.every);
        assert_eq!(h.val_every % h.log_every, 0);
        let maaf_models::ModelConfig::Saro(saro) = &h.model else {
            panic!("the preset is SaRO")
        };
        assert_eq!((saro.static_iterations, saro.lr.max_steps), (250, 7500));
        h.validate().expect("a valid config");
        // The cap never falls below the initial points.
        assert_eq!(c.scaled_schedule(0.01).densify.max_gaussians, c.init_points);
    }
}
