//! The report's tables: PSNR / SSIM per scale and their average, one row per run
//! (the paper's Tab. 2 shape), and the cost of each run.

use std::fmt::Write as _;

use super::ReportRun;
use crate::trim_float;

/// Column header of a scale: `1x`, `2x`, `1/2x`, `1/4x`.
pub fn scale_header(s: f64) -> String {
    if s < 1.0 && (1.0 / s - (1.0 / s).round()).abs() < 1e-6 {
        format!("1/{}x", (1.0 / s).round() as u64)
    } else {
        format!("{}x", trim_float(s))
    }
}

fn metric_at(r: &ReportRun, s: f64) -> Option<(f64, f64)> {
    r.at_scale(s).map(|x| (x.psnr, x.ssim))
}

/// A markdown table of PSNR and SSIM at `scales` plus their averages, one row per
/// run (the layout of the paper's Tab. 2). Missing cells are `-`; a run missing a
/// scale gets no average. Bold marks the best value of each column (every value that
/// prints the same as the best), when the column has two or more.
pub fn metrics_table(runs: &[ReportRun], scales: &[f64]) -> String {
    let mut t = String::from("| Method |");
    for s in scales {
        let _ = write!(t, " PSNR {} |", scale_header(*s));
    }
    t.push_str(" PSNR avg |");
    for s in scales {
        let _ = write!(t, " SSIM {} |", scale_header(*s));
    }
    t.push_str(" SSIM avg |\n|---|");
    for _ in 0..2 * scales.len() + 2 {
        t.push_str("---:|");
    }
    t.push('\n');
    // Per run, the PSNR columns then the SSIM columns, each scale then the average.
    let rows: Vec<Vec<Option<f64>>> = runs
        .iter()
        .map(|r| {
            let cells: Vec<Option<(f64, f64)>> = scales.iter().map(|&s| metric_at(r, s)).collect();
            let complete = !cells.is_empty() && cells.iter().all(Option::is_some);
            let column = |f: fn(&(f64, f64)) -> f64| {
                let v: Vec<Option<f64>> = cells.iter().map(|c| c.as_ref().map(f)).collect();
                let avg = complete.then(|| v.iter().flatten().sum::<f64>() / v.len() as f64);
                v.into_iter().chain([avg])
            };
            column(|c| c.0).chain(column(|c| c.1)).collect()
        })
        .collect();
    let digits = |k: usize| if k <= scales.len() { 2 } else { 4 };
    let best: Vec<Option<String>> = (0..2 * scales.len() + 2)
        .map(|k| {
            let values: Vec<f64> = rows.iter().filter_map(|r| r[k]).collect();
            let top = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (values.len() > 1).then(|| format!("{top:.*}", digits(k)))
        })
        .collect();
    for (r, row) in runs.iter().zip(&rows) {
        let _ = write!(t, "| {} |", r.label);
        for (k, cell) in row.iter().enumerate() {
            match cell {
                Some(v) => {
                    let v = format!("{v:.*}", digits(k));
                    if best[k].as_ref() == Some(&v) {
                        let _ = write!(t, " **{v}** |");
                    } else {
                        let _ = write!(t, " {v} |");
                    }
                }
                None => t.push_str(" - |"),
            }
        }
        t.push('\n');
    }
    t
}

/// A markdown table of cost: iterations, training time, Gaussians, bytes.
pub fn cost_table(runs: &[ReportRun]) -> String {
    let mut t = String::from(
        "| Method | Train scale | Iterations | Train time (s) | Gaussians | Model (MB) | Filter state (MB) | Total (MB) |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in runs {
        let e = &r.eval;
        let _ = writeln!(
            t,
            "| {} | {} | {} | {:.1} | {} | {:.2} | {:.3} | {:.2} |",
            r.label,
            trim_float(e.train_scale),
            e.iterations,
            e.train_seconds,
            e.num_gaussians,
            e.model_bytes as f64 / 1e6,
            e.filter_bytes as f64 / 1e6,
            e.total_bytes() as f64 / 1e6
        );
    }
    t
}

/// Every scale any run was evaluated at, ascending.
pub fn all_scales(runs: &[ReportRun]) -> Vec<f64> {
    let mut v: Vec<f64> = runs
        .iter()
        .flat_map(|r| r.eval.scales.iter().map(|s| s.scale))
        .collect();
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    v
}
