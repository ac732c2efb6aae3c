//! The report of a D-NeRF suite (`maaf bench-suite`): one Tab. 2-shaped table of every
//! method (preset / filter / background) averaged over the scenes it was evaluated on,
//! with the paper's Tab. 2 rows and the released code's row beside it
//! ([`super::published`], labelled as published), then per-scene PSNR, SSIM and LPIPS at
//! every evaluated scale and the cost of each run (training wall time, where the
//! training time went by phase, Gaussians, model bytes). Written as `report.md` and
//! `report.json`.
//!
//! Averages are plain means over the scenes present: a cell is averaged only when every
//! evaluated scene of the method has it, and a scene is counted only once it has an
//! `eval.json`. A scene trained with several seeds (`bench-suite --seeds`) counts once,
//! as the mean of its seeds, and a table of the seeds' spread says how far runs differ
//! by chance. The "avg" columns are the mean over 1x, 2x and 4x, the paper's "Avg.".

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use maaf_scene::{PHASE_COUNT, Timings};
use serde::{Deserialize, Serialize};

use super::published::{PublishedRow, paper_tab2, released};
use super::scale_header;
use crate::EvalReport;
use crate::{Error, write_atomic};

/// The scales of Tab. 2 (relative to the training scale), whose mean is its "Avg.".
pub const TAB2_SCALES: [f64; 3] = [1.0, 2.0, 4.0];

/// One run of a suite: a scene trained and evaluated with one method.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SuiteRun {
    /// Scene (its folder name).
    pub scene: String,
    /// Split it is evaluated on (`test`, or `val` where the suite says so).
    pub split: String,
    /// Preset name (the config file's stem).
    pub preset: String,
    /// Filter: `none`, `mip3d` or `motion`.
    pub filter: String,
    /// Background: `white` or `black`.
    pub background: String,
    /// Seed it was trained with when the suite gives seeds (`--seeds`); `None`: the
    /// preset's own, and left out of `suite.json` so suites without seeds read as
    /// before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Run folder.
    pub dir: PathBuf,
}

impl SuiteRun {
    /// `preset / filter / background`, the row label of its method (seeds of one
    /// method share it).
    pub fn method(&self) -> String {
        format!("{} / {} / {}", self.preset, self.filter, self.background)
    }
}

/// One metric triple at one scale.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Cell {
    /// Render scale relative to the training scale.
    pub scale: f64,
    /// PSNR, dB.
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
    /// LPIPS (absent when the evaluation could not compute it).
    pub lpips: Option<f64>,
}

/// One evaluated scene of a method.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneResult {
    /// Scene.
    pub scene: String,
    /// Split evaluated.
    pub split: String,
    /// Run folder.
    pub run: PathBuf,
    /// Metrics per evaluated scale, ascending.
    pub scales: Vec<Cell>,
    /// Iterations trained.
    pub iterations: usize,
    /// Training wall time, seconds.
    pub train_seconds: f64,
    /// Gaussians of the final model.
    pub gaussians: usize,
    /// Bytes of the model's parameters.
    pub model_bytes: u64,
    /// Bytes of the filter state.
    pub filter_bytes: u64,
    /// Training seconds per phase (`RUN/summary.json`'s `timings`; absent when the
    /// run has no summary).
    pub phases: Option<Timings>,
    /// LPIPS backbone of its evaluation (`alex` or `vgg`, `eval.json`'s `lpips_net`).
    pub lpips_net: String,
    /// The run's seed when the suite gives seeds.
    pub seed: Option<u64>,
}

impl SceneResult {
    /// The scene's name, with the seed when the suite gives seeds (`mutant seed 1`).
    pub fn label(&self) -> String {
        match self.seed {
            Some(seed) => format!("{} seed {seed}", self.scene),
            None => self.scene.clone(),
        }
    }
}

/// A method's mean over its evaluated scenes, each scene first averaged over its
/// seeds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Average {
    /// Scenes averaged.
    pub scenes: usize,
    /// Runs averaged (more than `scenes` when scenes have several seeds).
    pub runs: usize,
    /// Per scale; a scale some scene lacks is left out, LPIPS is `None` when a scene
    /// lacks it or the scenes were evaluated with different LPIPS backbones.
    pub scales: Vec<Cell>,
    /// The scenes' common LPIPS backbone; `None` when they differ.
    pub lpips_net: Option<String>,
    /// Mean training wall time, seconds.
    pub train_seconds: f64,
    /// Mean Gaussians.
    pub gaussians: f64,
    /// Mean model bytes.
    pub model_bytes: f64,
}

