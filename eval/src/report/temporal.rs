//! The report's LPIPS table and its temporal-stability part: a table shaped like the
//! paper's Tab. 3 per scale (W-Temporal Error, W-SSIM, W-LPIPS per run and flow) and
//! the supplementary's chart of the warping error `E_warp` over time.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

use super::charts::{e2s, padded_range, save_chart, text};
use super::style::{line, series_style, with_legend};
use super::{ReportRun, scale_header};
use crate::Error;
use crate::TemporalResult;

/// One line of the chart: run index (for its style) and `(t, E_warp)` points.
type Series = (usize, Vec<(f64, f64)>);

fn cell(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".to_string(), |v| format!("{v:.digits$}"))
}

/// The LPIPS backbones of `runs` for the table's heading: `AlexNet`, `VGG16`, or
/// both with the runs on each when they differ (`maaf eval --lpips-net`).
pub fn lpips_nets(runs: &[ReportRun]) -> String {
    let name = super::lpips_label;
    let mut nets: Vec<&str> = runs.iter().map(|r| r.eval.lpips_net.as_str()).collect();
    nets.sort_unstable();
    nets.dedup();
    match nets.as_slice() {
        [] => name("alex").to_string(),
        [one] => name(one).to_string(),
        _ => nets
            .iter()
            .map(|&n| {
                let labels: Vec<&str> = runs
                    .iter()
                    .filter(|r| r.eval.lpips_net == n)
                    .map(|r| r.label.as_str())
                    .collect();
                format!("{} for {}", name(n), labels.join(", "))
            })
            .collect::<Vec<_>>()
            .join("; "),
    }
}

/// A markdown table of mean LPIPS per scale (lower is better), one row per run;
/// `-` where a scale has none (its `lpips_note` says why).
pub fn lpips_table(runs: &[ReportRun], scales: &[f64]) -> String {
    let mut t = String::from("| Method |");
    for s in scales {
        let _ = write!(t, " LPIPS {} |", scale_header(*s));
    }
    t.push_str("\n|---|");
    for _ in scales {
        t.push_str("---:|");
    }
    t.push('\n');
    for r in runs {
        let _ = write!(t, "| {} |", r.label);
        for &s in scales {
            let _ = write!(t, " {} |", cell(r.at_scale(s).and_then(|x| x.lpips), 4));
        }
        t.push('\n');
    }
    t
}

/// Scales at which any run has temporal metrics, ascending.
pub fn temporal_scales(runs: &[ReportRun]) -> Vec<f64> {
    let mut v: Vec<f64> = runs
        .iter()
        .flat_map(|r| r.eval.scales.iter())
        .filter(|s| !s.temporal.is_empty())
        .map(|s| s.scale)
        .collect();
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    v
}

/// The temporal entries of `run` at scale `s`.
fn entries(run: &ReportRun, s: f64) -> &[TemporalResult] {
    run.at_scale(s).map_or(&[], |x| x.temporal.as_slice())
}

/// One Tab. 3-shaped markdown table per scale with temporal metrics: a row per run
/// and flow with W-Temporal Error (sum over t of `E_warp`, lower is better), W-SSIM
/// (higher is better) and W-LPIPS (lower is better). Empty when no run has any.
pub fn temporal_tables(runs: &[ReportRun]) -> String {
    let mut md = String::new();
    for s in temporal_scales(runs) {
        let _ = writeln!(md, "### {}\n", scale_header(s));
        md.push_str(
            "| Method | Flow | Camera | Frames | W-Temporal Error | W-SSIM | W-LPIPS |\n|---|---|---|---:|---:|---:|---:|\n",
        );
        for r in runs {
            for t in entries(r, s) {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {} | {:.4} | {:.4} | {} |",
                    r.label,
                    t.flow,
                    t.camera,
                    t.times.len(),
                    t.warp_error,
                    t.w_ssim,
                    cell(t.w_lpips, 4)
                );
            }
        }
        md.push('\n');
    }
    md
}

