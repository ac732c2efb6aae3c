//! Wall time per training phase, the CPU time they used, and the CPU time the whole
//! machine used meanwhile (what else ran beside the training).

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
    /// CPU seconds the whole machine used over the same phases, this process included
    /// (Linux's `/proc/stat`; 0 where unavailable and in runs that predate it); not
    /// part of [`Self::total`]. `machine_cpu - cpu` is what other processes used.
    #[serde(default)]
    pub machine_cpu: f64,
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

    /// The cores other processes kept busy on average while the phases ran,
    /// `(machine_cpu - cpu) / total` (at least 0: both clocks tick in steps);
    /// `None` when the machine's clock was not recorded. It is the load a run's wall
    /// time was measured under: 0 on an idle machine, up to the core count minus
    /// the training's own share on a busy one.
    pub fn others_busy(&self) -> Option<f64> {
        let total = self.total();
        (self.machine_cpu > 0.0 && total > 0.0)
            .then(|| ((self.machine_cpu - self.cpu) / total).max(0.0))
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
            .chain(self.others_busy().map(|others| {
                format!(
                    "{:>15}: {others:5.2} cores busy beside the training on average\n",
                    "other processes"
                )
            }))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::Timings;

    fn timings(cpu: f64, machine_cpu: f64) -> Timings {
        Timings {
            field_mlp: 10.0,
            backward: 30.0,
            cpu,
            machine_cpu,
            ..Timings::default()
        }
    }

    #[test]
    fn others_busy_is_the_machine_time_not_spent_by_the_training_per_wall_second() {
        // 40 s of phases; the training used 60 CPU s, the machine 100: others kept one
        // core busy.
        let t = timings(60.0, 100.0);
        assert!((t.others_busy().expect("recorded") - 1.0).abs() < 1e-12);
        assert!(
            t.report(100)
                .contains("1.00 cores busy beside the training")
        );
        // Tick rounding can put the machine's clock a little below the process's.
        assert_eq!(timings(60.0, 59.9).others_busy(), Some(0.0));
        // Not recorded (another OS, or a run that predates the field).
        assert_eq!(timings(60.0, 0.0).others_busy(), None);
        assert!(!timings(60.0, 0.0).report(100).contains("beside"));
    }

    #[test]
    fn summaries_without_the_machine_clock_still_read() {
        let t: Timings = serde_json::from_str(
            r#"{"field_mlp":1,"render_forward":2,"backward":3,"optimiser":4,"filter_refresh":0,"densification":0}"#,
        )
        .expect("an older summary's timings");
        assert_eq!((t.machine_cpu, t.statistics, t.cpu), (0.0, 0.0, 0.0));
        assert_eq!(t.others_busy(), None);
    }
}
