//! Filter configuration, validated once at start-up (defaults: the paper's Sec. 5; docs/config.md).

use serde::{Deserialize, Serialize};

/// Errors of the filter crate. Configuration errors name the offending field.
#[derive(Debug, thiserror::Error)]
pub enum FilterError {
    /// A configuration value is out of range or not finite.
    #[error("filter config: field `{field}`: {message}")]
    Config {
        /// Offending field (as spelled in the JSON config).
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// The configuration JSON is malformed (serde's message names the field).
    #[error("filter config: invalid JSON: {0}")]
    Json(String),
    /// No Gaussian is visible in any training frame, so no sampling rate exists
    /// (Mip-Splatting's "unseen Gaussians get the smallest nu seen" has nothing to use).
    #[error("no Gaussian is visible from any training camera: cannot estimate a sampling rate")]
    NothingVisible,
    /// Inputs of inconsistent sizes (e.g. a frame index out of range).
    #[error("{0}")]
    Shape(String),
    /// Writing an analysis export failed.
    #[error("{path}: {source}")]
    Io {
        /// File that failed.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
}

/// Which 3D smoothing filter the trainer applies: a built-in one, or a filter a
/// program registered under a name of its own in a [`crate::FilterRegistry`]. In
/// JSON the name as a string (`"motion"`, `"median"`), so configs written before
/// custom filters read unchanged.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum FilterKind {
    /// No 3D filter (variance 0).
    None,
    /// Mip-Splatting's static 3D filter on the canonical centres (paper Eq. 2,
    /// the "SaRO-GS + 3D filter" baseline of Tab. 6).
    Mip3d,
    /// The paper's motion-aware filter nu(t) (Sec. 4, Algorithm 1).
    #[default]
    Motion,
    /// A filter registered under this name by the program that trains the run
    /// (`maaf::cli::Maaf::filter`, docs/extending.md).
    Custom(String),
}

impl FilterKind {
    /// The config name (`"none"`, `"mip3d"`, `"motion"`, or the custom filter's), as
    /// `filter.kind` spells it.
    pub fn name(&self) -> &str {
        match self {
            FilterKind::None => "none",
            FilterKind::Mip3d => "mip3d",
            FilterKind::Motion => "motion",
            FilterKind::Custom(name) => name,
        }
    }

    /// The kind `filter.kind = name` selects: a built-in by its name, any other name
    /// a custom filter.
    pub fn from_name(name: &str) -> Self {
        match name {
            "none" => FilterKind::None,
            "mip3d" => FilterKind::Mip3d,
            "motion" => FilterKind::Motion,
            other => FilterKind::Custom(other.to_string()),
        }
    }
}

impl Serialize for FilterKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for FilterKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(FilterKind::from_name(&String::deserialize(d)?))
    }
}

/// How the motion-aware filter turns a Gaussian's observations `(t_j, x_j = f_j/d_j)`
/// into nu(t). Both are stored as the same per-bin curve ([`crate::MotionCurves`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionEstimator {
    /// The paper's estimator (Sec. 4, Algorithm 1): the mode in f/d of the Parzen
    /// density with a Weibull kernel in f/d and a Gaussian kernel in t.
    #[default]
    Kde,
    /// maaf's, not the paper's: Mip-Splatting's Eq. 2 restricted to a time window,
    /// `nu(t) = max { x_j : |t_j - t| <= h_t }` (normalised times), so nu(t) is the
    /// highest sampling rate any training view has at times near t. It follows f/d
    /// wherever it moves, without the KDE's upward bias of about `lambda h_x x_max`.
    WindowMax,
}

impl MotionEstimator {
    /// The config name (`"kde"`, `"window_max"`), as `filter.estimator` spells it.
    pub fn name(self) -> &'static str {
        match self {
            MotionEstimator::Kde => "kde",
            MotionEstimator::WindowMax => "window_max",
        }
    }
}

