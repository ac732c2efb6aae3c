//! The `RUN/eval.json` contract (docs/conventions.md): [`EvalReport`], one
//! [`ScaleResult`] per evaluation scale, and the temporal-stability entries
//! ([`TemporalResult`]) that `maaf eval --temporal` adds.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::Error;
use crate::metrics::regions::RegionPsnr;
use crate::metrics::rings::RingErrors;

/// Metrics at one evaluation scale (an entry of `eval.json`'s `scales`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleResult {
    /// Scale relative to the training scale.
    pub scale: f64,
    /// Rendered width, pixels.
    pub width: u32,
    /// Rendered height, pixels.
    pub height: u32,
    /// Mean over views of the per-image PSNR, dB (data range 1).
    pub psnr: f64,
    /// Mean over views of the per-image SSIM (scikit-image convention).
    pub ssim: f64,
    /// Mean over views of LPIPS (lin v0.1 on the backbone named in
    /// [`EvalReport::lpips_net`], [`maaf_lpips::Lpips::distance`]: RGB mapped to
    /// [-1, 1], no resizing); `null` when it could not be computed, with the reason in
    /// [`ScaleResult::lpips_note`].
    pub lpips: Option<f64>,
    /// Why `lpips` is `null` (weights missing, image below
    /// [`maaf_lpips::Net::min_size`] pixels); `null` when LPIPS was computed.
    #[serde(default)]
    pub lpips_note: Option<String>,
    /// W-Temporal Error (supplementary: `sum_t E_warp(I_t, I_{t+1})`) of the
    /// fixed-camera video with the flow named in [`ScaleResult::flow`]; `null` unless
    /// evaluated with `--temporal`.
    pub warp_error: Option<f64>,
    /// W-SSIM (mean over t of `SSIM(I_t, warped I_{t+1})`) with the same flow.
    #[serde(default)]
    pub w_ssim: Option<f64>,
    /// W-LPIPS (mean over t of `LPIPS(I_t, warped I_{t+1})`) with the same flow;
    /// `null` also when LPIPS is unavailable (see `lpips_note`).
    #[serde(default)]
    pub w_lpips: Option<f64>,
    /// Which flow `warp_error`, `w_ssim` and `w_lpips` used: `exact` (the data set's
    /// own flow files, preferred when present) or `model` (the run's rendered screen
    /// motion); `null` without `--temporal`.
    #[serde(default)]
    pub flow: Option<String>,
    /// Every temporal evaluation of this scale (exact and model flow side by side),
    /// with the per-step warping error for the chart; empty without `--temporal`.
    #[serde(default)]
    pub temporal: Vec<TemporalResult>,
    /// PSNR by region (moving, static, silhouette band), when the data set has
    /// moving-object masks for the evaluated views; `null` otherwise.
    #[serde(default)]
    pub regions: Option<RegionSummary>,
    /// Squared error by distance from the object silhouette, summed over the views
    /// ([`crate::metrics::rings`]), when the data set has alpha (D-NeRF); `null`
    /// otherwise. Two runs' sums give the share of an error reduction per ring.
    #[serde(default)]
    pub rings: Option<RingErrors>,
    /// Popping of single Gaussians in the fixed-camera video of the temporal metrics;
    /// `null` without `--temporal`.
    #[serde(default)]
    pub popping: Option<PoppingResult>,
    /// Mean over views of each per-image metric a program registered
    /// ([`crate::ImageMetric`]), by name; left out of the file when there is none.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub extra: BTreeMap<String, f64>,
}

/// Mean over views of the per-view PSNR of each region
/// ([`crate::metrics::regions`]), over the views that have pixels in it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegionSummary {
    /// Moving pixels, dB.
    pub moving: Option<f64>,
    /// Static pixels, dB.
    pub static_: Option<f64>,
    /// Silhouette band, dB.
    pub band: Option<f64>,
    /// Views averaged for moving, static and band.
    pub views: [usize; 3],
}

impl RegionSummary {
    /// The summary of per-view values (`None` when there are none).
    pub fn of(per_view: impl Iterator<Item = RegionPsnr>) -> Option<Self> {
        let mut sums = [0.0f64; 3];
        let mut views = [0usize; 3];
        let mut any = false;
        for r in per_view {
            any = true;
            for (k, v) in [r.moving, r.static_, r.band].into_iter().enumerate() {
                if let Some(v) = v {
                    sums[k] += v;
                    views[k] += 1;
                }
            }
        }
        let mean = |k: usize| (views[k] > 0).then(|| sums[k] / views[k] as f64);
        any.then(|| RegionSummary {
            moving: mean(0),
            static_: mean(1),
            band: mean(2),
            views,
        })
    }
}

