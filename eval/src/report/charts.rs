//! PNG charts of the report, drawn with plotters' bitmap backend and the vendored
//! DejaVu Sans font (no system font libraries): quality vs scale, quality vs
//! training time, quality vs model size (the nu(t) chart is `nu_chart.rs`), and the
//! chart helpers every report chart draws with.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use super::gap::{dodge, gap_panel};
use super::style::{SeriesStyle, line, marker, series_style, with_legend};
use super::{ReportRun, scale_header};
use crate::Error;
use crate::images::save_png;

/// DejaVu Sans (Bitstream Vera licence, see `eval/assets/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Font family name the charts use.
const FAMILY: &str = "sans-serif";

/// Registers the embedded font once per process.
fn ensure_font() -> Result<(), Error> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        register_font(FAMILY, FontStyle::Normal, FONT)
            .map_err(|_| "the embedded chart font is not a valid TTF".to_string())
    })
    .clone()
    .map_err(Error::Input)
}

fn plot_err(path: &Path) -> impl Fn(String) -> Error + '_ {
    move |e| Error::Input(format!("{}: drawing the chart failed: {e}", path.display()))
}

pub(super) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Draws a `width x height` chart with `draw` and writes it to `path` as PNG.
pub(super) fn save_chart(
    path: &Path,
    (width, height): (u32, u32),
    draw: impl FnOnce(&Area<'_>) -> Result<(), String>,
) -> Result<(), Error> {
    ensure_font()?;
    let mut buf = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE)
            .map_err(|e| plot_err(path)(e.to_string()))?;
        draw(&root).map_err(plot_err(path))?;
        root.present().map_err(|e| plot_err(path)(e.to_string()))?;
    }
    let img = image::RgbImage::from_raw(width, height, buf)
        .ok_or_else(|| Error::Input("chart buffer has the wrong size".into()))?;
    save_png(&img, path)
}

/// `(lo, hi)` of `values` padded by `pad` of the span (or a unit when flat).
pub(super) fn padded_range(values: impl Iterator<Item = f64>, pad: f64) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    if span < 1e-12 {
        let d = lo.abs() * 0.05 + 0.01;
        return (lo - d, hi + d);
    }
    (lo - pad * span, hi + pad * span)
}

/// Widens `(lo, hi)` by `below` and `above` times its span (room for a legend).
pub(super) fn widen((lo, hi): (f64, f64), below: f64, above: f64) -> (f64, f64) {
    let span = hi - lo;
    (lo - below * span, hi + above * span)
}

pub(super) fn text(size: u32) -> TextStyle<'static> {
    (FAMILY, size).into_font().color(&BLACK)
}

pub(super) fn e2s<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// The report's charts: f64 x and y axes on the bitmap backend.
pub(super) type Chart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart over `x0..x1` by `y0..y1` on `area` with a caption of `caption_size` px, a
/// 14 px margin, 55 px for the x labels and `y_label_area` px for the y labels.
pub(super) fn new_chart<'a, 'b>(
    area: &'a Area<'b>,
    caption: &str,
    caption_size: u32,
    y_label_area: u32,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Result<Chart<'a, 'b>, String> {
    ChartBuilder::on(area)
        .caption(caption, text(caption_size))
        .margin(14)
        .x_label_area_size(55)
        .y_label_area_size(y_label_area)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e2s)
}

/// Draws the axes of a scatter chart: six labels each, 16 px labels, 17 px
/// descriptions, no minor grid lines.
pub(super) fn draw_axes(
    chart: &mut Chart<'_, '_>,
    x_desc: &str,
    y_desc: &str,
) -> Result<(), String> {
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(text(16))
        .axis_desc_style(text(17))
        .light_line_style(WHITE.mix(0.0))
        .x_labels(6)
        .y_labels(6)
        .draw()
        .map_err(e2s)
}

/// Draws the series legend of `chart` at `position`: white at 85 % opacity, a black
/// border, 15 px labels.
pub(super) fn draw_legend<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    position: SeriesLabelPosition,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(text(15))
        .draw()
        .map_err(e2s)
}