/// A method and its scenes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodResult {
    /// `preset / filter / background`.
    pub method: String,
    /// Evaluated scenes, in the suite's order.
    pub scenes: Vec<SceneResult>,
    /// Their mean (absent while no scene is evaluated).
    pub average: Option<Average>,
}

/// Everything `report.json` holds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SuiteSummary {
    /// Every scale some run was evaluated at, ascending.
    pub scales: Vec<f64>,
    /// One entry per method, in the suite's order.
    pub methods: Vec<MethodResult>,
    /// Run folders without an `eval.json` yet.
    pub missing: Vec<PathBuf>,
    /// The paper's Tab. 2 rows (published, 8 scenes).
    pub paper_tab2: Vec<PublishedRow>,
    /// The released code's rows (published, 8 scenes, 4x).
    pub released: Vec<PublishedRow>,
}

/// What [`write_suite_report`] wrote.
#[derive(Clone, Debug)]
pub struct SuiteOutput {
    /// `OUT/report.md`.
    pub markdown: PathBuf,
    /// `OUT/report.json`.
    pub json: PathBuf,
    /// The Tab. 2-shaped table, for printing.
    pub table: String,
}

fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| sum / n as f64)
}

fn scene_result(run: &SuiteRun, eval: &EvalReport) -> SceneResult {
    let mut scales: Vec<Cell> = eval
        .scales
        .iter()
        .map(|s| Cell {
            scale: s.scale,
            psnr: s.psnr,
            ssim: s.ssim,
            lpips: s.lpips,
        })
        .collect();
    scales.sort_by(|a, b| a.scale.total_cmp(&b.scale));
    SceneResult {
        scene: run.scene.clone(),
        split: run.split.clone(),
        run: run.dir.clone(),
        scales,
        iterations: eval.iterations,
        train_seconds: eval.train_seconds,
        gaussians: eval.num_gaussians,
        model_bytes: eval.model_bytes,
        filter_bytes: eval.filter_bytes,
        phases: None,
        lpips_net: eval.lpips_net.clone(),
        seed: run.seed,
    }
}

fn cell_at(scene: &SceneResult, s: f64) -> Option<&Cell> {
    scene.scales.iter().find(|c| (c.scale - s).abs() < 1e-9)
}

/// The mean of each metric over `runs` at every scale in `scales` that all of them
/// have; LPIPS only when `with_lpips` and every run has it.
fn mean_cells(runs: &[&[Cell]], scales: &[f64], with_lpips: bool) -> Vec<Cell> {
    let n = runs.len() as f64;
    scales
        .iter()
        .filter_map(|&s| {
            let at: Vec<&Cell> = runs
                .iter()
                .filter_map(|cells| cells.iter().find(|c| (c.scale - s).abs() < 1e-9))
                .collect();
            (!runs.is_empty() && at.len() == runs.len()).then(|| Cell {
                scale: s,
                psnr: at.iter().map(|c| c.psnr).sum::<f64>() / n,
                ssim: at.iter().map(|c| c.ssim).sum::<f64>() / n,
                lpips: at
                    .iter()
                    .map(|c| c.lpips)
                    .sum::<Option<f64>>()
                    .filter(|_| with_lpips)
                    .map(|v| v / n),
            })
        })
        .collect()
}

/// The runs of `scenes` grouped by scene (a scene's seeds together), in the order the
/// scenes first appear.
fn by_scene(scenes: &[SceneResult]) -> Vec<Vec<&SceneResult>> {
    let mut groups: Vec<Vec<&SceneResult>> = Vec::new();
    for r in scenes {
        match groups.iter_mut().find(|g| g[0].scene == r.scene) {
            Some(g) => g.push(r),
            None => groups.push(vec![r]),
        }
    }
    groups
}

