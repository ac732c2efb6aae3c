//! `maaf report`: a markdown comparison of evaluated runs shaped like the paper's
//! Tab. 2 (PSNR / SSIM per scale and their average, one row per run; zoom-in and
//! zoom-out tables) plus PNG charts drawn with plotters and an embedded font:
//! quality vs scale, quality vs training time (and the validation PSNR logged during
//! training as curves), quality vs model size, and nu(t) of a
//! static and a moving Gaussian (the paper's f/d-over-time figure); and, beside the
//! tables, the ground truth, each run's render and its error map (with a colour bar)
//! of one test view at every evaluated scale ([`views`]). Each method keeps one colour
//! in every chart ([`style`]).
//!
//! Inputs are run directories holding `eval.json` (from [`crate::evaluate_run`])
//! and, for motion-filter runs, `eval/filter_analysis.json`. No data set is needed.

pub mod charts;
pub mod curves;
pub mod extra;
mod gap;
mod nu_chart;
pub mod published;
pub mod regions;
pub mod rings;
pub mod style;
pub mod suite;
mod tables;
pub mod temporal;
pub mod views;
pub mod zoom;

pub use tables::{all_scales, cost_table, metrics_table, scale_header};

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use maaf_filter::AnalysisExport;

use crate::{Error, write_atomic};
use crate::{EvalReport, FILTER_ANALYSIS_FILE, trim_float};

/// The display name of an `eval.json` `lpips_net` (`alex` -> `AlexNet`, `vgg` ->
/// `VGG16`, [`maaf_lpips::Net::label`]); an unknown name as written.
pub(crate) fn lpips_label(name: &str) -> &str {
    match name.parse::<maaf_lpips::Net>() {
        Ok(net) => net.label(),
        Err(_) => name,
    }
}

/// One evaluated run as the report shows it.
#[derive(Clone, Debug)]
pub struct ReportRun {
    /// Row label (the filter, disambiguated by the run folder when repeated).
    pub label: String,
    /// Run directory.
    pub dir: PathBuf,
    /// Its `eval.json`.
    pub eval: EvalReport,
    /// nu(t) traces of a static and a moving Gaussian (motion-filter runs).
    pub analysis: Option<AnalysisExport>,
}

impl ReportRun {
    /// Its evaluation at render scale `s`, if it was evaluated there.
    pub fn at_scale(&self, s: f64) -> Option<&crate::ScaleResult> {
        self.eval.scales.iter().find(|x| (x.scale - s).abs() < 1e-9)
    }

    /// A run of `model` and `filter` with `scales` and placeholder sizes (report tests).
    #[cfg(test)]
    pub(crate) fn for_test(
        label: &str,
        model: &str,
        filter: &str,
        scales: Vec<crate::ScaleResult>,
    ) -> Self {
        ReportRun {
            label: label.into(),
            dir: label.into(),
            eval: EvalReport {
                model: model.into(),
                filter: filter.into(),
                train_scale: 0.25,
                iterations: 10,
                train_seconds: 1.0,
                num_gaussians: 5,
                model_bytes: 1,
                filter_bytes: 1,
                background: [1.0; 3],
                trained_background: None,
                quantized_8bit: false,
                frame_stride: 1,
                lpips_net: "alex".into(),
                scales,
                skipped_scales: Vec::new(),
                extra_metrics: Default::default(),
            },
            analysis: None,
        }
    }
}

/// What [`write_report`] produced.
#[derive(Clone, Debug)]
pub struct ReportOutput {
    /// `OUT/report.md`.
    pub markdown: PathBuf,
    /// PSNR and SSIM at every evaluated scale (markdown), for printing: zoom-out and
    /// zoom-in in one table, so nothing the runs were evaluated at is left out.
    pub table: String,
    /// The per-image metrics of one's own at every evaluated scale (markdown,
    /// [`extra::extra_table`]), for printing; empty when no run has one.
    pub extra: String,
    /// Chart PNGs written.
    pub charts: Vec<PathBuf>,
}

/// Human label of a filter name, as in the paper's tables.
pub fn filter_label(filter: &str) -> &str {
    match filter {
        "none" => "no 3D filter",
        "mip3d" => "+ static 3D filter (Mip)",
        "motion" => "+ motion-aware filter",
        other => other,
    }
}

