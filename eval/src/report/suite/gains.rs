//! Paired gains: a method's PSNR minus another's on the scenes both were evaluated on,
//! scene by scene, the comparison the paper's Tab. 2 makes between MAAF and SaRO-GS.
//!
//! The Tab. 2 layout averages each method over its own scenes; while two methods have
//! different scenes, the difference of those averages mixes the scenes with the
//! method. Here `gain(s) = mean over shared scenes k of (PSNR_method(k, s) -
//! PSNR_base(k, s))`, each scene first averaged over its seeds, with the number of
//! shared scenes on which the method is ahead.
//!
//! Where the gain lies: for runs evaluated with alpha (D-NeRF), each pair also splits
//! the base's squared error that the method removes by distance from the silhouette
//! ([`crate::metrics::rings`]), as the paper's supplementary table `tab:supp_region`
//! does: per ring `(SSE_base(r) - SSE_method(r)) / (SSE_base - SSE_method)`, the sums
//! pooled over the shared scenes and their views (a scene's seeds averaged first).

use std::fmt::Write as _;

use serde::Serialize;

use super::tables::table_header;
use super::{Cell, MethodResult, SuiteSummary, at_scale, by_scene, cell_at, mean, seed_means};
use crate::metrics::rings::{Ring, RingErrors};
use crate::report::published::{PublishedRow, ring_shares as published_ring_shares};
use crate::report::rings::{RingSharesAt, ring_shares_rows};

/// One method against one listed before it with the same preset and background.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Gain {
    /// The method (`preset / filter / background`).
    pub method: String,
    /// The method it is compared with.
    pub base: String,
    /// Scenes both were evaluated on, in the method's order.
    pub scenes: Vec<String>,
    /// Per scale that every shared scene has in both methods, ascending.
    pub scales: Vec<GainAt>,
    /// Per scale at which every shared run of both methods has its squared error by
    /// ring, ascending; empty for data without alpha.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub rings: Vec<RingSharesAt>,
}

/// A paired gain at one scale.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GainAt {
    /// Render scale relative to the training scale.
    pub scale: f64,
    /// Mean over the shared scenes of the PSNR difference, dB.
    pub psnr: f64,
    /// Shared scenes on which the method's PSNR is the higher.
    pub ahead: usize,
}

/// Every pair of methods with the same preset and background, each method against
/// every one listed before it (the suite lists filters in `--filters` order, so with
/// the default `none,mip3d,motion`: mip3d and motion against none, motion against
/// mip3d). Pairs without a shared scene are left out.
pub fn gains(methods: &[MethodResult], scales: &[f64]) -> Vec<Gain> {
    let means: Vec<SceneMeans> = methods.iter().map(|m| scene_means(m, scales)).collect();
    let mut out = Vec::new();
    for (i, base) in methods.iter().enumerate() {
        for (j, m) in methods.iter().enumerate().skip(i + 1) {
            if m.preset == base.preset && m.background == base.background {
                out.extend(gain((m, &means[j]), (base, &means[i]), scales));
            }
        }
    }
    out
}

/// A method's scenes, each with its cells averaged over the scene's seeds.
type SceneMeans = Vec<(String, Vec<Cell>)>;

fn scene_means(m: &MethodResult, scales: &[f64]) -> SceneMeans {
    let groups = by_scene(&m.scenes);
    let cells = seed_means(&groups, scales, false);
    groups
        .iter()
        .map(|g| g[0].scene.clone())
        .zip(cells)
        .collect()
}

/// `m` against `base` on their shared scenes; `None` when they share none.
fn gain(
    (m, ours): (&MethodResult, &SceneMeans),
    (base, theirs): (&MethodResult, &SceneMeans),
    scales: &[f64],
) -> Option<Gain> {
    let pairs: Vec<(&str, &[Cell], &[Cell])> = ours
        .iter()
        .filter_map(|(scene, a)| {
            let (_, b) = theirs.iter().find(|(t, _)| t == scene)?;
            Some((scene.as_str(), a.as_slice(), b.as_slice()))
        })
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let at = scales
        .iter()
        .filter_map(|&s| {
            let d: Vec<f64> = pairs
                .iter()
                .filter_map(|(_, a, b)| Some(cell_at(a, s)?.psnr - cell_at(b, s)?.psnr))
                .collect();
            (d.len() == pairs.len()).then(|| GainAt {
                scale: s,
                psnr: mean(d.iter().copied()).unwrap_or(0.0),
                ahead: d.iter().filter(|&&x| x > 0.0).count(),
            })
        })
        .collect();
    let scenes: Vec<String> = pairs.iter().map(|(s, _, _)| s.to_string()).collect();
    Some(Gain {
        method: m.method.clone(),
        base: base.method.clone(),
        rings: scales
            .iter()
            .filter_map(|&s| ring_shares(m, base, &scenes, s))
            .collect(),
        scenes,
        scales: at,
    })
}