/// The mean over scenes of each scene's mean over its seeds.
fn average(scenes: &[SceneResult], scales: &[f64]) -> Option<Average> {
    if scenes.is_empty() {
        return None;
    }
    let net = &scenes[0].lpips_net;
    let lpips_net = scenes
        .iter()
        .all(|r| &r.lpips_net == net)
        .then(|| net.clone());
    let groups = by_scene(scenes);
    let per_scene: Vec<Vec<Cell>> = groups
        .iter()
        .map(|g| {
            let runs: Vec<&[Cell]> = g.iter().map(|r| r.scales.as_slice()).collect();
            mean_cells(&runs, scales, lpips_net.is_some())
        })
        .collect();
    let per_scene: Vec<&[Cell]> = per_scene.iter().map(Vec::as_slice).collect();
    let scene_mean = |f: fn(&SceneResult) -> f64| {
        groups
            .iter()
            .map(|g| g.iter().map(|r| f(r)).sum::<f64>() / g.len() as f64)
            .sum::<f64>()
            / groups.len() as f64
    };
    Some(Average {
        scenes: groups.len(),
        runs: scenes.len(),
        scales: mean_cells(&per_scene, scales, lpips_net.is_some()),
        lpips_net,
        train_seconds: scene_mean(|r| r.train_seconds),
        gaussians: scene_mean(|r| r.gaussians as f64),
        model_bytes: scene_mean(|r| r.model_bytes as f64),
    })
}

/// `**average (N scenes)**`, or `**average (N scenes, M runs)**` when scenes have
/// several seeds.
fn average_label(avg: &Average) -> String {
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
    let mut t = String::from("| Method | Scene | Seeds |");
    for &s in &summary.scales {
        let _ = write!(t, " {} |", scale_header(s));
    }
    t.push_str("\n|---|---|---:|");
    t.push_str(&"---:|".repeat(summary.scales.len()));
    t.push('\n');
    let mut any = false;
    for m in &summary.methods {
        for g in by_scene(&m.scenes).into_iter().filter(|g| g.len() > 1) {
            any = true;
            let _ = write!(t, "| {} | {} | {} |", m.method, g[0].scene, g.len());
            for &s in &summary.scales {
                let v: Vec<f64> = g
                    .iter()
                    .filter_map(|r| cell_at(r, s).map(|c| c.psnr))
                    .collect();
                if v.len() < 2 {
                    t.push_str(" - |");
                    continue;
                }
                let n = v.len() as f64;
                let mean = v.iter().sum::<f64>() / n;
                let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                let _ = write!(t, " {mean:.2} ± {sd:.2} |");
            }
            t.push('\n');
        }
    }
    any.then_some(t)
}

/// Groups `runs` (with their `eval.json`, `None` while not evaluated) by method, in
/// the order methods first appear, and averages each over its evaluated scenes.
pub fn summarise(runs: &[(SuiteRun, Option<EvalReport>)]) -> SuiteSummary {
    let mut scales: Vec<f64> = runs
        .iter()
        .filter_map(|(_, e)| e.as_ref())
        .flat_map(|e| e.scales.iter().map(|s| s.scale))
        .collect();
    scales.sort_by(f64::total_cmp);
    scales.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let mut methods: Vec<MethodResult> = Vec::new();
    let mut missing = Vec::new();
    for (run, eval) in runs {
        let name = run.method();
        let i = match methods.iter().position(|m| m.method == name) {
            Some(i) => i,
            None => {
                methods.push(MethodResult {
                    method: name,
                    scenes: Vec::new(),
                    average: None,
                });
                methods.len() - 1
            }
        };
        match eval {
            Some(e) => methods[i].scenes.push(scene_result(run, e)),
            None => missing.push(run.dir.clone()),
        }
    }
    for m in &mut methods {
        m.average = average(&m.scenes, &scales);
    }
    SuiteSummary {
        scales,
        methods,
        missing,
        paper_tab2: paper_tab2(),
        released: released(),
    }
}

/// `v` with `digits` decimals, `-` when absent.
fn num(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.digits$}"))
}