/// Reads `eval.json` (and the nu(t) export when present) of every run. Labels are
/// `<model> <filter label>`; a label used twice gets the run folder's name appended.
pub fn load_runs(runs: &[PathBuf]) -> Result<Vec<ReportRun>, Error> {
    if runs.is_empty() {
        return Err(Error::Input("no run given (--runs RUN...)".into()));
    }
    let mut out = Vec::with_capacity(runs.len());
    for dir in runs {
        if !dir.join("eval.json").is_file() {
            return Err(Error::Input(format!(
                "{}: no eval.json (run `maaf eval --run {}` first)",
                dir.display(),
                dir.display()
            )));
        }
        let eval = EvalReport::read(dir)?;
        let path = dir.join("eval").join(FILTER_ANALYSIS_FILE);
        let analysis = if path.is_file() {
            let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
            Some(serde_json::from_str(&text).map_err(|e| {
                Error::Input(format!("{}: not a filter analysis: {e}", path.display()))
            })?)
        } else {
            None
        };
        out.push(ReportRun {
            label: format!("{} {}", eval.model, filter_label(&eval.filter)),
            dir: dir.clone(),
            eval,
            analysis,
        });
    }
    let labels: Vec<String> = out.iter().map(|r| r.label.clone()).collect();
    for r in &mut out {
        if labels.iter().filter(|l| **l == r.label).count() > 1 {
            let name = r
                .dir
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| r.dir.display().to_string());
            r.label = format!("{} ({name})", r.label);
        }
    }
    Ok(out)
}

