//! Published D-NeRF figures the suite report ([`super::suite`]) prints beside maaf's
//! own rows, copied digit for digit from their sources (nothing here is measured by
//! maaf). Both sources average the eight D-NeRF scenes, trained at 200x200 (1/4 of the
//! 800x800 images): a suite over fewer scenes is not the same average.
//!
//! - The paper's Tab. 2 (`tab:avg_synthetic_single_train_multi_test`, "Single-Scale
//!   Training and Multi-Scale Evaluation on the Synthetic Dataset"): SaRO-GS and MAAF
//!   ("Ours") at 1x, 2x, 4x and their average. The paper gives no per-scene rows for
//!   this protocol; its only per-scene D-NeRF table (supplementary
//!   `tab:supp_zoomout`) trains at 800x800 and renders below it, another protocol.
//! - The released code's row (`val-iisc/MAAF-4DGS`, SpeeDe3DGS backbone), also the
//!   paper's Tab. 7 (`tab:speede3dgs`, "Integration with SpeeDe3DGS"): 4x only, with
//!   GPU training minutes and the number of Gaussians. Its LPIPS uses VGG features
//!   (`metrics.py`): maaf's compares with it when evaluated with `--lpips-net vgg`.

use serde::Serialize;

/// One metric at one render scale, as published.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PublishedScale {
    /// Render scale relative to the 200x200 training scale (1, 2, 4).
    pub scale: f64,
    /// PSNR, dB.
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
    /// LPIPS.
    pub lpips: f64,
}

/// A published row: what it is, where it is printed, its figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PublishedRow {
    /// Method as the source names it.
    pub method: &'static str,
    /// Where the figures are printed (table number and LaTeX label, or repository).
    pub source: &'static str,
    /// Scenes averaged.
    pub scenes: usize,
    /// Figures per scale, ascending.
    pub scales: Vec<PublishedScale>,
    /// The source's own "Avg." column (PSNR, SSIM, LPIPS over its scales), when it
    /// prints one; copied, not recomputed.
    pub average: Option<PublishedScale>,
    /// GPU training wall time, minutes, when published.
    pub train_minutes: Option<f64>,
    /// Number of Gaussians, when published.
    pub gaussians: Option<u64>,
}

/// Where Tab. 2 is printed.
const TAB2: &str = "paper Tab. 2 (tab:avg_synthetic_single_train_multi_test)";
/// Where the released code's row is printed.
const RELEASED: &str = "val-iisc/MAAF-4DGS, SpeeDe3DGS backbone; paper Tab. 7 (tab:speede3dgs)";

fn at(scale: f64, psnr: f64, ssim: f64, lpips: f64) -> PublishedScale {
    PublishedScale {
        scale,
        psnr,
        ssim,
        lpips,
    }
}

/// The paper's Tab. 2 rows for SaRO-GS and MAAF (8 scenes, 1x / 2x / 4x and Avg.).
pub fn paper_tab2() -> Vec<PublishedRow> {
    // "Avg." is the column's own scale-free average; its `scale` field is 0.
    vec![
        PublishedRow {
            method: "SaRO-GS",
            source: TAB2,
            scenes: 8,
            scales: vec![
                at(1.0, 36.61, 0.982, 0.015),
                at(2.0, 29.59, 0.952, 0.040),
                at(4.0, 27.15, 0.931, 0.064),
            ],
            average: Some(at(0.0, 31.12, 0.955, 0.039)),
            train_minutes: None,
            gaussians: None,
        },
        PublishedRow {
            method: "MAAF (SaRO-GS + motion-aware filter)",
            source: TAB2,
            scenes: 8,
            scales: vec![
                at(1.0, 37.10, 0.982, 0.017),
                at(2.0, 34.05, 0.972, 0.033),
                at(4.0, 32.36, 0.960, 0.054),
            ],
            average: Some(at(0.0, 34.50, 0.971, 0.035)),
            train_minutes: None,
            gaussians: None,
        },
    ]
}

/// The released code's rows: SpeeDe3DGS and SpeeDe3DGS + MAAF, trained at r/4 and
/// tested at 4x (8 scenes), with GPU training minutes and Gaussians.
pub fn released() -> Vec<PublishedRow> {
    vec![
        PublishedRow {
            method: "SpeeDe3DGS",
            source: RELEASED,
            scenes: 8,
            scales: vec![at(4.0, 27.83, 0.940, 0.067)],
            average: None,
            train_minutes: Some(4.45),
            gaussians: Some(2508),
        },
        PublishedRow {
            method: "SpeeDe3DGS + MAAF",
            source: RELEASED,
            scenes: 8,
            scales: vec![at(4.0, 32.28, 0.956, 0.064)],
            average: None,
            train_minutes: Some(6.48),
            gaussians: Some(2330),
        },
    ]
}

/// Where the supplementary's error-reduction table is printed.
const SUPP_REGION: &str = "paper supplementary (tab:supp_region)";

/// The supplementary's "Where the zoom-out error reduction comes from": the share (%)
/// of SpeeDe3DGS's squared error that SpeeDe3DGS + MAAF removes, by distance from the
/// silhouette, in [`crate::metrics::rings::Ring::ALL`] order, at 1/4x and 1/2x of its
/// 800x800 training scale (8 scenes, all frames). Another protocol than the suite's
/// (trained at 200x200, so its 1/4x is 50x50 pixels): a pattern to hold maaf's against,
/// not the same figures.
pub struct PublishedRingShares {
    /// Where it is printed.
    pub source: &'static str,
    /// (scale relative to the training scale, share in percent per ring).
    pub at: [(f64, [f64; 5]); 2],
}

/// [`PublishedRingShares`] as printed.
pub fn ring_shares() -> PublishedRingShares {
    PublishedRingShares {
        source: SUPP_REGION,
        at: [
            (0.25, [50.7, 11.8, 20.3, 17.0, 0.2]),
            (0.5, [57.8, 6.2, 25.8, 9.4, 0.7]),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each scale's copied shares add up to 100 % within their rounding (five
    /// values of half a last digit each).
    #[test]
    fn ring_shares_add_up_to_the_whole_reduction() {
        for (scale, shares) in ring_shares().at {
            let sum: f64 = shares.iter().sum();
            assert!((sum - 100.0).abs() <= 0.25, "{scale}: {sum}");
        }
    }

    /// The copied "Avg." columns are the means of the copied scales within the
    /// rounding of both (half a last digit each: SaRO-GS's LPIPS prints 0.039 for a
    /// mean of 0.0397), so a mistyped digit in either shows up.
    #[test]
    fn tab2_averages_agree_with_their_scales() {
        for row in paper_tab2() {
            let avg = row.average.expect("Tab. 2 prints an average");
            let n = row.scales.len() as f64;
            let mean = |f: fn(&PublishedScale) -> f64| row.scales.iter().map(f).sum::<f64>() / n;
            assert!(
                (mean(|s| s.psnr) - avg.psnr).abs() <= 0.01,
                "{}",
                row.method
            );
            assert!(
                (mean(|s| s.ssim) - avg.ssim).abs() <= 0.001,
                "{}",
                row.method
            );
            assert!(
                (mean(|s| s.lpips) - avg.lpips).abs() <= 0.001,
                "{}",
                row.method
            );
        }
    }
}
