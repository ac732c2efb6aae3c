//! The report of a D-NeRF suite (`maaf bench-suite`): one Tab. 2-shaped table of every
//! method (preset / filter / background) averaged over the scenes it was evaluated on,
//! with the paper's Tab. 2 rows and the released code's row beside it
//! ([`super::published`], labelled as published) and how hard each method's scenes are
//! against all eight by the paper's per-scene table ([`scene_sets`]), then per-scene
//! PSNR, SSIM and LPIPS at every evaluated scale and the cost of each run (training
//! wall time, where the training time went by phase, Gaussians, model bytes), and a
//! chart of each method's PSNR against its training time (`chart.rs`). Written as
//! `report.md`, `report.json` and `speed_quality.png`.
//!
//! Averages are plain means over the scenes present: a cell is averaged only when every
//! evaluated scene of the method has it, and a scene is counted only once it has an
//! `eval.json`. Because methods may cover different scenes, the report also pairs
//! them ([`gains`]): a method's PSNR minus another's on the scenes both have. A scene
//! trained with several seeds (`bench-suite --seeds`) counts once,
//! as the mean of its seeds, and a table of the seeds' spread says how far runs differ
//! by chance. The "avg" columns are the mean over 1x, 2x and 4x, the paper's "Avg.".

use std::path::{Path, PathBuf};

use maaf_scene::Timings;
use serde::{Deserialize, Serialize};

use super::published::{PerScenePsnr, PublishedRow, paper_tab2, per_scene_psnr, released};
use crate::EvalReport;
use crate::eval_json::OTHER_BACKGROUND_PREFIX;
use crate::metrics::rings::RingErrors;
use crate::{Error, write_atomic};

mod chart;
mod cost;
mod gains;
mod scene_set;
mod tables;

pub use cost::phase_shares;
pub use gains::{Gain, GainAt, gains, gains_table, ring_shares_table};
pub use scene_set::{SceneSet, scene_set, scene_set_table, scene_sets};
pub use tables::{markdown, released_table, tab2_table};

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
    /// Background: `white`, `black` or `random` (a random colour per training view,
    /// data and evaluation on black).
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
    /// Squared error by distance from the silhouette (`eval.json`'s `rings`), for the
    /// paired gains' error-reduction shares; not written to `report.json` per cell,
    /// and absent from averages.
    #[serde(skip)]
    pub rings: Option<RingErrors>,
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
    /// Its evaluations on other backgrounds than its own (`RUN/eval-on-NAME.json`),
    /// by name.
    pub other_backgrounds: Vec<OtherBackground>,
}

/// A run evaluated on another background than the one it trained on (`maaf eval
/// --background`, `RUN/eval-on-NAME.json`): on white, what a model trained on black
/// left in empty space shows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OtherBackground {
    /// The evaluation's background (`white`, `black`, `R,G,B`).
    pub background: String,
    /// Its metrics per scale, ascending.
    pub scales: Vec<Cell>,
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
    /// Its preset.
    pub preset: String,
    /// Its filter (the chart's colour).
    pub filter: String,
    /// Its background.
    pub background: String,
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
    /// Each method against every one before it with the same preset and background,
    /// on their shared scenes ([`gains`]).
    pub gains: Vec<Gain>,
    /// Run folders without an `eval.json` yet.
    pub missing: Vec<PathBuf>,
    /// The paper's Tab. 2 rows (published, 8 scenes).
    pub paper_tab2: Vec<PublishedRow>,
    /// The released code's rows (published, 8 scenes, 4x).
    pub released: Vec<PublishedRow>,
    /// The paper's per-scene table (published, trained at 800x800), which says how
    /// each method's scenes sit against all eight.
    pub paper_per_scene: PerScenePsnr,
    /// Each method's scenes in that table ([`scene_sets`]).
    pub scene_sets: Vec<SceneSet>,
}

/// What [`write_suite_report`] wrote.
#[derive(Clone, Debug)]
pub struct SuiteOutput {
    /// `OUT/report.md`.
    pub markdown: PathBuf,
    /// `OUT/report.json`.
    pub json: PathBuf,
    /// `OUT/speed_quality.png` (`chart.rs`).
    pub chart: PathBuf,
    /// The Tab. 2-shaped table, for printing.
    pub table: String,
}

/// The mean of `v`, `None` when it is empty.
pub(super) fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| sum / n as f64)
}

/// The metrics of `eval` per scale, ascending.
fn cells(eval: &EvalReport) -> Vec<Cell> {
    let mut scales: Vec<Cell> = eval
        .scales
        .iter()
        .map(|s| Cell {
            scale: s.scale,
            psnr: s.psnr,
            ssim: s.ssim,
            lpips: s.lpips,
            rings: s.rings,
        })
        .collect();
    scales.sort_by(|a, b| a.scale.total_cmp(&b.scale));
    scales
}