/// PSNR, SSIM and the PSNR gap to the best run against the render scale (log2 axis),
/// one line per run (`gap.rs`: the third panel separates runs the first two
/// draw on top of each other).
pub fn quality_vs_scale(runs: &[ReportRun], path: &Path) -> Result<(), Error> {
    save_chart(path, (1950, 560), |root| {
        let panels = with_legend(root, runs)?.split_evenly((1, 3));
        scale_panel(
            &panels[0],
            runs,
            "PSNR (dB) vs render scale",
            "PSNR (dB)",
            1,
            &|s| Some(s.psnr),
        )?;
        scale_panel(&panels[1], runs, "SSIM vs render scale", "SSIM", 3, &|s| {
            Some(s.ssim)
        })?;
        gap_panel(&panels[2], runs)
    })
}

/// PSNR of the moving pixels, the static pixels and the silhouette band
/// ([`crate::metrics::regions`]) against the render scale, one line per run: what the
/// report's by-region table shows, for data with moving masks.
pub fn quality_by_region(runs: &[ReportRun], path: &Path) -> Result<(), Error> {
    type Pick = fn(&crate::RegionSummary) -> Option<f64>;
    let regions: [(&str, Pick); 3] = [
        ("moving pixels", |g| g.moving),
        ("static pixels", |g| g.static_),
        ("silhouette band", |g| g.band),
    ];
    save_chart(path, (1800, 560), |root| {
        let panels = with_legend(root, runs)?.split_evenly((1, 3));
        for (area, (name, pick)) in panels.iter().zip(regions) {
            let title = format!("PSNR of {name} vs render scale");
            scale_panel(area, runs, &title, "PSNR (dB)", 1, &|s| {
                s.regions.as_ref().and_then(pick)
            })?;
        }
        Ok(())
    })
}

/// One panel of a metric against the render scale (log2 axis, labelled at the
/// evaluated powers of two), a line per run over the scales where `metric` has a
/// value, each run's points dodged a little sideways, `decimals` on the y labels.
fn scale_panel(
    area: &Area<'_>,
    runs: &[ReportRun],
    title: &str,
    y_desc: &str,
    decimals: usize,
    metric: &dyn Fn(&crate::ScaleResult) -> Option<f64>,
) -> Result<(), String> {
    let scales = super::all_scales(runs);
    let keys: Vec<f64> = scales.iter().map(|s| s.log2()).collect();
    let (x0, x1) = padded_range(keys.iter().copied(), 0.08);
    let series: Vec<Vec<(f64, f64)>> = runs
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let x = |s: f64| s.log2() + dodge(i, runs.len());
            let mut pts: Vec<(f64, f64)> = r
                .eval
                .scales
                .iter()
                .filter_map(|s| metric(s).map(|v| (x(s.scale), v)))
                .collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            pts
        })
        .collect();
    let (y0, y1) = padded_range(series.iter().flatten().map(|p| p.1), 0.05);
    let mut chart = new_chart(area, title, 24, 70, (x0, x1), (y0, y1))?;
    draw_scale_axes(&mut chart, keys.len(), y_desc, decimals)?;
    for (i, pts) in series.iter().enumerate() {
        draw_run(&mut chart, pts, series_style(runs, i))?;
    }
    Ok(())
}

/// Draws one run's line through `pts` with its marker at each point.
pub(super) fn draw_run(
    chart: &mut Chart<'_, '_>,
    pts: &[(f64, f64)],
    style: SeriesStyle,
) -> Result<(), String> {
    chart
        .draw_series(std::iter::once(line(pts.to_vec(), style)))
        .map_err(e2s)?;
    chart
        .draw_series(pts.iter().map(|&q| marker(q, style)))
        .map_err(e2s)?;
    Ok(())
}

