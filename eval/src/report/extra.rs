//! The report's table of the per-image metrics a program registered
//! ([`crate::ImageMetric`]): one row per run, a column per metric and scale, from
//! `eval.json`'s `extra` means.

use std::fmt::Write as _;

use super::{ReportRun, scale_header};

/// The metrics any run has, sorted by name, each with whether higher is better (as
/// the first run that records it says).
fn extra_metrics(runs: &[ReportRun]) -> Vec<(&str, bool)> {
    let mut out: Vec<(&str, bool)> = Vec::new();
    for r in runs {
        for (name, info) in &r.eval.extra_metrics {
            if !out.iter().any(|(n, _)| n == name) {
                out.push((name, info.higher_is_better));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(b.0));
    out
}

/// A markdown table of every registered metric at every scale of `scales`, one row
/// per run (`-` where a run lacks it), the header marking which way is better (up:
/// higher) and bold marking the best of each column that has two or more values
/// (every value printing as the best). Empty when no run has such a metric.
pub fn extra_table(runs: &[ReportRun], scales: &[f64]) -> String {
    let metrics = extra_metrics(runs);
    if metrics.is_empty() {
        return String::new();
    }
    let mut t = String::from("| Method |");
    for (name, higher) in &metrics {
        let arrow = if *higher { "↑" } else { "↓" };
        for s in scales {
            let _ = write!(t, " {name} {arrow} {} |", scale_header(*s));
        }
    }
    t.push_str("\n|---|");
    t.push_str(&"---:|".repeat(metrics.len() * scales.len()));
    t.push('\n');
    let cell = |r: &ReportRun, name: &str, s: f64| {
        r.at_scale(s)
            .and_then(|x| x.extra.get(name))
            .map(|v| format!("{v:.4}"))
    };
    let best: Vec<Option<String>> = metrics
        .iter()
        .flat_map(|&(name, higher)| scales.iter().map(move |&s| (name, higher, s)))
        .map(|(name, higher, s)| {
            let values: Vec<f64> = runs
                .iter()
                .filter_map(|r| r.at_scale(s).and_then(|x| x.extra.get(name)).copied())
                .collect();
            let top = if higher {
                values.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            } else {
                values.iter().copied().fold(f64::INFINITY, f64::min)
            };
            (values.len() > 1).then(|| format!("{top:.4}"))
        })
        .collect();
    for r in runs {
        let _ = write!(t, "| {} |", r.label);
        let cells = metrics
            .iter()
            .flat_map(|&(name, _)| scales.iter().map(move |&s| cell(r, name, s)));
        for (value, best) in cells.zip(&best) {
            match value {
                Some(v) if best.as_ref() == Some(&v) => {
                    let _ = write!(t, " **{v}** |");
                }
                Some(v) => {
                    let _ = write!(t, " {v} |");
                }
                None => t.push_str(" - |"),
            }
        }
        t.push('\n');
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ExtraMetric, ScaleResult};

    fn run(label: &str, mae: Option<[f64; 2]>) -> ReportRun {
        let cells = [1.0, 2.0]
            .iter()
            .enumerate()
            .map(|(k, &s)| {
                let mut c = ScaleResult::new(s, (8, 8), 30.0, 0.9);
                if let Some(v) = mae {
                    c.extra.insert("mae".into(), v[k]);
                }
                c
            })
            .collect();
        let mut r = ReportRun::for_test(label, "saro", label, cells);
        if mae.is_some() {
            let info = ExtraMetric {
                higher_is_better: false,
            };
            r.eval.extra_metrics.insert("mae".into(), info);
        }
        r
    }

    #[test]
    fn a_column_per_metric_and_scale_with_the_lowest_error_in_bold() {
        let runs = [
            run("a", Some([0.02, 0.05])),
            run("b", Some([0.03, 0.04])),
            run("c", None),
        ];
        let table = extra_table(&runs, &[1.0, 2.0]);
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines[0], "| Method | mae ↓ 1x | mae ↓ 2x |");
        assert_eq!(lines[2], "| a | **0.0200** | 0.0500 |");
        assert_eq!(lines[3], "| b | 0.0300 | **0.0400** |");
        assert_eq!(lines[4], "| c | - | - |");
        assert!(extra_table(&runs[2..], &[1.0]).is_empty());
    }
}
