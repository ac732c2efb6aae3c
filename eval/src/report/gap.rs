//! What the quality-vs-scale chart does so that close runs stay apart: each run's
//! points sit a little to the side of the scale they belong to ([`dodge`]), so a line
//! drawn later does not cover an equal one; and a panel of each run's PSNR gap to the
//! best run at every scale ([`gap_panel`]), on an axis spanning only the runs within
//! [`GAP_WINDOW`] dB of the best, where differences of a tenth of a dB show that the
//! PSNR panel's 10-dB range hides.

use super::ReportRun;
use super::charts::{Area, draw_run, draw_scale_axes, new_chart, padded_range};
use super::style::series_style;

/// Runs further than this below the best at a scale (dB) are left out of the gap panel.
pub(super) const GAP_WINDOW: f64 = 1.0;

/// Horizontal offset of run `i` of `n` on a log2 scale axis: the runs spread over a
/// fifth of the distance between two scales, centred on the scale.
pub(super) fn dodge(i: usize, n: usize) -> f64 {
    if n < 2 {
        return 0.0;
    }
    0.2 * (i as f64 / (n - 1) as f64 - 0.5)
}

/// Each run's `(log2 scale + dodge, PSNR - best PSNR at that scale)` where within
/// [`GAP_WINDOW`] of the best, split into stretches of consecutive scales (a line is
/// drawn along each stretch only).
pub(super) fn gaps(runs: &[ReportRun], scales: &[f64]) -> Vec<Vec<Vec<(f64, f64)>>> {
    let best: Vec<Option<f64>> = scales
        .iter()
        .map(|&s| {
            runs.iter()
                .filter_map(|r| r.at_scale(s).map(|c| c.psnr))
                .reduce(f64::max)
        })
        .collect();
    runs.iter()
        .enumerate()
        .map(|(i, r)| {
            let mut stretches: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
            for (&s, b) in scales.iter().zip(&best) {
                let gap = r.at_scale(s).zip(*b).map(|(c, b)| c.psnr - b);
                match gap.filter(|g| *g >= -GAP_WINDOW) {
                    Some(g) => stretches
                        .last_mut()
                        .map_or((), |v| v.push((s.log2() + dodge(i, runs.len()), g))),
                    None => stretches.push(Vec::new()),
                }
            }
            stretches.retain(|v| !v.is_empty());
            stretches
        })
        .collect()
}

/// The gap panel: PSNR below the best run at each scale, for the runs within
/// [`GAP_WINDOW`] dB of it, on an axis spanning only those.
pub(super) fn gap_panel(area: &Area<'_>, runs: &[ReportRun]) -> Result<(), String> {
    let scales = super::all_scales(runs);
    let keys: Vec<f64> = scales.iter().map(|s| s.log2()).collect();
    let (x0, x1) = padded_range(keys.iter().copied(), 0.08);
    let series = gaps(runs, &scales);
    let values = series.iter().flatten().flatten().map(|p| p.1);
    let (y0, y1) = padded_range(values.chain([0.0]), 0.1);
    let title = format!("PSNR below the best run (runs within {GAP_WINDOW} dB)");
    let mut chart = new_chart(area, &title, 22, 70, (x0, x1), (y0, y1.max(0.02)))?;
    draw_scale_axes(
        &mut chart,
        keys.len(),
        "PSNR - best PSNR at the scale (dB)",
        2,
    )?;
    for (i, stretches) in series.iter().enumerate() {
        for pts in stretches {
            draw_run(&mut chart, pts, series_style(runs, i))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ScaleResult;

    fn run(name: &str, psnr: [f64; 3]) -> ReportRun {
        let cells = [0.25, 1.0, 4.0]
            .iter()
            .zip(psnr)
            .map(|(&s, p)| ScaleResult::new(s, (8, 8), p, 0.5))
            .collect();
        ReportRun::for_test(name, "saro", name, cells)
    }

    #[test]
    fn close_runs_are_kept_apart_and_far_ones_left_out() {
        let runs = [
            run("none", [16.0, 23.5, 15.0]),
            run("mip3d", [28.9, 23.3, 16.05]),
            run("motion", [28.8, 23.3, 16.0]),
        ];
        let g = gaps(&runs, &[0.25, 1.0, 4.0]);
        // No filter: only at 1x within a dB of the best (it is the best there).
        assert_eq!(g[0], vec![vec![(0.0 + dodge(0, 3), 0.0)]]);
        // The static filter is the best at 1/4x and 4x, 0.2 below at 1x: one stretch.
        let mip: Vec<f64> = g[1][0].iter().map(|p| p.1).collect();
        assert_eq!(g[1].len(), 1);
        assert!((mip[0]).abs() < 1e-12 && (mip[1] + 0.2).abs() < 1e-9 && mip[2].abs() < 1e-12);
        // The two filters' points do not share an x position.
        assert!(
            g[1][0]
                .iter()
                .zip(&g[2][0])
                .all(|(a, b)| (a.0 - b.0).abs() > 0.05)
        );
        assert_eq!(dodge(0, 1), 0.0);
    }
}
