//! The report's table of PSNR by region (moving pixels, static pixels, silhouette
//! band; [`crate::metrics::regions`]) for runs evaluated on data with moving masks.

use std::fmt::Write as _;

use super::{ReportRun, scale_header};

/// A markdown table with one row per run and one column per scale, each cell
/// `moving / static / band` PSNR in dB (`-` where a region or scale has no value);
/// empty when no run has PSNR by region.
pub fn region_table(runs: &[ReportRun], scales: &[f64]) -> String {
    let has = |r: &ReportRun| r.eval.scales.iter().any(|s| s.regions.is_some());
    if !runs.iter().any(has) {
        return String::new();
    }
    let mut t = String::from("| Method |");
    for s in scales {
        let _ = write!(t, " {} |", scale_header(*s));
    }
    t.push_str("\n|---|");
    for _ in scales {
        t.push_str("---|");
    }
    t.push('\n');
    let db = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    for r in runs {
        let _ = write!(t, "| {} |", r.label);
        for &s in scales {
            let cell = r
                .at_scale(s)
                .and_then(|x| x.regions.as_ref())
                .map_or("-".to_string(), |g| {
                    format!("{} / {} / {}", db(g.moving), db(g.static_), db(g.band))
                });
            let _ = write!(t, " {cell} |");
        }
        t.push('\n');
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{RegionSummary, ScaleResult};

    fn run(label: &str, regions: Option<RegionSummary>) -> ReportRun {
        let mut s = ScaleResult::new(1.0, (8, 6), 20.0, 0.5);
        s.regions = regions;
        ReportRun::for_test(label, "saro", "motion", vec![s])
    }

    #[test]
    fn one_cell_per_scale_with_the_three_regions_and_nothing_without_masks() {
        let with = RegionSummary {
            moving: Some(17.4),
            static_: Some(27.876),
            band: None,
            views: [3, 3, 0],
        };
        let t = region_table(&[run("a", Some(with)), run("b", None)], &[0.5, 1.0]);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0], "| Method | 1/2x | 1x |");
        assert_eq!(lines[2], "| a | - | 17.40 / 27.88 / - |");
        assert_eq!(lines[3], "| b | - | - |");
        assert_eq!(region_table(&[run("b", None)], &[1.0]), "");
    }
}