impl std::fmt::Display for RegionSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let show = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2} dB"));
        write!(
            f,
            "moving {} ({} views), static {} ({}), band {} ({})",
            show(self.moving),
            self.views[0],
            show(self.static_),
            self.views[1],
            show(self.band),
            self.views[2]
        )
    }
}

impl ScaleResult {
    /// A scale with PSNR and SSIM only (no LPIPS, no temporal metrics yet).
    pub fn new(scale: f64, (width, height): (u32, u32), psnr: f64, ssim: f64) -> Self {
        ScaleResult {
            scale,
            width,
            height,
            psnr,
            ssim,
            lpips: None,
            lpips_note: None,
            warp_error: None,
            w_ssim: None,
            w_lpips: None,
            flow: None,
            temporal: Vec::new(),
            regions: None,
            rings: None,
            popping: None,
            extra: BTreeMap::new(),
        }
    }
}

/// Temporal stability of one fixed-camera video at one scale with one flow
/// ([`crate::metrics::temporal::temporal_metrics`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemporalResult {
    /// `exact` (data set flow files) or `model` (rendered Gaussian motion,
    /// [`crate::flow::model_flow`]).
    pub flow: String,
    /// Which camera the video was rendered from: `video 0` (the data set's fixed-camera
    /// video split) or `test 0` (the first test camera, when there is no video split).
    pub camera: String,
    /// Times of the `T` frames, ascending.
    pub times: Vec<f64>,
    /// W-Temporal Error: the sum over the `T - 1` steps of `E_warp`.
    pub warp_error: f64,
    /// W-SSIM: mean over the steps.
    pub w_ssim: f64,
    /// W-LPIPS: mean over the steps (`null` without LPIPS weights).
    pub w_lpips: Option<f64>,
    /// `E_warp(I_t, I_{t+1})` of each step, `T - 1` values (the supplementary's
    /// warping-error-over-time figure).
    pub per_step: Vec<f64>,
}

/// Popping of single Gaussians in one fixed-camera video at one scale
/// ([`crate::metrics::popping`]: a Gaussian pops when its visible weight at least
/// halves or doubles within one frame step).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoppingResult {
    /// The camera of the video, as in [`TemporalResult::camera`].
    pub camera: String,
    /// Times of the `T` frames, ascending.
    pub times: Vec<f64>,
    /// Popping Gaussians of each step, `T - 1` values.
    pub pops: Vec<usize>,
    /// Popped mass of each step (fraction of the frame's pixels), `T - 1` values.
    pub mass: Vec<f64>,
}

impl PoppingResult {
    /// Mean number of popping Gaussians per step.
    pub fn mean_pops(&self) -> f64 {
        mean(self.pops.iter().map(|&p| p as f64))
    }

    /// Mean popped mass per step.
    pub fn mean_mass(&self) -> f64 {
        mean(self.mass.iter().copied())
    }

    /// The step with the largest popped mass: `(t, mass)`, `t` the time of its first
    /// frame; `None` for a video of one frame.
    pub fn worst_step(&self) -> Option<(f64, f64)> {
        self.mass
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(j, &m)| (self.times[j], m))
    }
}