/// The mean over [`TAB2_SCALES`] of one metric, when every one is present.
fn tab2_avg(cells: &[Cell], f: fn(&Cell) -> Option<f64>) -> Option<f64> {
    let v: Vec<f64> = TAB2_SCALES
        .iter()
        .map(|&s| {
            cells
                .iter()
                .find(|c| (c.scale - s).abs() < 1e-9)
                .and_then(f)
        })
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
                let v = avg
                    .scales
                    .iter()
                    .find(|c| (c.scale - s).abs() < 1e-9)
                    .and_then(f);
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
            let pick = |p: &super::published::PublishedScale| [p.psnr, p.ssim, p.lpips][i];
            for s in TAB2_SCALES {
                let v = row.scales.iter().find(|p| p.scale == s).map(pick);
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
fn lpips_net_note(summary: &SuiteSummary) -> String {
    let mut nets: Vec<&str> = summary
        .methods
        .iter()
        .filter_map(|m| m.average.as_ref())
        .map(|a| a.lpips_net.as_deref().map_or("mixed", super::lpips_label))
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
        let c = avg.scales.iter().find(|c| (c.scale - 4.0).abs() < 1e-9);
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
        let c = row.scales.iter().find(|p| p.scale == 4.0);
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

/// Per scene and method, one metric at every evaluated scale and the mean over
/// 1x..4x, with each method's average row.
fn per_scene_table(summary: &SuiteSummary, metric: &Metric) -> String {
    let (_, digits, f) = *metric;
    let mut t = String::from("| Method | Scene | Split |");
    for &s in &summary.scales {
        let _ = write!(t, " {} |", scale_header(s));
    }
    let _ = write!(t, " avg 1x-4x |\n|---|---|---|");
    t.push_str(&"---:|".repeat(summary.scales.len() + 1));
    t.push('\n');
    let row = |t: &mut String, method: &str, scene: &str, split: &str, cells: &[Cell]| {
        let _ = write!(t, "| {method} | {scene} | {split} |");
        for &s in &summary.scales {
            let v = cells
                .iter()
                .find(|c| (c.scale - s).abs() < 1e-9)
                .and_then(f);
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

/// The mean CPU minutes over the scenes that have them.
fn mean_cpu_minutes(scenes: &[SceneResult]) -> Option<f64> {
    let all: Vec<f64> = scenes.iter().filter_map(cpu_minutes).collect();
    (!all.is_empty()).then(|| all.iter().sum::<f64>() / all.len() as f64)
}

/// The cores other processes kept busy beside a run's training
/// ([`Timings::others_busy`]), `None` when its summary predates the machine's clock.
fn others_busy(r: &SceneResult) -> Option<f64> {
    r.phases.as_ref().and_then(Timings::others_busy)
}

/// The mean load beside the runs over the scenes that recorded it.
fn mean_others_busy(scenes: &[SceneResult]) -> Option<f64> {
    let all: Vec<f64> = scenes.iter().filter_map(others_busy).collect();
    (!all.is_empty()).then(|| all.iter().sum::<f64>() / all.len() as f64)
}

/// Per scene and method: iterations, training wall and CPU time, the load beside it,
/// the phase split (percent of the timed phases), Gaussians, bytes.
fn cost_table(summary: &SuiteSummary) -> String {
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
                num(mean_cpu_minutes(&m.scenes), 2),
                num(mean_others_busy(&m.scenes), 2),
                share_cells(mean_shares(&m.scenes)),
                avg.gaussians,
                avg.model_bytes / 1e6
            );
        }
    }
    t
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

/// Reads each run's `eval.json` (a run without one is listed as not evaluated yet)
/// and writes `OUT/report.md` and `OUT/report.json`.
pub fn write_suite_report(runs: &[SuiteRun], out: &Path) -> Result<SuiteOutput, Error> {
    let mut loaded = Vec::with_capacity(runs.len());
    for r in runs {
        let eval = if r.dir.join("eval.json").is_file() {
            Some(EvalReport::read(&r.dir)?)
        } else {
            None
        };
        loaded.push((r.clone(), eval));
    }
    let mut summary = summarise(&loaded);
    for m in &mut summary.methods {
        for r in &mut m.scenes {
            r.phases = read_phases(&r.run)?;
        }
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let markdown_path = out.join("report.md");
    write_atomic(&markdown_path, markdown(&summary).as_bytes())?;
    let json_path = out.join("report.json");
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::Input(format!("cannot serialise the suite report: {e}")))?;
    write_atomic(&json_path, json.as_bytes())?;
    Ok(SuiteOutput {
        markdown: markdown_path,
        json: json_path,
        table: tab2_table(&summary),
    })
}

/// The `timings` of `RUN/summary.json`, `None` when the run has no summary; a
/// summary that cannot be read is an error naming it.
fn read_phases(run: &Path) -> Result<Option<Timings>, Error> {
    #[derive(Deserialize)]
    struct Summary {
        timings: Timings,
    }
    let path = run.join("summary.json");
    if !path.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let summary: Summary = serde_json::from_str(&text)
        .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
    Ok(Some(summary.timings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ScaleResult;

    fn run(scene: &str, filter: &str) -> SuiteRun {
        SuiteRun {
            scene: scene.into(),
            split: "test".into(),
            preset: "dnerf".into(),
            filter: filter.into(),
            background: "black".into(),
            seed: None,
            dir: format!("{scene}/{filter}").into(),
        }
    }

    fn eval(psnr: f64, scales: &[f64]) -> EvalReport {
        let cells = scales
            .iter()
            .map(|&s| {
                let mut c = ScaleResult::new(s, (8, 8), psnr + s, 0.9);
                c.lpips = Some(0.1 * s);
                c
            })
            .collect();
        let mut r = super::super::ReportRun::for_test("x", "saro", "motion", cells).eval;
        r.train_seconds = psnr;
        r
    }

    #[test]
    fn methods_average_their_evaluated_scenes_and_list_the_rest() {
        let all = [0.25, 1.0, 2.0, 4.0];
        let runs = vec![
            (run("a", "motion"), Some(eval(30.0, &all))),
            (run("a", "none"), Some(eval(20.0, &all))),
            (run("b", "motion"), Some(eval(34.0, &all))),
            (run("b", "none"), None),
        ];
        let s = summarise(&runs);
        assert_eq!(s.methods.len(), 2);
        assert_eq!(s.missing, vec![PathBuf::from("b/none")]);
        let motion = s.methods[0].average.as_ref().expect("average");
        assert_eq!(motion.scenes, 2);
        let at4 = motion.scales.iter().find(|c| c.scale == 4.0).expect("4x");
        assert!((at4.psnr - 36.0).abs() < 1e-12);
        assert!((motion.train_seconds - 32.0).abs() < 1e-12);
        let none = s.methods[1].average.as_ref().expect("average");
        assert_eq!(none.scenes, 1);
        // Tab. 2's avg: the mean of 1x, 2x, 4x (32 + 34 + 36) / 3.
        let table = tab2_table(&s);
        assert!(
            table.contains("| dnerf / motion / black (maaf) | 2 | 33.00 | 34.00 | 36.00 | 34.33 |"),
            "{table}"
        );
        assert!(
            table.contains("37.10") && table.contains("36.61"),
            "{table}"
        );
        assert!(released_table(&s).contains("32.28"));
    }

    #[test]
    fn a_scene_with_several_seeds_counts_once_and_its_spread_is_reported() {
        let seeded = |scene: &str, seed| SuiteRun {
            seed: Some(seed),
            dir: format!("{scene}/motion-seed{seed}").into(),
            ..run(scene, "motion")
        };
        let runs = vec![
            (seeded("a", 0), Some(eval(30.0, &[1.0, 4.0]))),
            (seeded("a", 1), Some(eval(32.0, &[1.0, 4.0]))),
            (seeded("a", 2), Some(eval(34.0, &[1.0, 4.0]))),
            (seeded("b", 0), Some(eval(40.0, &[1.0, 4.0]))),
        ];
        let s = summarise(&runs);
        let avg = s.methods[0].average.as_ref().expect("average");
        assert_eq!((avg.scenes, avg.runs), (2, 4));
        // At 1x a's seeds give 31, 33, 35 (mean 33) and b 41: the scenes' mean is 37,
        // where the runs' mean would be 35; likewise the time, (32 + 40) / 2.
        assert!((avg.scales[0].psnr - 37.0).abs() < 1e-12, "{avg:?}");
        assert!((avg.train_seconds - 36.0).abs() < 1e-12);
        let md = markdown(&s);
        // The sample standard deviation of 31, 33, 35 is 2; b has one seed, no row.
        assert!(
            md.contains("| dnerf / motion / black | a | 3 | 33.00 ± 2.00 | 36.00 ± 2.00 |"),
            "{md}"
        );
        assert!(!md.contains("| dnerf / motion / black | b | 1 |"), "{md}");
        assert!(md.contains("| a seed 1 |") && md.contains("**average (2 scenes, 4 runs)**"));
        // A suite without seeds has no such section and reads as before.
        let plain = markdown(&summarise(&[(
            run("a", "motion"),
            Some(eval(30.0, &[1.0])),
        )]));
        assert!(!plain.contains("## Seeds") && plain.contains("**average (1 scenes)**"));
        let json = serde_json::to_string(&run("a", "motion")).expect("json");
        assert!(!json.contains("seed"), "{json}");
    }

    #[test]
    fn a_scale_missing_in_one_scene_is_left_out_of_the_average() {
        let runs = vec![
            (run("a", "motion"), Some(eval(30.0, &[1.0, 2.0, 4.0]))),
            (run("b", "motion"), Some(eval(30.0, &[1.0, 2.0]))),
        ];
        let s = summarise(&runs);
        let avg = s.methods[0].average.as_ref().expect("average");
        let scales: Vec<f64> = avg.scales.iter().map(|c| c.scale).collect();
        assert_eq!(scales, vec![1.0, 2.0]);
        let md = markdown(&s);
        assert!(md.contains("**average (2 scenes)**"), "{md}");
    }

    #[test]
    fn the_cost_table_splits_training_time_by_phase_and_averages_the_shares() {
        let runs = vec![
            (run("a", "motion"), Some(eval(30.0, &[1.0]))),
            (run("b", "motion"), Some(eval(30.0, &[1.0]))),
            (run("c", "motion"), Some(eval(30.0, &[1.0]))),
        ];
        let mut s = summarise(&runs);
        let timings = |field_mlp, backward, cpu, machine_cpu| Timings {
            field_mlp,
            render_forward: 1.0,
            backward,
            optimiser: 1.0,
            statistics: 1.0,
            filter_refresh: 0.5,
            densification: 0.5,
            cpu,
            machine_cpu,
        };
        // a: 2 + 1 + 4 + 1 + 1 + 0.5 + 0.5 = 10 s; b: 6 + 1 + 2 + 1 + 1 + 0.5 + 0.5 = 12 s.
        // CPU: a 0.25 min, b 0.35 min; the phases' sum leaves CPU time out. Others
        // busy: a (20 - 15) / 10 = 0.50 cores; b predates the machine clock (blank).
        s.methods[0].scenes[0].phases = Some(timings(2.0, 4.0, 15.0, 20.0));
        s.methods[0].scenes[1].phases = Some(timings(6.0, 2.0, 21.0, 0.0));
        let a = phase_shares(s.methods[0].scenes[0].phases.as_ref()).expect("shares");
        assert!(
            (a[0] - 20.0).abs() < 1e-9 && (a[2] - 40.0).abs() < 1e-9 && (a[4] - 10.0).abs() < 1e-9
        );
        assert!((a.iter().sum::<f64>() - 100.0).abs() < 1e-9);
        let table = cost_table(&s);
        assert!(
            table.contains("| 0.25 | 0.50 | 20 | 10 | 40 | 10 | 10 | 5 | 5 |"),
            "{table}"
        );
        assert!(
            table.contains("| 0.35 | - | 50 | 8 | 17 | 8 | 8 | 4 | 4 |"),
            "{table}"
        );
        // Scene c has no summary: dashes, and the average is over a and b only
        // (field + MLPs (20 + 50) / 2 = 35, filter (5 + 4.17) / 2 = 4.58; CPU
        // (0.25 + 0.35) / 2 = 0.30; others busy over a alone).
        assert!(
            table.contains("| - | - | - | - | - | - | - | - | - |"),
            "{table}"
        );
        assert!(
            table.contains("| 0.30 | 0.50 | 35 | 9 | 28 | 9 | 9 | 5 | 5 |"),
            "{table}"
        );
        assert_eq!(phase_shares(Some(&Timings::default())), None);
    }

    #[test]
    fn lpips_is_averaged_only_over_one_backbone_and_the_note_says_which() {
        let vgg = |psnr| {
            let mut e = eval(psnr, &[1.0, 4.0]);
            e.lpips_net = "vgg".into();
            e
        };
        let all_vgg = summarise(&[
            (run("a", "motion"), Some(vgg(30.0))),
            (run("b", "motion"), Some(vgg(31.0))),
        ]);
        let avg = all_vgg.methods[0].average.as_ref().expect("average");
        assert_eq!(avg.lpips_net.as_deref(), Some("vgg"));
        assert!((avg.scales[1].lpips.expect("lpips") - 0.4).abs() < 1e-12);
        assert!(lpips_net_note(&all_vgg).contains("the LPIPS column compares"));

        let mixed = summarise(&[
            (run("a", "motion"), Some(vgg(30.0))),
            (run("b", "motion"), Some(eval(31.0, &[1.0, 4.0]))),
        ]);
        let avg = mixed.methods[0].average.as_ref().expect("average");
        assert_eq!(avg.lpips_net, None);
        assert!(avg.scales.iter().all(|c| c.lpips.is_none()), "{avg:?}");
        assert!(avg.scales.iter().all(|c| c.psnr > 0.0));
        let note = lpips_net_note(&mixed);
        assert!(note.contains("use mixed features"), "{note}");

        let alex = summarise(&[(run("a", "none"), Some(eval(30.0, &[4.0])))]);
        let note = lpips_net_note(&alex);
        assert!(note.contains("use AlexNet features") && note.contains("--lpips-net vgg"));
    }
}