/// When the filter is recomputed, outside the tape. It is always computed once
/// before the first iteration (the trainer's first step does it, as Mip-Splatting
/// does); this schedule says when it is recomputed.
///
/// Mip-Splatting (`train.py`) recomputes once before training, after every
/// densification, and every 100 iterations after densification ends while
/// `iteration < iterations - 100`; the paper (supp. Tab. "update interval") keeps
/// a 100-iteration interval. Here: at iteration `i` (1-based, after that step's
/// update) the filter is due when
/// `(i >= start && (i - start) % every == 0 && i < total)` or when a densification
/// happened at this step (`after_densify`), never at or after the last iteration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefreshSchedule {
    /// First periodic refresh iteration (600).
    pub start: u64,
    /// Interval in iterations (100; paper supp. ablation 100/200/300).
    pub every: u64,
    /// Also refresh after every densification (clone/split/prune).
    pub after_densify: bool,
}

impl Default for RefreshSchedule {
    fn default() -> Self {
        RefreshSchedule {
            start: 600,
            every: 100,
            after_densify: true,
        }
    }
}

impl RefreshSchedule {
    /// Whether the filter must be recomputed after iteration `iteration` (1-based)
    /// of a run of `total` iterations; `densified` says whether this iteration
    /// cloned, split or pruned Gaussians. Never true at the last iteration
    /// (the filter of the final model is the one computed before it, as in Mip-Splatting).
    pub fn due(&self, iteration: u64, total: u64, densified: bool) -> bool {
        if iteration >= total {
            return false;
        }
        let periodic =
            iteration >= self.start && (iteration - self.start).is_multiple_of(self.every.max(1));
        periodic || (self.after_densify && densified)
    }
}