/// Draws the axes of a chart against the render scale: the log2 x axis labelled at
/// the `scales` evaluated powers of two only, `decimals` on the y labels.
pub(super) fn draw_scale_axes(
    chart: &mut Chart<'_, '_>,
    scales: usize,
    y_desc: &str,
    decimals: usize,
) -> Result<(), String> {
    chart
        .configure_mesh()
        .x_desc("render scale relative to training (log axis)")
        .y_desc(y_desc)
        .x_labels(scales.max(2))
        .x_label_formatter(&|x| {
            if (x - x.round()).abs() < 1e-6 {
                scale_header(2f64.powf(x.round()))
            } else {
                String::new()
            }
        })
        .y_label_formatter(&|y| {
            // Rounded first, so a label near zero never prints as "-0.00".
            let step = 10f64.powi(decimals as i32);
            format!("{:.decimals$}", (y * step).round() / step + 0.0)
        })
        .label_style(text(16))
        .axis_desc_style(text(17))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(e2s)
}

/// One scatter panel: a point per run at `(x(run), y(run))` (the legend is the
/// figure's strip).
fn scatter_panel(
    area: &Area<'_>,
    runs: &[ReportRun],
    title: &str,
    (x_desc, x): (&str, &dyn Fn(&ReportRun) -> f64),
    (y_desc, y): (&str, &dyn Fn(&ReportRun) -> f64),
) -> Result<(), String> {
    let (x0, x1) = padded_range(runs.iter().map(x), 0.15);
    let (y0, y1) = padded_range(runs.iter().map(y), 0.15);
    let x0 = if x0 < 0.0 && runs.iter().all(|r| x(r) >= 0.0) {
        0.0
    } else {
        x0
    };
    let mut chart = new_chart(area, title, 22, 70, (x0, x1), (y0, y1))?;
    draw_axes(&mut chart, x_desc, y_desc)?;
    chart
        .draw_series(
            (0..runs.len()).map(|i| marker((x(&runs[i]), y(&runs[i])), series_style(runs, i))),
        )
        .map_err(e2s)?;
    Ok(())
}

/// Mean PSNR (left) and mean SSIM (right) over the evaluated scales against the
/// training wall time: speed vs accuracy.
pub fn quality_vs_time(runs: &[ReportRun], path: &Path) -> Result<(), Error> {
    save_chart(path, (1300, 560), |root| {
        let panels = with_legend(root, runs)?.split_evenly((1, 2));
        let t = |r: &ReportRun| r.eval.train_seconds;
        let psnr = |r: &ReportRun| r.eval.mean_psnr();
        let ssim = |r: &ReportRun| r.eval.mean_ssim();
        scatter_panel(
            &panels[0],
            runs,
            "Mean PSNR over scales vs training time",
            ("training wall time (s)", &t),
            ("mean PSNR (dB)", &psnr),
        )?;
        scatter_panel(
            &panels[1],
            runs,
            "Mean SSIM over scales vs training time",
            ("training wall time (s)", &t),
            ("mean SSIM", &ssim),
        )
    })
}

/// Mean PSNR against the number of Gaussians (left) and against the bytes of the
/// model plus its filter state (right).
pub fn quality_vs_size(runs: &[ReportRun], path: &Path) -> Result<(), Error> {
    save_chart(path, (1300, 560), |root| {
        let panels = with_legend(root, runs)?.split_evenly((1, 2));
        let n = |r: &ReportRun| r.eval.num_gaussians as f64 / 1000.0;
        let mb = |r: &ReportRun| r.eval.total_bytes() as f64 / 1e6;
        let psnr = |r: &ReportRun| r.eval.mean_psnr();
        scatter_panel(
            &panels[0],
            runs,
            "Mean PSNR vs number of Gaussians",
            ("Gaussians (thousands)", &n),
            ("mean PSNR (dB)", &psnr),
        )?;
        scatter_panel(
            &panels[1],
            runs,
            "Mean PSNR vs size (model + filter state)",
            ("model + filter state (MB)", &mb),
            ("mean PSNR (dB)", &psnr),
        )
    })
}
