//! Where a gain lies: the share of one method's squared-error reduction over another in
//! each ring around the silhouette ([`crate::metrics::rings`]), the split of the
//! paper's supplementary `tab:supp_region`, as `maaf report` (each run against the
//! first) and the suite report's paired gains ([`super::suite`]) print it.

use std::fmt::Write as _;

use serde::Serialize;

use super::{ReportRun, scale_header};
use crate::metrics::rings::Ring;

/// Below this fraction of the base's squared error removed (or added), the tables
/// leave a scale's shares out: they divide by the total change, so a change near zero
/// sends them far past 100 % (the demo's 1/2x: 2 % removed, shares of several hundred
/// percent). The shares stay in `report.json`.
pub const MIN_REMOVED_FOR_SHARES: f64 = 0.05;

/// What the ring tables' introductions say of the shares' one weakness.
pub const NEAR_ZERO_NOTE: &str = "The shares divide by the total change, so where the last \
     row (the total removed) is under 5 % either way they are left out (`-`; still in \
     `report.json`).";

/// Where a gain lies at one scale, in [`Ring::ALL`] order.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RingSharesAt {
    /// Render scale relative to the training scale.
    pub scale: f64,
    /// `(SSE_base(r) - SSE_method(r)) / (SSE_base - SSE_method)` per ring: negative
    /// where the method's error grew (or, when the total grew, where it shrank); all
    /// zero when the totals are equal.
    pub shares: [f64; 5],
    /// Fraction of the pixels in each ring.
    pub pixels: [f64; 5],
    /// `(SSE_base - SSE_method) / SSE_base`: the fraction of the base's squared error
    /// that the method removes (negative when it adds error).
    pub removed: f64,
}

impl RingSharesAt {
    /// The shares from per-ring squared-error sums of the base and the method over
    /// the same pixels (`pixels` per ring, counts or means).
    pub fn of_sums(scale: f64, base: [f64; 5], method: [f64; 5], pixels: [f64; 5]) -> Self {
        let cut: [f64; 5] = std::array::from_fn(|k| base[k] - method[k]);
        let (total_cut, total_base): (f64, f64) = (cut.iter().sum(), base.iter().sum());
        let n: f64 = pixels.iter().sum();
        RingSharesAt {
            scale,
            shares: cut.map(|c| if total_cut != 0.0 { c / total_cut } else { 0.0 }),
            pixels: pixels.map(|p| p / n.max(1.0)),
            removed: if total_base > 0.0 {
                total_cut / total_base
            } else {
                0.0
            },
        }
    }
}

/// A markdown table of `at` (ascending scales): a row per ring, `share % (pixels %)`
/// per scale (`- (pixels %)` where less than [`MIN_REMOVED_FOR_SHARES`] of the base's
/// error changed), and the fraction of the base's squared error removed.
pub fn ring_shares_rows(at: &[RingSharesAt]) -> String {
    let mut t = String::from("| Region |");
    for r in at {
        let _ = write!(t, " {} |", scale_header(r.scale));
    }
    t.push_str("\n|---|");
    t.push_str(&"---:|".repeat(at.len()));
    t.push('\n');
    for (k, ring) in Ring::ALL.iter().enumerate() {
        let _ = write!(t, "| {} |", ring.label());
        for r in at {
            let pixels = 100.0 * r.pixels[k];
            if r.removed.abs() < MIN_REMOVED_FOR_SHARES {
                let _ = write!(t, " - ({pixels:.1}) |");
            } else {
                // `+ 0.0` turns the -0.0 of an unchanged ring under a negative total
                // into 0.0.
                let _ = write!(t, " {:.1} ({pixels:.1}) |", 100.0 * r.shares[k] + 0.0);
            }
        }
        t.push('\n');
    }
    t.push_str("| squared error removed, % of the base's |");
    for r in at {
        let _ = write!(t, " {:.1} |", 100.0 * r.removed);
    }
    t.push('\n');
    t
}