/// Every parameter of both filters. Build with [`FilterConfig::default`] (the
/// paper's values) and check with [`FilterConfig::validate`], or parse with
/// [`FilterConfig::from_json_str`], which validates.
///
/// Defaults: `h_x = 0.3, h_t = 0.05, T = 100, k = 10` (paper Sec. 5, "Unless stated
/// otherwise"); `lambda = 1`, `D = 101` chosen here (not given in the paper):
///
/// * **lambda = 1**: in Algorithm 1 the Weibull kernel is evaluated at
///   `u = (g_x - xbar)/h_x`, so `K_w(u; k, lambda) = K_w(u / lambda; k, 1) / lambda`:
///   the argmax depends on `lambda` and `h_x` only through their product
///   `lambda * h_x`. `lambda = 1` is the one value for which the paper's `h_x`
///   (and its ablation 0.1/0.2/0.3, Tab. 7) is the kernel's scale in normalised
///   f/d units; any other lambda just rescales h_x. With k = 10 the kernel in
///   `g_x` peaks `0.99 lambda h_x` above each observation (the "bias toward the
///   maximum" of Sec. 4) with a width (std) of `0.12 lambda h_x`.
/// * **D = 101**: the grid step is exactly 0.01 (nu quantised to 1% of x_max,
///   i.e. < 0.5% error, far below the filter's own tolerance), and it resolves the
///   kernel width `0.12 * 0.3 = 0.036` with 3.6 points per std, still 1.2 at the
///   smallest ablated `h_x = 0.1`. The index fits a `u8` (D <= 255), which keeps
///   the stored curve at one byte per time bin.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FilterConfig {
    /// Which filter the trainer applies.
    pub kind: FilterKind,
    /// How the motion-aware filter estimates nu(t): the paper's KDE (default) or
    /// maaf's windowed maximum.
    pub estimator: MotionEstimator,
    /// Filter size `s` of the variance `s / nu^2` (Mip-Splatting code: 0.2; the
    /// paper's Eq. 4 writes `s / nu`, maaf follows the code's squared form).
    pub s3d: f32,
    /// Near plane: a centre is visible only if its camera depth `z > near` (0.2,
    /// Mip-Splatting `compute_3D_filter` and the rasterizer's frustum test).
    pub near: f32,
    /// Screen margin: visible if `-margin W <= u <= (1 + margin) W` (same for v, H); 0.15.
    pub margin: f32,
    /// Bandwidth of the Weibull kernel in normalised f/d (Alg. 1 line 7), 0.3.
    pub h_x: f32,
    /// Bandwidth of the Gaussian kernel in normalised time (Alg. 1 line 7), 0.05;
    /// the half-width of the time window for [`MotionEstimator::WindowMax`].
    pub h_t: f32,
    /// Weibull shape k (Alg. 1 line 1), 10. Must be >= 1 (pole at u = 0 below 1).
    pub weibull_k: f32,
    /// Weibull scale lambda (Alg. 1 line 1), 1 (see the type docs).
    pub weibull_lambda: f32,
    /// Number of f/d grid points D over [0, 1] (Alg. 1 line 4), 101; 2..=255.
    pub grid_x: usize,
    /// Number of time grid points T over the time range (Alg. 1 line 4), 100; >= 2.
    pub grid_t: usize,
    /// Time range `[t0, t1]` mapped to the paper's [0, 1] time grid (D-NeRF: [0, 1]).
    pub time_range: [f32; 2],
    /// The Gaussian time kernel is truncated at `|u| > time_support` (in units of
    /// h_t), 4: weights below `exp(-8) = 3.4e-4` of the peak are dropped. A time bin
    /// with no observation within `time_support * h_t` has zero density and falls
    /// back to the static nu. The brute-force oracle uses the same kernel.
    pub time_support: f32,
    /// The Weibull kernel is truncated where it is below `weibull_cutoff` times its
    /// peak (1e-7, the f32 relative precision), which bounds its support to a band
    /// of grid points above each observation. The oracle uses the same kernel.
    pub weibull_cutoff: f32,
    /// A time bin whose maximal density `max_d rho[d, s]` is `<= density_floor`
    /// counts as "no observation near t" and falls back to the static nu
    /// (1e-30: far below any real density, above f32 underflow noise).
    pub density_floor: f32,
    /// Most training views whose f/d the motion filter keeps per Gaussian, 2048:
    /// the observation table holds `4 * min(views, max_views)` bytes per Gaussian
    /// (8 kB, 246 MB at 30 000 Gaussians). With more views it observes every camera
    /// of an even stride of the times ([`crate::observed_frames`]). A bound of maaf's:
    /// the paper observes every training view (D-NeRF's 150-200 are far below it;
    /// Panoptic's 4 050 are not).
    pub max_views: usize,
    /// When to recompute.
    pub refresh: RefreshSchedule,
    /// A filter of one's own's options (`"filter": {"kind": "NAME", "options":
    /// {...}}`), for its factory to read and check, naming the field; the built-in
    /// filters take none. Left out of the JSON when empty.
    #[serde(skip_serializing_if = "serde_json::Map::is_empty")]
    pub options: serde_json::Map<String, serde_json::Value>,
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig {
            kind: FilterKind::Motion,
            estimator: MotionEstimator::Kde,
            s3d: 0.2,
            near: 0.2,
            margin: 0.15,
            h_x: 0.3,
            h_t: 0.05,
            weibull_k: 10.0,
            weibull_lambda: 1.0,
            grid_x: 101,
            grid_t: 100,
            time_range: [0.0, 1.0],
            time_support: 4.0,
            weibull_cutoff: 1e-7,
            density_floor: 1e-30,
            max_views: 2048,
            refresh: RefreshSchedule::default(),
            options: serde_json::Map::new(),
        }
    }
}

/// Why `name` cannot name a custom filter, if it cannot: 1 to 64 ASCII letters,
/// digits or `_`, and not `window_max` (the built-in spelled `"kind": "motion",
/// "estimator": "window_max"`).
pub fn name_problem(name: &str) -> Option<String> {
    if !maaf_io::is_plugin_name(name) {
        Some(format!(
            "`{name}` is not a filter name (1 to 64 letters, digits or _)"
        ))
    } else if name == "window_max" {
        Some(
            "`window_max` is the motion filter's estimator: \"kind\": \"motion\", \"estimator\": \"window_max\""
                .to_string(),
        )
    } else {
        None
    }
}

