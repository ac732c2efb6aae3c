//! Analysis export: chosen Gaussians' observations `(t, f/d)` and curves nu(t), as
//! JSON and CSV, to draw the paper's Fig. 3 (f/d over time for static vs moving
//! primitives). Files are written atomically (temporary file, then rename).

use std::path::Path;

use maaf_autodiff::PerGaussian;
use serde::{Deserialize, Serialize};

use crate::config::{FilterError, MotionEstimator};
use crate::curves::MotionCurves;
use crate::observations::ObservationTable;

/// One Gaussian's data for the figure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GaussianTrace {
    /// Gaussian index at export time.
    pub index: usize,
    /// Caller's label, e.g. "static" or "moving".
    pub label: String,
    /// `x_max` (Alg. 1 line 3), 0 if never observed.
    pub x_max: f32,
    /// Static Mip nu on canonical centres, if the caller has it.
    pub static_nu: Option<f32>,
    /// Observations `[t, f/d]`, sorted by time.
    pub observations: Vec<[f32; 2]>,
    /// Motion-aware curve `[bin time, nu]`, T points: the one the run's filter uses.
    pub nu: Vec<[f32; 2]>,
    /// Other estimators' curves recomputed from the same observations, for comparison
    /// (see [`AnalysisExport::compare`]).
    #[serde(default)]
    pub compared: Vec<EstimatorCurve>,
    /// How far the caller saw the Gaussian move while drawn (its drawn centres'
    /// bounding-box diagonal over the camera extent), if it measured that.
    #[serde(default)]
    pub drawn_motion: Option<f32>,
}

/// One estimator's nu(t) curve of a Gaussian.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatorCurve {
    /// The estimator's config name (`"kde"`, `"window_max"`).
    pub estimator: String,
    /// `[bin time, nu]`, T points.
    pub nu: Vec<[f32; 2]>,
}

/// A set of traces, serialisable as JSON (`{"gaussians": [...]}`) or long-format CSV.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AnalysisExport {
    /// The config name of the estimator behind each trace's `nu` (`"kde"` in exports
    /// that predate the choice).
    #[serde(default = "paper_estimator")]
    pub estimator: String,
    /// The chosen Gaussians.
    pub gaussians: Vec<GaussianTrace>,
}

fn paper_estimator() -> String {
    MotionEstimator::Kde.name().into()
}

impl AnalysisExport {
    /// Collects the traces of `chosen` (index, label) from the observations and the
    /// curves of the same refresh, made by `estimator`; `static_nu` optionally adds
    /// the Mip value.
    pub fn collect(
        table: &ObservationTable,
        curves: &MotionCurves,
        estimator: MotionEstimator,
        chosen: &[(usize, String)],
        static_nu: Option<&[f32]>,
    ) -> Result<Self, FilterError> {
        let rows = curves.rows();
        if table.rows() != rows {
            return Err(FilterError::Shape(format!(
                "export: {} observation rows vs {rows} curves",
                table.rows()
            )));
        }
        let mut gaussians = Vec::with_capacity(chosen.len());
        for (index, label) in chosen {
            let n = *index;
            if n >= rows {
                return Err(FilterError::Shape(format!(
                    "export: Gaussian {n} out of range for {rows}"
                )));
            }
            let mut observations: Vec<[f32; 2]> = table
                .observations(n)
                .into_iter()
                .map(|(t, x)| [t, x])
                .collect();
            observations.sort_by(|a, b| a[0].total_cmp(&b[0]));
            let nu = curve_points(curves, n);
            gaussians.push(GaussianTrace {
                index: n,
                label: label.clone(),
                x_max: curves.x_max()[n],
                static_nu: static_nu.and_then(|v| v.get(n).copied()),
                observations,
                nu,
                compared: Vec::new(),
                drawn_motion: None,
            });
        }
        Ok(AnalysisExport {
            estimator: estimator.name().into(),
            gaussians,
        })
    }

    /// Adds `other`'s curve of every traced Gaussian (curves of `estimator`, refreshed
    /// from the same observation table) as a compared curve.
    pub fn compare(
        &mut self,
        estimator: MotionEstimator,
        other: &MotionCurves,
    ) -> Result<(), FilterError> {
        for g in &mut self.gaussians {
            if g.index >= other.rows() {
                return Err(FilterError::Shape(format!(
                    "export: Gaussian {} out of range for {} compared curves",
                    g.index,
                    other.rows()
                )));
            }
            g.compared.push(EstimatorCurve {
                estimator: estimator.name().into(),
                nu: curve_points(other, g.index),
            });
        }
        Ok(())
    }

    /// Pretty JSON text.
    pub fn to_json(&self) -> String {
        // Plain numbers, strings and arrays: serialisation cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Long-format CSV: `gaussian,label,series,t,value` with series
    /// `observation` (value f/d), `nu` (the run's motion-aware nu at the bin time),
    /// `nu_<estimator>` (a compared curve) and `static_nu` (one row, t empty).
    pub fn to_csv(&self) -> String {
        let mut rows: Vec<[String; 5]> =
            vec![["gaussian", "label", "series", "t", "value"].map(String::from)];
        for g in &self.gaussians {
            let mut row = |series: &str, t: String, value: f32| {
                rows.push([
                    g.index.to_string(),
                    g.label.clone(),
                    series.into(),
                    t,
                    value.to_string(),
                ]);
            };
            for [t, x] in &g.observations {
                row("observation", t.to_string(), *x);
            }
            for [t, nu] in &g.nu {
                row("nu", t.to_string(), *nu);
            }
            for c in &g.compared {
                for [t, nu] in &c.nu {
                    row(&format!("nu_{}", c.estimator), t.to_string(), *nu);
                }
            }
            if let Some(v) = g.static_nu {
                row("static_nu", String::new(), v);
            }
        }
        let mut w = csv::Writer::from_writer(Vec::new());
        for r in &rows {
            // Writing strings into memory cannot fail.
            let _ = w.write_record(r);
        }
        w.into_inner()
            .ok()
            .and_then(|bytes| String::from_utf8(bytes).ok())
            .unwrap_or_default()
    }

    /// Writes [`Self::to_json`] atomically.
    pub fn write_json(&self, path: &Path) -> Result<(), FilterError> {
        write_atomic(path, self.to_json().as_bytes())
    }

    /// Writes [`Self::to_csv`] atomically.
    pub fn write_csv(&self, path: &Path) -> Result<(), FilterError> {
        write_atomic(path, self.to_csv().as_bytes())
    }
}

/// Gaussian `n`'s curve as `[bin time, nu]` points.
fn curve_points(curves: &MotionCurves, n: usize) -> Vec<[f32; 2]> {
    (0..curves.grid_t())
        .map(|s| [curves.bin_time(s), curves.nu(n, s)])
        .collect()
}

/// Writes `bytes` to `path` through a temporary sibling file and a rename, so a
/// reader never sees a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FilterError> {
    let io = |source| FilterError::Io {
        path: path.display().to_string(),
        source,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "export".into());
    let tmp = path.with_file_name(format!(".{name}.tmp{}", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })
}