/// Per ring, the mean over a scene's seeds of their squared error (and pixels) at
/// scale `s`; `None` when a seed lacks it or the scene has no run.
fn scene_rings(m: &MethodResult, scene: &str, s: f64) -> Option<([f64; 5], [f64; 5])> {
    let runs: Vec<RingErrors> = m
        .scenes
        .iter()
        .filter(|r| r.scene == scene)
        .map(|r| cell_at(&r.scales, s)?.rings)
        .collect::<Option<_>>()?;
    let n = runs.len() as f64;
    let total = RingErrors::total(runs.into_iter())?;
    Some((total.sse.map(|v| v / n), total.pixels.map(|p| p as f64 / n)))
}

/// [`RingSharesAt`] of `m` against `base` at scale `s`, pooled over `scenes`; `None`
/// when a run lacks its rings there or the two methods' pixels differ.
fn ring_shares(
    m: &MethodResult,
    base: &MethodResult,
    scenes: &[String],
    s: f64,
) -> Option<RingSharesAt> {
    let (mut ours, mut theirs, mut pixels) = ([0.0; 5], [0.0; 5], [0.0; 5]);
    for scene in scenes {
        let (a, pa) = scene_rings(m, scene, s)?;
        let (b, pb) = scene_rings(base, scene, s)?;
        if pa != pb {
            return None;
        }
        for k in 0..5 {
            ours[k] += a[k];
            theirs[k] += b[k];
            pixels[k] += pa[k];
        }
    }
    Some(RingSharesAt::of_sums(s, theirs, ours, pixels))
}

/// A published row against the row before it in its source, PSNR per scale.
struct PublishedGain<'a> {
    base: &'a PublishedRow,
    method: &'a PublishedRow,
    /// (scale, PSNR difference) at each scale both rows print.
    at: Vec<(f64, f64)>,
}

/// A source's second row against its first (MAAF against SaRO-GS in Tab. 2,
/// SpeeDe3DGS + MAAF against SpeeDe3DGS in the release): the difference of the
/// published averages.
fn published_gain(rows: &[PublishedRow]) -> Option<PublishedGain<'_>> {
    let [base, method, ..] = rows else {
        return None;
    };
    let at = method
        .scales
        .iter()
        .filter_map(|p| {
            let b = at_scale(&base.scales, p.scale, |q| q.scale)?;
            Some((p.scale, p.psnr - b.psnr))
        })
        .collect();
    Some(PublishedGain { base, method, at })
}

/// The markdown table of the suite's paired gains at every evaluated scale, with the
/// published gains below them (`+4.38 (4/4)`: 4.38 dB on average, ahead on all four
/// shared scenes); `None` when no pair shares a scene.
pub fn gains_table(summary: &SuiteSummary) -> Option<String> {
    if summary.gains.is_empty() {
        return None;
    }
    let mut t = table_header(&["Method", "Against", "Scenes"], 1, &summary.scales, &[]);
    for g in &summary.gains {
        let _ = write!(t, "| {} | {} | {} |", g.method, g.base, g.scenes.len());
        for &s in &summary.scales {
            match at_scale(&g.scales, s, |c| c.scale) {
                Some(c) => {
                    let _ = write!(t, " {:+.2} ({}/{}) |", c.psnr, c.ahead, g.scenes.len());
                }
                None => t.push_str(" - |"),
            }
        }
        t.push('\n');
    }
    for rows in [&summary.paper_tab2, &summary.released] {
        let Some(PublishedGain { base, method, at }) = published_gain(rows) else {
            continue;
        };
        let _ = write!(
            t,
            "| {} [published: {}] | {} | {} |",
            method.method, method.source, base.method, method.scenes
        );
        for &s in &summary.scales {
            let v = at_scale(&at, s, |&(p, _)| p).map(|&(_, d)| d);
            let _ = write!(t, " {} |", v.map_or("-".into(), |d| format!("{d:+.2}")));
        }
        t.push('\n');
    }
    Some(t)
}

/// The markdown tables of where each paired gain lies (one per pair with ring errors:
/// a row per ring, a column per scale, `share % (pixels %)`, and the fraction of the
/// base's squared error removed), then the paper's supplementary shares; `None` when
/// no pair has them.
pub fn ring_shares_table(summary: &SuiteSummary) -> Option<String> {
    let with: Vec<&Gain> = summary
        .gains
        .iter()
        .filter(|g| !g.rings.is_empty())
        .collect();
    if with.is_empty() {
        return None;
    }
    let mut t = String::new();
    for g in with {
        let _ = writeln!(
            t,
            "{} against {} ({} scenes): share of the error reduction, % (pixels, %)\n",
            g.method,
            g.base,
            g.scenes.len()
        );
        t.push_str(&ring_shares_rows(&g.rings));
        t.push('\n');
    }
    let published = published_ring_shares();
    let scales: Vec<f64> = published.at.iter().map(|&(s, _)| s).collect();
    let _ = writeln!(
        t,
        "SpeeDe3DGS + MAAF against SpeeDe3DGS [published: {}; trained at 800x800, so its \
         1/4x is 200x200 pixels]: share of the error reduction, %\n",
        published.source
    );
    t.push_str(&table_header(&["Region"], 0, &scales, &[]));
    for (k, ring) in Ring::ALL.iter().enumerate() {
        let _ = write!(t, "| {} |", ring.label());
        for (_, shares) in &published.at {
            let _ = write!(t, " {:.1} |", shares[k]);
        }
        t.push('\n');
    }
    Some(t)
}