/// `RUN/eval.json`: exactly the field names of the docs/conventions.md contract.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalReport {
    /// Representation label (`saro`, `deform + GroupFlow (500 groups)`).
    pub model: String,
    /// Filter: `none`, `mip3d` or `motion`.
    pub filter: String,
    /// Training scale relative to the source images.
    pub train_scale: f64,
    /// Iterations trained.
    pub iterations: usize,
    /// Training wall time, seconds (all phases, summed over every resume).
    pub train_seconds: f64,
    /// Number of Gaussians.
    pub num_gaussians: usize,
    /// Bytes of the representation's parameters (`num_scalars * 4`).
    pub model_bytes: u64,
    /// Bytes of the filter state (`bytes_per_gaussian * num_gaussians`).
    pub filter_bytes: u64,
    /// Background colour the renders and ground truth are composited on.
    pub background: [f32; 3],
    /// Background the run was trained on, when the evaluation composited on another
    /// (`maaf eval --background`; its outputs are then [`EvalReport::name`]
    /// `eval-on-NAME`); left out of the file otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trained_background: Option<[f32; 3]>,
    /// Whether renders were quantised to 8 bits before the metrics (always `false`).
    pub quantized_8bit: bool,
    /// Every this many distinct times of the split were evaluated (1 = all views; then
    /// the field is left out of `eval.json`, whose contract is unchanged).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub frame_stride: usize,
    /// Backbone of `lpips` and `w_lpips`: `alex` (then the field is left out of
    /// `eval.json`, as files written before VGG was offered) or `vgg`.
    #[serde(default = "alex", skip_serializing_if = "is_alex")]
    pub lpips_net: String,
    /// One entry per evaluated scale, in the order asked.
    pub scales: Vec<ScaleResult>,
    /// The scales asked for that the data cannot give ground truth for, with the
    /// reason (left out of the file when every scale was evaluated).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub skipped_scales: Vec<SkippedScale>,
    /// The per-image metrics of [`ScaleResult::extra`], by name, with which way is
    /// better; left out of the file when there is none.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub extra_metrics: BTreeMap<String, ExtraMetric>,
}

/// What `eval.json` records of a per-image metric of one's own besides its values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtraMetric {
    /// Whether a larger value is better ([`crate::ImageMetric::higher_is_better`]).
    pub higher_is_better: bool,
}

/// A scale `maaf eval` was asked for and skipped.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkippedScale {
    /// The scale, relative to the training scale.
    pub scale: f64,
    /// Why no ground truth of that size can be made.
    pub reason: String,
}

fn one() -> usize {
    1
}

fn is_one(v: &usize) -> bool {
    *v == 1
}

fn alex() -> String {
    maaf_lpips::Net::Alex.name().to_string()
}

fn is_alex(v: &String) -> bool {
    *v == alex()
}

/// Start of the name of an evaluation on another background than the run's
/// ([`EvalReport::name`]).
pub const OTHER_BACKGROUND_PREFIX: &str = "eval-on-";

/// Name of the outputs of an evaluation on the background spelt `background`
/// (`white`, `black`, `r,g,b`) when it is not the run's own: `eval-on-white`.
pub fn other_background_name(background: &str) -> String {
    format!("{OTHER_BACKGROUND_PREFIX}{background}")
}

impl EvalReport {
    /// Name of the evaluation's outputs in the run folder (`NAME.json` and the image
    /// folder `NAME/`): `eval` on the background the run trained on; on another one
    /// `eval-on-white`, `eval-on-black` or `eval-on-R,G,B`. Evaluating on another
    /// background shows what a model put into empty space (Gaussians clamped to the
    /// training background's colour appear as floaters), and never replaces the run's
    /// own `eval.json`, which the reports read.
    pub fn name(&self) -> String {
        match self.trained_background {
            None => "eval".into(),
            Some(_) => other_background_name(&maaf_data::Background(self.background).to_string()),
        }
    }

    /// Mean PSNR over the scales (the "Avg." column of the paper's tables).
    pub fn mean_psnr(&self) -> f64 {
        mean(self.scales.iter().map(|s| s.psnr))
    }

    /// Mean SSIM over the scales.
    pub fn mean_ssim(&self) -> f64 {
        mean(self.scales.iter().map(|s| s.ssim))
    }

    /// Model plus filter bytes.
    pub fn total_bytes(&self) -> u64 {
        self.model_bytes + self.filter_bytes
    }

    /// Reads `RUN/eval.json`.
    pub fn read(run: &Path) -> Result<Self, Error> {
        Self::read_file(&run.join("eval.json"))
    }

    /// Reads an evaluation file (`eval.json`, `eval-on-white.json`, ...).
    pub fn read_file(path: &Path) -> Result<Self, Error> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text).map_err(|e| {
            // Older versions wrote a NaN metric as null; say so instead of a type error.
            let hint = if e.to_string().contains("null") {
                " (a null metric: the evaluated model rendered non-finite pixels; retrain and re-run `maaf eval`)"
            } else {
                ""
            };
            Error::Input(format!("{}: not an eval.json: {e}{hint}", path.display()))
        })
    }
}

/// Arithmetic mean, NaN for no value.
pub(crate) fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Folder name of a scale's outputs: `1x`, `2x`, `0.5x`, `0.25x`.
pub fn scale_label(scale: f64) -> String {
    format!("{}x", trim_float(scale))
}