impl FilterConfig {
    /// The name of the filter this config selects in a [`crate::FilterRegistry`]:
    /// `filter.kind`, except that the motion filter with the windowed maximum is
    /// `"window_max"` (the KDE keeps `"motion"`).
    pub fn filter_name(&self) -> &str {
        match (&self.kind, self.estimator) {
            (FilterKind::Motion, MotionEstimator::WindowMax) => "window_max",
            (kind, _) => kind.name(),
        }
    }

    /// Parses a JSON config (missing fields take their defaults, unknown fields are
    /// rejected) and validates it.
    pub fn from_json_str(text: &str) -> Result<Self, FilterError> {
        let cfg: FilterConfig =
            serde_json::from_str(text).map_err(|e| FilterError::Json(e.to_string()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks every field; the error names the first bad one. Call at start-up so a
    /// bad value never surfaces mid-training.
    pub fn validate(&self) -> Result<(), FilterError> {
        let bad = |field: &'static str, message: String| FilterError::Config { field, message };
        if let FilterKind::Custom(name) = &self.kind
            && let Some(problem) = name_problem(name)
        {
            return Err(bad("kind", problem));
        }
        if !matches!(self.kind, FilterKind::Custom(_)) && !self.options.is_empty() {
            return Err(bad(
                "options",
                format!(
                    "the built-in filter `{}` takes no options (options are for a filter of one's own)",
                    self.filter_name()
                ),
            ));
        }
        let positive = [
            ("s3d", self.s3d),
            ("h_x", self.h_x),
            ("h_t", self.h_t),
            ("weibull_lambda", self.weibull_lambda),
            ("time_support", self.time_support),
        ];
        for (field, v) in positive {
            if !v.is_finite() {
                return Err(bad(field, format!("{v} is not finite")));
            }
            if v <= 0.0 {
                return Err(bad(field, format!("{v} must be > 0")));
            }
        }
        let non_negative = [
            ("near", self.near),
            ("margin", self.margin),
            ("density_floor", self.density_floor),
        ];
        for (field, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, format!("{v} must be finite and >= 0")));
            }
        }
        if !self.weibull_k.is_finite() {
            return Err(bad(
                "weibull_k",
                format!("{} is not finite", self.weibull_k),
            ));
        }
        if self.weibull_k < 1.0 {
            return Err(bad(
                "weibull_k",
                format!(
                    "{} must be >= 1 (k <= 0 is no distribution; for 0 < k < 1 the kernel \
                     has a pole at u = 0 and is not biased toward the maximum, paper Sec. 4)",
                    self.weibull_k
                ),
            ));
        }
        if !(self.weibull_cutoff.is_finite()
            && self.weibull_cutoff > 0.0
            && self.weibull_cutoff < 1.0)
        {
            return Err(bad(
                "weibull_cutoff",
                format!("{} must be in (0, 1)", self.weibull_cutoff),
            ));
        }
        if !(2..=255).contains(&self.grid_x) {
            return Err(bad(
                "grid_x",
                format!(
                    "D = {} must be in 2..=255 (the nu index is stored in one byte)",
                    self.grid_x
                ),
            ));
        }
        if self.grid_t < 2 {
            return Err(bad("grid_t", format!("T = {} must be >= 2", self.grid_t)));
        }
        let [t0, t1] = self.time_range;
        if !(t0.is_finite() && t1.is_finite()) {
            return Err(bad("time_range", format!("[{t0}, {t1}] is not finite")));
        }
        if t1 <= t0 {
            return Err(bad("time_range", format!("[{t0}, {t1}] is empty")));
        }
        if self.refresh.every == 0 {
            return Err(bad("refresh.every", "must be >= 1".into()));
        }
        if self.max_views == 0 {
            return Err(bad("max_views", "must be >= 1".into()));
        }
        Ok(())
    }

    /// Maps a time to the paper's normalised [0, 1] time axis.
    pub fn normalise_time(&self, t: f32) -> f32 {
        let [t0, t1] = self.time_range;
        (t - t0) / (t1 - t0)
    }
}

#[cfg(test)]
mod tests;