/// One markdown table of popping ([`crate::metrics::popping`]) over the scales with
/// temporal metrics: a row per run and scale with the mean number of popping
/// Gaussians per frame step, the mean popped mass and the step with the largest one.
/// Empty when no run has any.
pub fn popping_table(runs: &[ReportRun]) -> String {
    let mut md = String::new();
    for s in temporal_scales(runs) {
        for r in runs {
            let Some(p) = r.at_scale(s).and_then(|x| x.popping.as_ref()) else {
                continue;
            };
            let worst = p.worst_step().map_or("-".to_string(), |(t, m)| {
                format!("{:.3} % at t = {t:.3}", 100.0 * m)
            });
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.1} | {:.3} % | {worst} |",
                r.label,
                scale_header(s),
                p.camera,
                p.times.len(),
                p.mean_pops(),
                100.0 * p.mean_mass(),
            );
        }
    }
    if md.is_empty() {
        return md;
    }
    let head = "| Method | Scale | Camera | Frames | popping Gaussians per step | popped mass per step | largest step |\n|---|---|---|---:|---:|---:|---|\n";
    format!("{head}{md}")
}

/// The warping error over time: one panel per (flow, scale), rows by flow (`exact`
/// then `model`) and columns by scale, a line per run of `E_warp(I_t, I_{t+1})`
/// against `t`. Returns `false` (and writes nothing) when no run has temporal metrics.
pub fn warp_error_over_time(runs: &[ReportRun], path: &Path) -> Result<bool, Error> {
    let scales = temporal_scales(runs);
    let flows: Vec<&str> = ["exact", "model"]
        .into_iter()
        .filter(|f| {
            runs.iter().any(|r| {
                scales
                    .iter()
                    .any(|&s| entries(r, s).iter().any(|t| t.flow == *f))
            })
        })
        .collect();
    if scales.is_empty() || flows.is_empty() {
        return Ok(false);
    }
    let size = (520 * scales.len() as u32, 420 * flows.len() as u32);
    save_chart(path, size, |root| {
        let panels = with_legend(root, runs)?.split_evenly((flows.len(), scales.len()));
        for (fi, flow) in flows.iter().enumerate() {
            for (si, &s) in scales.iter().enumerate() {
                let area = &panels[fi * scales.len() + si];
                let series: Vec<Series> = runs
                    .iter()
                    .enumerate()
                    .filter_map(|(i, r)| {
                        let t = entries(r, s).iter().find(|t| t.flow == *flow)?;
                        let pts = t.times.iter().zip(&t.per_step).map(|(&x, &y)| (x, y));
                        Some((i, pts.collect()))
                    })
                    .collect();
                let all = || series.iter().flat_map(|(_, p)| p.iter());
                let (x0, x1) = padded_range(all().map(|p| p.0), 0.02);
                let (y0, y1) = padded_range(all().map(|p| p.1), 0.05);
                let mut chart = ChartBuilder::on(area)
                    .caption(format!("{} flow, {}", flow, scale_header(s)), text(20))
                    .margin(12)
                    .x_label_area_size(45)
                    .y_label_area_size(75)
                    .build_cartesian_2d(x0..x1, y0.max(0.0)..y1)
                    .map_err(e2s)?;
                chart
                    .configure_mesh()
                    .x_desc("time t (step t -> t+1)")
                    .y_desc("E_warp")
                    .label_style(text(14))
                    .axis_desc_style(text(15))
                    .x_labels(6)
                    .y_labels(6)
                    .y_label_formatter(&|y| format!("{y:.4}"))
                    .draw()
                    .map_err(e2s)?;
                for (i, pts) in &series {
                    chart
                        .draw_series(std::iter::once(line(pts.clone(), series_style(runs, *i))))
                        .map_err(e2s)?;
                }
            }
        }
        Ok(())
    })?;
    Ok(true)
}