/// `0.5` -> `0.5`, `2.0` -> `2`: the shortest decimal spelling of a scale.
pub fn trim_float(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels() {
        assert_eq!(scale_label(1.0), "1x");
        assert_eq!(scale_label(0.25), "0.25x");
        assert_eq!(scale_label(4.0), "4x");
        assert_eq!(trim_float(0.125), "0.125");
    }

    #[test]
    fn report_has_the_contract_fields() {
        let r = EvalReport {
            model: "saro".into(),
            filter: "motion".into(),
            train_scale: 0.25,
            iterations: 1,
            train_seconds: 1.0,
            num_gaussians: 2,
            model_bytes: 3,
            filter_bytes: 4,
            background: [1.0; 3],
            trained_background: None,
            quantized_8bit: false,
            frame_stride: 1,
            lpips_net: "alex".into(),
            scales: vec![ScaleResult::new(4.0, (8, 8), 30.0, 0.9)],
            skipped_scales: Vec::new(),
            extra_metrics: BTreeMap::new(),
        };
        assert_eq!(r.name(), "eval");
        let v: serde_json::Value =
            serde_json::from_slice(&serde_json::to_vec(&r).expect("json")).expect("value");
        let mut got: Vec<&str> = v
            .as_object()
            .expect("object")
            .keys()
            .map(String::as_str)
            .collect();
        let mut want = vec![
            "model",
            "filter",
            "train_scale",
            "iterations",
            "train_seconds",
            "num_gaussians",
            "model_bytes",
            "filter_bytes",
            "background",
            "quantized_8bit",
            "scales",
        ];
        want.sort_unstable();
        got.sort_unstable();
        assert_eq!(got, want);
        for k in [
            "lpips",
            "lpips_note",
            "warp_error",
            "w_ssim",
            "w_lpips",
            "flow",
        ] {
            assert!(v["scales"][0][k].is_null(), "{k}");
        }
        // VGG's LPIPS is named; a file without the field reads as AlexNet's.
        let vgg = EvalReport {
            lpips_net: "vgg".into(),
            ..r.clone()
        };
        let text = serde_json::to_string(&vgg).expect("json");
        assert!(text.contains(r#""lpips_net":"vgg""#), "{text}");
        let back: EvalReport = serde_json::from_str(&text).expect("reads back");
        assert_eq!(back, vgg);
        let old: EvalReport =
            serde_json::from_str(&serde_json::to_string(&r).expect("json")).expect("reads");
        assert_eq!(old.lpips_net, "alex");
        // On another background than the run's: the training one is recorded and the
        // outputs are named after the evaluation's.
        let moved = EvalReport {
            background: [0.0; 3],
            trained_background: Some([1.0; 3]),
            ..r.clone()
        };
        assert_eq!(moved.name(), "eval-on-black");
        let text = serde_json::to_string(&moved).expect("json");
        assert!(
            text.contains(r#""trained_background":[1.0,1.0,1.0]"#),
            "{text}"
        );
        let back: EvalReport = serde_json::from_str(&text).expect("reads back");
        assert_eq!(back, moved);
    }

    #[test]
    fn extra_metrics_are_written_only_when_there_are_some_and_read_back() {
        let mut scale = ScaleResult::new(1.0, (8, 8), 30.0, 0.9);
        let plain = serde_json::to_string(&scale).expect("json");
        assert!(!plain.contains("extra"), "{plain}");
        scale.extra.insert("mae".into(), 0.25);
        let text = serde_json::to_string(&scale).expect("json");
        assert!(text.contains(r#""extra":{"mae":0.25}"#), "{text}");
        let back: ScaleResult = serde_json::from_str(&text).expect("reads back");
        assert_eq!(back, scale);
        let info = ExtraMetric {
            higher_is_better: false,
        };
        let text = serde_json::to_string(&info).expect("json");
        assert_eq!(text, r#"{"higher_is_better":false}"#);
        assert!(serde_json::from_str::<ExtraMetric>(r#"{"higher":true}"#).is_err());
    }

    #[test]
    fn an_eval_json_from_before_the_temporal_fields_still_reads() {
        let old = r#"{"scale":1.0,"width":8,"height":8,"psnr":30.0,"ssim":0.9,
                      "lpips":null,"warp_error":null}"#;
        let s: ScaleResult = serde_json::from_str(old).expect("old entry");
        assert_eq!(s, ScaleResult::new(1.0, (8, 8), 30.0, 0.9));
    }
}
