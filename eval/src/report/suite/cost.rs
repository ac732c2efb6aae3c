//! The cost table of a suite's report: training wall and CPU time, the load beside
//! each run, the phase split, Gaussians and bytes.

use std::fmt::Write as _;

use maaf_scene::{PHASE_COUNT, Timings};

use super::tables::{average_label, num};
use super::{SceneResult, SuiteSummary, mean};

/// The cost table's short names of [`Timings::phases`], in that order.
const PHASES: [&str; PHASE_COUNT] = [
    "field + MLPs",
    "render",
    "backward",
    "optimiser",
    "statistics",
    "filter",
    "densify",
];

/// Each phase's share of the phases' sum, in percent, in the order field + MLPs,
/// render, backward, optimiser, statistics, filter, densify; `None` when the timings are absent
/// or sum to zero.
pub fn phase_shares(timings: Option<&Timings>) -> Option<[f64; PHASE_COUNT]> {
    let t = timings?;
    let total = t.total();
    (total > 0.0).then(|| t.phases().map(|(_, s)| 100.0 * s / total))
}

/// The mean of each phase's share over the scenes that have timings.
fn mean_shares(scenes: &[SceneResult]) -> Option<[f64; PHASE_COUNT]> {
    let all: Vec<[f64; PHASE_COUNT]> = scenes
        .iter()
        .filter_map(|r| phase_shares(r.phases.as_ref()))
        .collect();
    (!all.is_empty())
        .then(|| std::array::from_fn(|i| all.iter().map(|s| s[i]).sum::<f64>() / all.len() as f64))
}

/// `| a | b | ...` of the shares with no decimals, or dashes.
fn share_cells(shares: Option<[f64; PHASE_COUNT]>) -> String {
    match shares {
        Some(s) => s.iter().map(|v| format!(" {v:.0} |")).collect(),
        None => " - |".repeat(PHASES.len()),
    }
}

/// A run's training CPU time in minutes (all threads), `None` when its summary
/// predates the CPU clock or is absent.
fn cpu_minutes(r: &SceneResult) -> Option<f64> {
    r.phases.as_ref().map(|t| t.cpu / 60.0).filter(|&m| m > 0.0)
}

/// The cores other processes kept busy beside a run's training
/// ([`Timings::others_busy`]), `None` when its summary predates the machine's clock.
fn others_busy(r: &SceneResult) -> Option<f64> {
    r.phases.as_ref().and_then(Timings::others_busy)
}

/// Per scene and method: iterations, training wall and CPU time, the load beside it,
/// the phase split (percent of the timed phases), Gaussians, bytes.
pub(super) fn cost_table(summary: &SuiteSummary) -> String {
    let mut t = String::from(
        "| Method | Scene | Iterations | Train time (min) | CPU time (min) | Others busy (cores) |",
    );
    for name in PHASES {
        let _ = write!(t, " {name} % |");
    }
    t.push_str(" Gaussians | Model (MB) | Filter state (MB) |\n|---|---|---:|---:|---:|---:|");
    t.push_str(&"---:|".repeat(PHASES.len() + 3));
    t.push('\n');
    for m in &summary.methods {
        for r in &m.scenes {
            let _ = writeln!(
                t,
                "| {} | {} | {} | {:.2} | {} | {} |{} {} | {:.2} | {:.3} |",
                m.method,
                r.label(),
                r.iterations,
                r.train_seconds / 60.0,
                num(cpu_minutes(r), 2),
                num(others_busy(r), 2),
                share_cells(phase_shares(r.phases.as_ref())),
                r.gaussians,
                r.model_bytes as f64 / 1e6,
                r.filter_bytes as f64 / 1e6
            );
        }
        if let Some(avg) = &m.average {
            let _ = writeln!(
                t,
                "| {} | {} | | {:.2} | {} | {} |{} {:.0} | {:.2} | |",
                m.method,
                average_label(avg),
                avg.train_seconds / 60.0,
                num(mean(m.scenes.iter().filter_map(cpu_minutes)), 2),
                num(mean(m.scenes.iter().filter_map(others_busy)), 2),
                share_cells(mean_shares(&m.scenes)),
                avg.gaussians,
                avg.model_bytes / 1e6
            );
        }
    }
    t
}