/// Writes `OUT/report.md` and the charts (`quality_vs_scale.png`,
/// `quality_vs_time.png`, `quality_vs_size.png`, `quality_by_region.png` when a run
/// has PSNR by region, `warp_error_over_time.png` when a
/// run has temporal metrics, and `nu_t.png` when a motion run has a nu(t) export),
/// the pictures of one test view per scale (`views/<scale>x/`, `error_colour_bar.png`)
/// when the runs saved images,
/// the LPIPS table, the table of the per-image metrics of one's own
/// ([`extra::extra_table`]) and the Tab. 3-shaped temporal tables for the evaluated
/// runs in `runs`. Every file is written atomically; `OUT` is created if needed.
pub fn write_report(runs: &[PathBuf], out: &Path) -> Result<ReportOutput, Error> {
    let runs = load_runs(runs)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let scales = all_scales(&runs);
    let zoom_in: Vec<f64> = scales.iter().copied().filter(|&s| s >= 1.0).collect();
    let mut zoom_out: Vec<f64> = scales.iter().copied().filter(|&s| s <= 1.0).collect();
    zoom_out.reverse();

    let mut charts = Vec::new();
    let mut chart_notes = Vec::new();
    let scale_png = out.join("quality_vs_scale.png");
    charts::quality_vs_scale(&runs, &scale_png)?;
    charts.push(scale_png);
    let time_png = out.join("quality_vs_time.png");
    charts::quality_vs_time(&runs, &time_png)?;
    charts.push(time_png);
    let val_png = out.join("val_psnr_vs_time.png");
    if curves::validation_psnr_vs_time(&runs, &val_png)? {
        charts.push(val_png);
    }
    let size_png = out.join("quality_vs_size.png");
    charts::quality_vs_size(&runs, &size_png)?;
    charts.push(size_png);
    if runs
        .iter()
        .any(|r| r.eval.scales.iter().any(|s| s.regions.is_some()))
    {
        let region_png = out.join("quality_by_region.png");
        charts::quality_by_region(&runs, &region_png)?;
        charts.push(region_png);
    }
    let warp_png = out.join("warp_error_over_time.png");
    if temporal::warp_error_over_time(&runs, &warp_png)? {
        charts.push(warp_png);
    }
    match runs.iter().find(|r| r.analysis.is_some()) {
        Some(r) => {
            let nu_png = out.join("nu_t.png");
            nu_chart::nu_over_time(r, &nu_png)?;
            charts.push(nu_png);
        }
        None => chart_notes.push(
            "No motion-filter run with `eval/filter_analysis.json`: no nu(t) chart.".to_string(),
        ),
    }

    let main_scales: Vec<f64> = if zoom_in.len() > 1 {
        zoom_in.clone()
    } else {
        scales.clone()
    };
    let main_table = metrics_table(&runs, &main_scales);
    let mut md = String::from("# maaf evaluation report\n\n");
    let mut train_scales: Vec<String> = runs
        .iter()
        .map(|r| trim_float(r.eval.train_scale))
        .collect();
    train_scales.dedup();
    let _ = writeln!(
        md,
        "Runs: {}. Scales are relative to the training scale ({}); PSNR is the mean of \
         per-image values on float renders (8-bit quantisation: {}), SSIM uses an 11x11 \
         Gaussian window (sigma 1.5).\n",
        runs.len(),
        train_scales.join(", "),
        if runs.iter().any(|r| r.eval.quantized_8bit) {
            "yes"
        } else {
            "no"
        }
    );
    if zoom_in.len() > 1 {
        md.push_str("## Zoom-in (rendered above the training resolution)\n\n");
    } else {
        md.push_str("## All scales\n\n");
    }
    md.push_str(&main_table);
    if zoom_out.len() > 1 {
        md.push_str("\n## Zoom-out (rendered below the training resolution)\n\n");
        md.push_str(&metrics_table(&runs, &zoom_out));
    }
    let table = metrics_table(&runs, &scales);
    if zoom_in.len() > 1 && zoom_out.len() > 1 {
        md.push_str("\n## All scales\n\n");
        md.push_str(&table);
    }
    let pictures = views::view_section(&runs, &scales, out)?;
    if !pictures.is_empty() {
        md.push_str("\n## Renders and error maps\n\n");
        md.push_str(&pictures);
    }
    if zoom::zoom_figure(&runs, &scales, out)?.is_some() {
        let names: Vec<&str> = runs.iter().map(|r| r.label.as_str()).collect();
        let _ = writeln!(
            md,
            "\n## Zoomed out and in\n\nGround truth, then {} (left to right) on one test view: top at {} (enlarged without interpolation), bottom at {} (a centre crop). The README's figure is this file.\n\n![zoomed out and in]({})",
            names.join(", "),
            scales.first().map_or(String::new(), |s| scale_header(*s)),
            scales.last().map_or(String::new(), |s| scale_header(*s)),
            zoom::ZOOM_FIGURE
        );
    }
    let by_region = regions::region_table(&runs, &scales);
    if !by_region.is_empty() {
        md.push_str(
            "\n## PSNR by region (moving / static / silhouette band, dB; data with moving masks)\n\n",
        );
        md.push_str(&by_region);
    }
    let by_ring = rings::ring_section(&runs, &scales);
    if !by_ring.is_empty() {
        md.push_str(
            "\n## Where the gains lie: the error reduction by distance from the silhouette (data with alpha)\n\n\
             Each run against the first: the first run's squared error that the run removes, \
             split by the chessboard distance d of each pixel to the ground truth's \
             silhouette, as the paper's supplementary (`tab:supp_region`) splits its \
             zoom-out gain. ",
        );
        md.push_str(rings::NEAR_ZERO_NOTE);
        md.push_str("\n\n");
        md.push_str(&by_ring);
    }
    let _ = writeln!(
        md,
        "\n## LPIPS ({}, lin v0.1; lower is better)\n",
        temporal::lpips_nets(&runs)
    );
    md.push_str(&temporal::lpips_table(&runs, &scales));
    let extra = extra::extra_table(&runs, &scales);
    if !extra.is_empty() {
        md.push_str(
            "\n## Metrics of one's own (registered by the evaluating program; mean over views)\n\n",
        );
        md.push_str(&extra);
    }
    let tab3 = temporal::temporal_tables(&runs);
    if !tab3.is_empty() {
        md.push_str(
            "\n## Temporal stability (Tab. 3 layout; fixed-camera video, frame t+1 warped onto t)\n\n",
        );
        md.push_str(&tab3);
    }
    let pops = temporal::popping_table(&runs);
    if !pops.is_empty() {
        md.push_str(
            "\n## Popping (Gaussians whose visible weight halves or doubles within one frame step; mass = share of the frame's pixels)\n\n",
        );
        md.push_str(&pops);
    }
    md.push_str("\n## Cost\n\n");
    md.push_str(&cost_table(&runs));
    md.push_str("\n## Charts\n\n");
    for c in &charts {
        if let Some(name) = c.file_name() {
            let name = name.to_string_lossy();
            let _ = writeln!(md, "![{name}]({name})\n");
        }
    }
    for n in &chart_notes {
        let _ = writeln!(md, "{n}\n");
    }
    md.push_str("## Runs\n\n");
    for r in &runs {
        let _ = writeln!(md, "- {}: `{}`", r.label, r.dir.display());
    }
    let markdown = out.join("report.md");
    write_atomic(&markdown, md.as_bytes())?;
    Ok(ReportOutput {
        markdown,
        table,
        extra,
        charts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bold_marks_the_best_of_each_column_only() {
        let run = |label: &str, psnr: [f64; 2], ssim: [f64; 2]| {
            let cells = [0.25, 4.0]
                .iter()
                .zip(psnr.iter().zip(ssim))
                .map(|(&s, (&p, q))| crate::ScaleResult::new(s, (8, 8), p, q))
                .collect();
            ReportRun::for_test(label, "saro", label, cells)
        };
        let runs = [
            run("none", [16.0, 15.0], [0.5, 0.30]),
            run("mip3d", [28.0, 16.0], [0.8, 0.31]),
            run("motion", [28.0, 15.5], [0.7, 0.31]),
        ];
        let table = metrics_table(&runs, &[0.25, 4.0]);
        let line = |label: &str| {
            table
                .lines()
                .find(|l| l.starts_with(&format!("| {label} |")))
                .expect("row")
                .to_string()
        };
        assert_eq!(
            line("none"),
            "| none | 16.00 | 15.00 | 15.50 | 0.5000 | 0.3000 | 0.4000 |"
        );
        assert_eq!(
            line("mip3d"),
            "| mip3d | **28.00** | **16.00** | **22.00** | **0.8000** | **0.3100** | **0.5550** |"
        );
        assert_eq!(
            line("motion"),
            "| motion | **28.00** | 15.50 | 21.75 | 0.7000 | **0.3100** | 0.5050 |"
        );
    }

    #[test]
    fn headers() {
        assert_eq!(scale_header(0.25), "1/4x");
        assert_eq!(scale_header(0.5), "1/2x");
        assert_eq!(scale_header(1.0), "1x");
        assert_eq!(scale_header(4.0), "4x");
    }
}
