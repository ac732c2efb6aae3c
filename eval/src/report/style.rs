//! How a run looks in every chart: one palette with a fixed colour per method (the
//! filter, and for the motion filter its estimator), so a method has the same colour
//! in every report; a marker shape per run and a dashed line for a run whose colour an
//! earlier run already has, so curves that coincide stay visible; and the legend,
//! drawn in a strip below the plots so it never covers data or stretches an axis.

use plotters::element::{DashedPathElement, DynElement, IntoDynElement};
use plotters::prelude::*;

use super::ReportRun;
use super::charts::{Area, e2s, text};

/// The method of a run as charts colour it: `none`, `mip3d`, `motion` (the KDE
/// estimator), `window_max` (the motion filter with the window-max estimator), or
/// another filter's name.
pub fn method(run: &ReportRun) -> String {
    if run.eval.filter != "motion" {
        return run.eval.filter.clone();
    }
    match run.analysis.as_ref().map(|a| a.estimator.as_str()) {
        Some("window_max") => "window_max".into(),
        _ => "motion".into(),
    }
}

/// Colours of methods outside the four named ones (Tableau 10 without the four).
const OTHERS: [RGBColor; 6] = [
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The colour of `method` (see [`method`]), the same in every chart and report: no
/// filter blue, Mip orange, motion (KDE) red, window max green (Tableau 10,
/// colour-blind-safe); any other name a fixed pick of the rest by its bytes.
pub fn method_colour(method: &str) -> RGBColor {
    match method {
        "none" => RGBColor(31, 119, 180),
        "mip3d" => RGBColor(255, 127, 14),
        "motion" => RGBColor(214, 39, 40),
        "window_max" => RGBColor(44, 160, 44),
        other => {
            let sum = other.bytes().map(usize::from).sum::<usize>();
            OTHERS[sum % OTHERS.len()]
        }
    }
}

/// A point marker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Marker {
    /// Filled disc.
    Disc,
    /// Filled triangle.
    Triangle,
    /// Diagonal cross.
    Cross,
    /// Ring (hollow disc).
    Ring,
}

const MARKERS: [Marker; 4] = [Marker::Disc, Marker::Triangle, Marker::Cross, Marker::Ring];

/// The look of one run's series.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeriesStyle {
    /// Its method's colour.
    pub colour: RGBColor,
    /// Its marker (by the run's position in the report).
    pub marker: Marker,
    /// Dashed when an earlier run has the same colour.
    pub dashed: bool,
    /// Line width: later runs are drawn thinner on top, so a line under one that
    /// coincides with it still shows at its edges.
    pub width: u32,
    /// Marker size in pixels, smaller for later runs for the same reason.
    pub size: u32,
}

/// The style of `runs[i]`.
pub fn series_style(runs: &[ReportRun], i: usize) -> SeriesStyle {
    let colour = method_colour(&method(&runs[i]));
    SeriesStyle {
        colour,
        marker: MARKERS[i % MARKERS.len()],
        dashed: runs[..i]
            .iter()
            .any(|r| method_colour(&method(r)) == colour),
        width: 7u32.saturating_sub(2 * i as u32).max(2),
        size: 9u32.saturating_sub(2 * i as u32).max(4),
    }
}

/// The marker of `style` at `at` (chart or pixel coordinates).
pub fn marker<DB: DrawingBackend, C: Clone + 'static>(
    at: C,
    style: SeriesStyle,
) -> DynElement<'static, DB, C> {
    let (c, r) = (style.colour, style.size);
    match style.marker {
        Marker::Disc => Circle::new(at, r, c.filled()).into_dyn(),
        Marker::Triangle => TriangleMarker::new(at, r + 2, c.filled()).into_dyn(),
        Marker::Cross => Cross::new(at, r, c.stroke_width(3)).into_dyn(),
        Marker::Ring => Circle::new(at, r, c.stroke_width(2)).into_dyn(),
    }
}

/// The line of `style` through `points` (chart or pixel coordinates).
pub fn line<DB: DrawingBackend, C: Clone + 'static>(
    points: Vec<C>,
    style: SeriesStyle,
) -> DynElement<'static, DB, C> {
    let stroke = style.colour.stroke_width(style.width);
    if style.dashed {
        DashedPathElement::new(points, 10, 6, stroke).into_dyn()
    } else {
        PathElement::new(points, stroke).into_dyn()
    }
}

/// Height of the legend strip for `entries` labels laid out in `columns`.
fn strip_height(entries: usize, columns: usize) -> u32 {
    24 * entries.div_ceil(columns) as u32 + 12
}

/// Draws the legend of `runs` (each run's line, marker and label) in a strip at the
/// bottom of `root` and returns the area above it for the plots.
pub fn with_legend<'a>(root: &Area<'a>, runs: &[ReportRun]) -> Result<Area<'a>, String> {
    let (width, height) = root.dim_in_pixel();
    let columns = ((width / 420) as usize).clamp(1, 3);
    let strip = strip_height(runs.len(), columns);
    let (plots, legend) = root.split_vertically(height.saturating_sub(strip));
    let cell = (width / columns as u32) as i32;
    for (i, r) in runs.iter().enumerate() {
        let style = series_style(runs, i);
        let x = 20 + cell * (i % columns) as i32;
        let y = 12 + 24 * (i / columns) as i32;
        legend
            .draw(&line(vec![(x, y), (x + 36, y)], style))
            .map_err(e2s)?;
        legend.draw(&marker((x + 18, y), style)).map_err(e2s)?;
        legend
            .draw(&Text::new(r.label.clone(), (x + 46, y - 8), text(15)))
            .map_err(e2s)?;
    }
    Ok(plots)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(model: &str, filter: &str) -> ReportRun {
        ReportRun::for_test(&format!("{model} {filter}"), model, filter, Vec::new())
    }

    #[test]
    fn a_method_keeps_its_colour_whatever_the_other_runs() {
        let three = [
            run("saro", "motion"),
            run("saro", "none"),
            run("saro", "mip3d"),
        ];
        let alone = [run("deform", "none")];
        assert_eq!(
            series_style(&three, 1).colour,
            series_style(&alone, 0).colour
        );
        let colours: Vec<_> = (0..3).map(|i| series_style(&three, i).colour).collect();
        assert!(colours[0] != colours[1] && colours[1] != colours[2] && colours[0] != colours[2]);
        let mut window = run("saro", "motion");
        window.analysis = Some(maaf_filter::AnalysisExport {
            estimator: "window_max".into(),
            ..Default::default()
        });
        assert_eq!(method(&window), "window_max");
        assert_ne!(method_colour("window_max"), colours[0]);
        // Two runs of one method: same colour, told apart by dash and marker.
        let shared = [run("saro", "none"), run("deform", "none")];
        let (a, b) = (series_style(&shared, 0), series_style(&shared, 1));
        assert_eq!(a.colour, b.colour);
        assert!(!a.dashed && b.dashed && a.marker != b.marker, "{a:?} {b:?}");
    }
}