fn scene_result(run: &SuiteRun, eval: &EvalReport) -> SceneResult {
    SceneResult {
        scene: run.scene.clone(),
        split: run.split.clone(),
        run: run.dir.clone(),
        scales: cells(eval),
        iterations: eval.iterations,
        train_seconds: eval.train_seconds,
        gaussians: eval.num_gaussians,
        model_bytes: eval.model_bytes,
        filter_bytes: eval.filter_bytes,
        phases: None,
        lpips_net: eval.lpips_net.clone(),
        seed: run.seed,
        other_backgrounds: Vec::new(),
    }
}

/// The item of `items` at render scale `s` (`scale` reads an item's), if any.
fn at_scale<T>(items: &[T], s: f64, scale: impl Fn(&T) -> f64) -> Option<&T> {
    items.iter().find(|x| (scale(x) - s).abs() < 1e-9)
}

/// The metrics at scale `s` among `cells`, if it was evaluated there.
fn cell_at(cells: &[Cell], s: f64) -> Option<&Cell> {
    at_scale(cells, s, |c| c.scale)
}

/// The mean of each metric over `runs` at every scale in `scales` that all of them
/// have; LPIPS only when `with_lpips` and every run has it.
fn mean_cells(runs: &[&[Cell]], scales: &[f64], with_lpips: bool) -> Vec<Cell> {
    let n = runs.len() as f64;
    scales
        .iter()
        .filter_map(|&s| {
            let at: Vec<&Cell> = runs.iter().filter_map(|cells| cell_at(cells, s)).collect();
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
                rings: None,
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

/// Each scene group's cells averaged over its seeds (see [`mean_cells`]).
fn seed_means(groups: &[Vec<&SceneResult>], scales: &[f64], with_lpips: bool) -> Vec<Vec<Cell>> {
    groups
        .iter()
        .map(|g| {
            let runs: Vec<&[Cell]> = g.iter().map(|r| r.scales.as_slice()).collect();
            mean_cells(&runs, scales, with_lpips)
        })
        .collect()
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
    let per_scene = seed_means(&groups, scales, lpips_net.is_some());
    let per_scene: Vec<&[Cell]> = per_scene.iter().map(Vec::as_slice).collect();
    let scene_mean = |f: fn(&SceneResult) -> f64| {
        mean(groups.iter().filter_map(|g| mean(g.iter().map(|r| f(r))))).unwrap_or(0.0)
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
                    preset: run.preset.clone(),
                    filter: run.filter.clone(),
                    background: run.background.clone(),
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
    let paper_per_scene = per_scene_psnr();
    SuiteSummary {
        gains: gains(&methods, &scales),
        scene_sets: scene_sets(&methods, &paper_per_scene),
        scales,
        methods,
        missing,
        paper_tab2: paper_tab2(),
        released: released(),
        paper_per_scene,
    }
}

/// Reads each run's `eval.json` (a run without one is listed as not evaluated yet)
/// and writes `OUT/report.md`, `OUT/report.json` and `OUT/speed_quality.png`.
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
            r.other_backgrounds = read_other_backgrounds(&r.run)?;
        }
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let markdown_path = out.join("report.md");
    write_atomic(&markdown_path, markdown(&summary).as_bytes())?;
    let json_path = out.join("report.json");
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::Input(format!("cannot serialise the suite report: {e}")))?;
    write_atomic(&json_path, json.as_bytes())?;
    let chart_path = out.join("speed_quality.png");
    chart::speed_quality(&summary, &chart_path)?;
    Ok(SuiteOutput {
        markdown: markdown_path,
        json: json_path,
        chart: chart_path,
        table: tab2_table(&summary),
    })
}

/// The run's `eval-on-NAME.json` files, each named by the background it records, in
/// name order; an unreadable one is an error naming it.
fn read_other_backgrounds(run: &Path) -> Result<Vec<OtherBackground>, Error> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(run).map_err(|e| Error::io(run, e))? {
        let path = entry.map_err(|e| Error::io(run, e))?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.starts_with(OTHER_BACKGROUND_PREFIX) && name.ends_with(".json") {
            let eval = EvalReport::read_file(&path)?;
            found.push(OtherBackground {
                background: maaf_data::Background(eval.background).to_string(),
                scales: cells(&eval),
            });
        }
    }
    found.sort_by(|a, b| a.background.cmp(&b.background));
    Ok(found)
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
mod tests;
