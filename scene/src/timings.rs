//! Wall time per training phase, and the CPU time they used.

use serde::{Deserialize, Serialize};

/// Seconds spent in each phase of the training step, summed over iterations.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// Binding parameters, residual field and MLPs (the deformation).
    pub field_mlp: f64,
    /// Filter fold, projection, rasterization and objective.
    pub render_forward: f64,
    /// Reverse sweep of the tape.
    pub backward: f64,
    /// The gradients' finiteness check and the Adam updates (in runs that predate
    /// [`Self::statistics`], also what that field now holds).
    pub optimiser: f64,
    /// Bookkeeping after the update: the densification statistics (screen-space
    /// gradient sums), opacity liveness and the filter's observation recording
    /// (0 in runs that predate it).
    #[serde(default)]
    pub statistics: f64,
    /// Filter refreshes (static nu or motion-aware KDE).
    pub filter_refresh: f64,
    /// Densification, pruning and opacity resets.
    pub densification: f64,
    /// CPU seconds of all the process's threads over the same phases (0 in runs
    /// that predate it); not part of [`Self::total`]. Unlike the wall phases it
    /// barely moves with other load: on an idle machine wall ≈ `cpu` / cores busy.
    #[serde(default)]
    pub cpu: f64,
}

/// How many timed phases a step has ([`Timings::phases`]).
pub const PHASE_COUNT: usize = 7;

impl Timings {
    /// Each timed phase with its name, in the step's order: field + MLPs, render
    /// forward, backward, optimiser, statistics, filter refresh, densification.
    pub fn phases(&self) -> [(&'static str, f64); PHASE_COUNT] {
        [
            ("field+MLP", self.field_mlp),
            ("render forward", self.render_forward),
            ("backward", self.backward),
            ("optimiser", self.optimiser),
            ("statistics", self.statistics),
            ("filter refresh", self.filter_refresh),
            ("densification", self.densification),
        ]
    }

    /// Sum of all phases.
    pub fn total(&self) -> f64 {
        self.phases().iter().map(|(_, s)| s).sum()
    }

    /// One line per phase with seconds, ms per iteration and share of the total.
    pub fn report(&self, iterations: usize) -> String {
        let total = self.total().max(1e-12);
        let per = |s: f64| 1e3 * s / iterations.max(1) as f64;
        self.phases()
            .iter()
            .map(|(name, s)| {
                format!(
                    "{name:>15}: {s:8.1} s  {:7.2} ms/it  {:5.1}%\n",
                    per(*s),
                    100.0 * s / total
                )
            })
            .chain((self.cpu > 0.0).then(|| {
                format!(
                    "{:>15}: {:8.1} s  {:5.2} cores busy on average\n",
                    "CPU (all)",
                    self.cpu,
                    self.cpu / total
                )
            }))
            .collect()
    }
}
