//! The markdown of a suite's report: the Tab. 2 layout, how hard its scenes are, the paired
//! gains, the released row at 4x, the per-scene tables of each metric and the seeds'
//! spread.

use std::fmt::Write as _;

use super::cost::cost_table;
use super::gains::{gains_table, ring_shares_table};
use super::scene_set::scene_set_table;
use super::{Average, Cell, SuiteSummary, TAB2_SCALES, at_scale, by_scene, cell_at, mean};
use crate::report::{lpips_label, scale_header};

/// `v` with `digits` decimals, `-` when absent.
pub(super) fn num(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.digits$}"))
}

/// The mean over [`TAB2_SCALES`] of one metric, when every one is present.
fn tab2_avg(cells: &[Cell], f: fn(&Cell) -> Option<f64>) -> Option<f64> {
    let v: Vec<f64> = TAB2_SCALES
        .iter()
        .map(|&s| cell_at(cells, s).and_then(f))
        .collect::<Option<Vec<f64>>>()?;
    mean(v.into_iter())
}

type Metric = (&'static str, usize, fn(&Cell) -> Option<f64>);

const METRICS: [Metric; 3] = [
    ("PSNR", 2, |c| Some(c.psnr)),
    ("SSIM", 3, |c| Some(c.ssim)),
    ("LPIPS", 3, |c| c.lpips),
];

/// The Tab. 2-shaped table: each method's average over its scenes at 1x, 2x, 4x and
/// their mean for PSNR, SSIM and LPIPS, then the paper's rows (published).
pub fn tab2_table(summary: &SuiteSummary) -> String {
    let mut t = String::from("| Method | Scenes |");
    for (name, _, _) in METRICS {
        for s in TAB2_SCALES {
            let _ = write!(t, " {name} {} |", scale_header(s));
        }
        let _ = write!(t, " {name} avg |");
    }
    t.push_str("\n|---|---:|");
    t.push_str(&"---:|".repeat(METRICS.len() * (TAB2_SCALES.len() + 1)));
    t.push('\n');
    for m in &summary.methods {
        let Some(avg) = &m.average else { continue };
        let _ = write!(t, "| {} (maaf) | {} |", m.method, avg.scenes);
        for (_, digits, f) in METRICS {
            for s in TAB2_SCALES {
                let v = cell_at(&avg.scales, s).and_then(f);
                let _ = write!(t, " {} |", num(v, digits));
            }
            let _ = write!(t, " {} |", num(tab2_avg(&avg.scales, f), digits));
        }
        t.push('\n');
    }
    for row in &summary.paper_tab2 {
        let _ = write!(
            t,
            "| {} [published: {}] | {} |",
            row.method, row.source, row.scenes
        );
        let avg = row.average;
        for (i, digits) in [2, 3, 3].into_iter().enumerate() {
            let pick = |p: &crate::report::published::PublishedScale| [p.psnr, p.ssim, p.lpips][i];
            for s in TAB2_SCALES {
                let v = at_scale(&row.scales, s, |p| p.scale).map(pick);
                let _ = write!(t, " {} |", num(v, digits));
            }
            let _ = write!(t, " {} |", num(avg.as_ref().map(pick), digits));
        }
        t.push('\n');
    }
    t
}

/// Whether maaf's LPIPS column compares with the release's: it computes LPIPS on VGG
/// features (`lpips.LPIPS(net='vgg')` in its `metrics.py`); maaf's methods on the
/// backbone each was evaluated with (`maaf eval --lpips-net`, passed through
/// `bench-suite --eval-args`).
pub(super) fn lpips_net_note(summary: &SuiteSummary) -> String {
    let mut nets: Vec<&str> = summary
        .methods
        .iter()
        .filter_map(|m| m.average.as_ref())
        .map(|a| a.lpips_net.as_deref().map_or("mixed", lpips_label))
        .collect();
    nets.dedup();
    let release = "The release's LPIPS is computed on VGG features (`lpips.LPIPS(net='vgg')` \
                   in its `metrics.py`)";
    if nets == [maaf_lpips::Net::Vgg.label()] {
        format!("{release}, as maaf's here (`--lpips-net vgg`): the LPIPS column compares.\n\n")
    } else {
        format!(
            "{release}; maaf's rows here use {} features, so only a VGG row compares with it \
             (evaluate with `--eval-args \"--no-images --lpips-net vgg\"` for that).\n\n",
            nets.join(" / ")
        )
    }
}

/// Each method's average at 4x with its cost, beside the released code's rows.
pub fn released_table(summary: &SuiteSummary) -> String {
    let mut t = String::from(
        "| Method | Scenes | PSNR 4x | SSIM 4x | LPIPS 4x | Train time (min) | Gaussians | Model (MB) |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for m in &summary.methods {
        let Some(avg) = &m.average else { continue };
        let c = cell_at(&avg.scales, 4.0);
        let _ = writeln!(
            t,
            "| {} (maaf, CPU) | {} | {} | {} | {} | {:.2} | {:.0} | {:.2} |",
            m.method,
            avg.scenes,
            num(c.map(|c| c.psnr), 2),
            num(c.map(|c| c.ssim), 3),
            num(c.and_then(|c| c.lpips), 3),
            avg.train_seconds / 60.0,
            avg.gaussians,
            avg.model_bytes / 1e6
        );
    }
    for row in &summary.released {
        let c = at_scale(&row.scales, 4.0, |p| p.scale);
        let _ = writeln!(
            t,
            "| {} [published, GPU: {}] | {} | {} | {} | {} | {} | {} | - |",
            row.method,
            row.source,
            row.scenes,
            num(c.map(|c| c.psnr), 2),
            num(c.map(|c| c.ssim), 3),
            num(c.map(|c| c.lpips), 3),
            num(row.train_minutes, 2),
            row.gaussians.map_or("-".into(), |g| g.to_string())
        );
    }
    t
}

/// A table's header: the `labels` columns (left-aligned, the last `right` of them
/// right-aligned), one right-aligned column per scale of `scales` and the `extra`
/// right-aligned columns after them.
pub(super) fn table_header(
    labels: &[&str],
    right: usize,
    scales: &[f64],
    extra: &[&str],
) -> String {
    let mut t = String::from("|");
    for l in labels {
        let _ = write!(t, " {l} |");
    }
    for &s in scales {
        let _ = write!(t, " {} |", scale_header(s));
    }
    for e in extra {
        let _ = write!(t, " {e} |");
    }
    t.push_str("\n|");
    t.push_str(&"---|".repeat(labels.len() - right));
    t.push_str(&"---:|".repeat(right + scales.len() + extra.len()));
    t.push('\n');
    t
}

/// Per scene and method, one metric at every evaluated scale and the mean over
/// 1x..4x, with each method's average row.
fn per_scene_table(summary: &SuiteSummary, metric: &Metric) -> String {
    let (_, digits, f) = *metric;
    let mut t = table_header(
        &["Method", "Scene", "Split"],
        0,
        &summary.scales,
        &["avg 1x-4x"],
    );
    let row = |t: &mut String, method: &str, scene: &str, split: &str, cells: &[Cell]| {
        let _ = write!(t, "| {method} | {scene} | {split} |");
        for &s in &summary.scales {
            let v = cell_at(cells, s).and_then(f);
            let _ = write!(t, " {} |", num(v, digits));
        }
        let _ = writeln!(t, " {} |", num(tab2_avg(cells, f), digits));
    };
    for m in &summary.methods {
        for r in &m.scenes {
            row(&mut t, &m.method, &r.label(), &r.split, &r.scales);
        }
        if let Some(avg) = &m.average {
            row(&mut t, &m.method, &average_label(avg), "", &avg.scales);
        }
    }
    t
}

/// PSNR of each run evaluated on other backgrounds than its own (`eval-on-NAME.json`)
/// beside its own, at every scale; `None` when no run has such an evaluation.
fn other_backgrounds_table(summary: &SuiteSummary) -> Option<String> {
    let mut t = table_header(
        &["Method", "Scene", "Evaluated on"],
        0,
        &summary.scales,
        &[],
    );
    let mut any = false;
    for m in &summary.methods {
        for r in m.scenes.iter().filter(|r| !r.other_backgrounds.is_empty()) {
            any = true;
            let own = std::iter::once((format!("{} (own)", m.background), &r.scales));
            let others = r
                .other_backgrounds
                .iter()
                .map(|o| (o.background.clone(), &o.scales));
            for (bg, cells) in own.chain(others) {
                let _ = write!(t, "| {} | {} | {bg} |", m.method, r.label());
                for &s in &summary.scales {
                    let _ = write!(t, " {} |", num(cell_at(cells, s).map(|c| c.psnr), 2));
                }
                t.push('\n');
            }
        }
    }
    any.then_some(t)
}

/// `**average (N scenes)**`, or `**average (N scenes, M runs)**` when scenes have
/// several seeds.
pub(super) fn average_label(avg: &Average) -> String {
    if avg.runs == avg.scenes {
        format!("**average ({} scenes)**", avg.scenes)
    } else {
        format!("**average ({} scenes, {} runs)**", avg.scenes, avg.runs)
    }
}

/// Per method and scene with two or more evaluated seeds: PSNR's mean and sample
/// standard deviation over the seeds at every scale, `s = sqrt(sum (x - mean)^2 /
/// (n - 1))`; `None` when no scene has two seeds.
fn seed_spread_table(summary: &SuiteSummary) -> Option<String> {
    let mut t = table_header(&["Method", "Scene", "Seeds"], 1, &summary.scales, &[]);
    let mut any = false;
    for m in &summary.methods {
        for g in by_scene(&m.scenes).into_iter().filter(|g| g.len() > 1) {
            any = true;
            let _ = write!(t, "| {} | {} | {} |", m.method, g[0].scene, g.len());
            for &s in &summary.scales {
                let v: Vec<f64> = g
                    .iter()
                    .filter_map(|r| cell_at(&r.scales, s).map(|c| c.psnr))
                    .collect();
                if v.len() < 2 {
                    t.push_str(" - |");
                    continue;
                }
                let m = mean(v.iter().copied()).unwrap_or(0.0);
                let sd =
                    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
                let _ = write!(t, " {m:.2} ± {sd:.2} |");
            }
            t.push('\n');
        }
    }
    any.then_some(t)
}

/// The markdown report of `summary`.
pub fn markdown(summary: &SuiteSummary) -> String {
    let evaluated: usize = summary.methods.iter().map(|m| m.scenes.len()).sum();
    let mut md = String::from("# D-NeRF suite report\n\n");
    let _ = writeln!(
        md,
        "{evaluated} of {} runs evaluated. Scales are relative to the training scale. maaf's \
         rows average the scenes present (the Scenes column); the published rows average \
         the eight D-NeRF scenes on a GPU: the two are not the same scenes, and the \
         published figures are copied from their sources, not measured here. \"avg\" is \
         the mean over 1x, 2x and 4x (Tab. 2's Avg.).\n",
        evaluated + summary.missing.len()
    );
    md.push_str("## Tab. 2 layout: 1x / 2x / 4x, averaged over scenes\n\n");
    md.push_str(&tab2_table(summary));
    if let Some(sets) = scene_set_table(&summary.scene_sets, &summary.paper_per_scene) {
        md.push_str(
            "\n## How hard these scenes are: the paper's per-scene table\n\n\
             Tab. 2 has no per-scene rows. The paper's one per-scene D-NeRF table (supplementary \
             `tab:supp_zoomout`: SpeeDe3DGS with and without MAAF, trained at 800x800 and \
             rendered at 1x, 1/2x and 1/4x of that) gives, for each method's scenes, their mean \
             PSNR and in brackets its difference from the table's eight-scene average: how \
             much easier (positive) or harder the scenes above are than the eight under the \
             paper's own neighbouring protocol, to read beside a gap between a maaf row and a \
             published one. Published figures, not measured here.\n\n",
        );
        md.push_str(&sets);
    }
    if let Some(gains) = gains_table(summary) {
        md.push_str(
            "\n## Paired gains: PSNR against each method listed before it, on the scenes both have\n\n\
             Each cell is the mean over the shared scenes of the per-scene PSNR difference \
             (dB), each scene first averaged over its seeds, and in brackets the shared \
             scenes on which the method is ahead. The published rows are the differences of \
             their sources' eight-scene averages.\n\n",
        );
        md.push_str(&gains);
    }
    if let Some(rings) = ring_shares_table(summary) {
        md.push_str(
            "\n## Where the gains lie: the error reduction by distance from the silhouette\n\n\
             For each pair above, the base's squared error that the method removes, split by \
             the chessboard distance d of each pixel to the silhouette of the ground truth's \
             alpha (object where it covers half the pixel), pooled over the shared scenes and \
             their views, as the paper's supplementary splits its zoom-out gain. A share \
             above the ring's pixel share means the gain concentrates there; negative: the \
             method's error grew there. ",
        );
        md.push_str(crate::report::rings::NEAR_ZERO_NOTE);
        md.push_str("\n\n");
        md.push_str(&rings);
    }
    md.push_str(
        "\n## Speed against accuracy\n\n\
         Each method's mean PSNR at 1x and 4x against its mean training wall time (on this \
         machine, with the load of the cost table below), and the released code's rows \
         with their published GPU times (crosses).\n\n\
         ![mean PSNR against training time](speed_quality.png)\n",
    );
    md.push_str("\n## At 4x against the released code (SpeeDe3DGS backbone)\n\n");
    md.push_str(&lpips_net_note(summary));
    md.push_str(&released_table(summary));
    for metric in &METRICS {
        let _ = writeln!(md, "\n## Per scene: {}\n", metric.0);
        md.push_str(&per_scene_table(summary, metric));
    }
    if let Some(spread) = seed_spread_table(summary) {
        md.push_str(
            "\n## Seeds: PSNR mean ± sample standard deviation over each scene's seeds\n\n",
        );
        md.push_str(&spread);
    }
    if let Some(other) = other_backgrounds_table(summary) {
        md.push_str(
            "\n## PSNR on other backgrounds (`maaf bench-suite --also-eval-on white`, or `maaf eval --run RUN --background white`)\n\n\
             A model trained on one background is scored on another: Gaussians it left in \
             empty space in the training background's colour (free there) now show. \
             \"(own)\" is the run's own evaluation (a `random` run's is on black).\n\n",
        );
        md.push_str(&other);
    }
    md.push_str("\n## Per scene: cost (training wall time as each run recorded it; \"Others busy\" is the load it was measured under, the cores other processes kept busy on average beside the training, blank for runs that predate it; the phase split in percent of the timed phases, from each run's `summary.json`)\n\n");
    md.push_str(&cost_table(summary));
    if !summary.missing.is_empty() {
        md.push_str("\n## Not evaluated yet\n\n");
        for d in &summary.missing {
            let _ = writeln!(md, "- `{}`", d.display());
        }
    }
    md
}