/// `maaf report`'s section: every run against the first at each scale of `scales`
/// where both have ring errors over the same pixels, one table per run; empty when no
/// pair has them.
pub fn ring_section(runs: &[ReportRun], scales: &[f64]) -> String {
    let Some((base, rest)) = runs.split_first() else {
        return String::new();
    };
    let mut md = String::new();
    for run in rest {
        let at: Vec<RingSharesAt> = scales
            .iter()
            .filter_map(|&s| {
                let b = base.at_scale(s)?.rings?;
                let m = run.at_scale(s)?.rings?;
                (b.pixels == m.pixels)
                    .then(|| RingSharesAt::of_sums(s, b.sse, m.sse, b.pixels.map(|p| p as f64)))
            })
            .collect();
        if !at.is_empty() {
            let _ = writeln!(
                md,
                "{} against {}: share of the error reduction, % (pixels, %)\n",
                run.label, base.label
            );
            md.push_str(&ring_shares_rows(&at));
            md.push('\n');
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ScaleResult;
    use crate::metrics::rings::RingErrors;

    fn run(label: &str, at: &[(f64, Option<[f64; 5]>)]) -> ReportRun {
        let scales = at
            .iter()
            .map(|&(s, sse)| {
                let mut r = ScaleResult::new(s, (8, 8), 30.0, 0.9);
                r.rings = sse.map(|sse| RingErrors {
                    pixels: [1, 1, 2, 0, 4],
                    sse,
                });
                r
            })
            .collect();
        ReportRun::for_test(label, "saro", "none", scales)
    }

    #[test]
    fn shares_are_differences_of_sums_over_the_total_cut() {
        // The metric test's view: pixels [8, 24, 0, 16, 16], error 0.25 inside and
        // 0.02 in the halo. A model that fixes the inside pixel and halves the halo
        // error, then one worse in the halo.
        let pixels = [8.0, 24.0, 0.0, 16.0, 16.0];
        let base = [0.0, 0.25, 0.0, 0.02, 0.0];
        let r = RingSharesAt::of_sums(1.0, base, [0.0, 0.0, 0.0, 0.01, 0.0], pixels);
        assert_eq!(r.pixels, [0.125, 0.375, 0.0, 0.25, 0.25]);
        let s = r.shares;
        let total = 0.25 + 0.01;
        assert!((s[1] - 0.25 / total).abs() < 1e-12 && (s[3] - 0.01 / total).abs() < 1e-12);
        assert_eq!([s[0], s[2], s[4]], [0.0; 3]);
        let s = RingSharesAt::of_sums(1.0, base, [0.0, 0.0, 0.0, 0.04, 0.0], pixels).shares;
        assert!(s[3] < 0.0 && (s.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        // Nothing removed: no shares, and nothing removed.
        let same = RingSharesAt::of_sums(1.0, base, base, pixels);
        assert_eq!((same.shares, same.removed), ([0.0; 5], 0.0));
    }

    #[test]
    fn each_run_is_split_against_the_first_where_both_have_rings() {
        let base = run(
            "none",
            &[
                (0.25, Some([2.0, 1.0, 1.0, 0.0, 1.0])),
                (1.0, Some([1.0; 5])),
            ],
        );
        // At 1/4x: 1.5 of 5 removed, 1 of it on the ring, 0.5 inside. 1x has no rings
        // for the method, so no column.
        let ours = run(
            "motion",
            &[(0.25, Some([1.0, 0.5, 1.0, 0.0, 1.0])), (1.0, None)],
        );
        let no_rings = run("other", &[(0.25, None)]);
        let md = ring_section(&[base, ours, no_rings], &[0.25, 1.0]);
        assert!(md.contains("motion against none: share"), "{md}");
        assert!(!md.contains("other against"), "{md}");
        assert!(!md.contains("| 1x |"), "{md}");
        for row in [
            "| silhouette ring (object, d = 1 px) | 66.7 (12.5) |",
            "| inside band (object, d = 2-5 px) | 33.3 (12.5) |",
            "| far background (d > 2 px) | 0.0 (50.0) |",
            "| squared error removed, % of the base's | 30.0 |",
        ] {
            assert!(md.contains(row), "`{row}` not in:\n{md}");
        }
        assert_eq!(
            ring_section(&[run("only", &[(1.0, Some([1.0; 5]))])], &[1.0]),
            ""
        );
    }

    #[test]
    fn shares_of_a_total_change_under_five_percent_are_left_out() {
        let pixels = [1.0, 1.0, 2.0, 0.0, 4.0];
        let base = [1.0, 5.0, 1.0, 1.0, 92.0];
        // 4 % removed: ring -1, inside +5 (shares -25 % and 125 %) are not printed.
        let small = RingSharesAt::of_sums(0.5, base, [2.0, 0.0, 1.0, 1.0, 92.0], pixels);
        // 5 % added (removed -0.05): printed; the ring holds all of the change, the
        // unchanged rings print 0.0 (not -0.0).
        let added = RingSharesAt::of_sums(1.0, base, [6.0, 5.0, 1.0, 1.0, 92.0], pixels);
        assert!((small.removed - 0.04).abs() < 1e-12 && (added.removed + 0.05).abs() < 1e-12);
        let md = ring_shares_rows(&[small, added]);
        for row in [
            "| silhouette ring (object, d = 1 px) | - (12.5) | 100.0 (12.5) |",
            "| inside band (object, d = 2-5 px) | - (12.5) | 0.0 (12.5) |",
            "| squared error removed, % of the base's | 4.0 | -5.0 |",
        ] {
            assert!(md.contains(row), "`{row}` not in:\n{md}");
        }
        assert_eq!(small.shares[1], 1.25, "report.json keeps the share");
        let percent = format!("under {} %", (100.0 * MIN_REMOVED_FOR_SHARES).round());
        assert!(NEAR_ZERO_NOTE.contains(&percent), "the note says {percent}");
    }
}
