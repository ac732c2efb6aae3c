//! The suite's speed-against-accuracy chart (`OUT/speed_quality.png`): each method's
//! mean PSNR at 1x and at 4x against its mean training wall time, one labelled point
//! per method, beside the released code's rows that publish a GPU time.

use std::path::Path;

use plotters::prelude::*;

use super::{SuiteSummary, at_scale, cell_at};
use crate::Error;
use crate::report::charts::{Area, draw_axes, e2s, new_chart, padded_range, save_chart, text};
use crate::report::style::method_colour;

/// One point of a panel: training minutes, PSNR, label, colour, published or not.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Point {
    pub minutes: f64,
    pub psnr: f64,
    pub label: String,
    pub colour: RGBColor,
    pub published: bool,
}

/// The points at `scale`: every method whose average has that scale (its colour the
/// filter's, [`method_colour`]; its label the method and its scene count), then the
/// released rows with a published time and a figure at that scale.
pub(super) fn points(summary: &SuiteSummary, scale: f64) -> Vec<Point> {
    let measured = summary.methods.iter().filter_map(|m| {
        let avg = m.average.as_ref()?;
        let cell = cell_at(&avg.scales, scale)?;
        Some(Point {
            minutes: avg.train_seconds / 60.0,
            psnr: cell.psnr,
            label: format!("{} ({} scenes)", m.method, avg.scenes),
            colour: method_colour(&m.filter),
            published: false,
        })
    });
    let published = summary.released.iter().filter_map(|row| {
        let s = at_scale(&row.scales, scale, |p| p.scale)?;
        Some(Point {
            minutes: row.train_minutes?,
            psnr: s.psnr,
            label: format!("{} ({} scenes, GPU)", row.method, row.scenes),
            colour: RGBColor(90, 90, 90),
            published: true,
        })
    });
    measured.chain(published).collect()
}

/// Draws the chart: a panel for 1x and one for 4x, measured methods as discs and the
/// published rows as crosses, each labelled beside its marker.
pub(super) fn speed_quality(summary: &SuiteSummary, path: &Path) -> Result<(), Error> {
    save_chart(path, (1400, 620), |root| {
        let panels = root.split_evenly((1, 2));
        for (area, scale) in panels.iter().zip([1.0, 4.0]) {
            panel(area, &points(summary, scale), scale)?;
        }
        Ok(())
    })
}

/// One panel: `points` over training minutes from 0 and over their PSNR range.
fn panel(area: &Area<'_>, points: &[Point], scale: f64) -> Result<(), String> {
    // From 0 to 1.8x the longest time: room on the right for the labels.
    let longest = points.iter().map(|p| p.minutes).fold(1.0, f64::max);
    let (y0, y1) = padded_range(points.iter().map(|p| p.psnr), 0.2);
    let title = format!("Mean PSNR at {scale}x against training time");
    let mut chart = new_chart(area, &title, 22, 70, (0.0, 1.8 * longest), (y0, y1))?;
    draw_axes(
        &mut chart,
        "mean training wall time (min)",
        &format!("mean PSNR at {scale}x (dB)"),
    )?;
    for p in points {
        let at = (p.minutes, p.psnr);
        if p.published {
            chart
                .draw_series(std::iter::once(Cross::new(at, 7, p.colour.stroke_width(3))))
                .map_err(e2s)?;
        } else {
            chart
                .draw_series(std::iter::once(Circle::new(at, 7, p.colour.filled())))
                .map_err(e2s)?;
        }
        let label = EmptyElement::at(at) + Text::new(p.label.clone(), (10, -18), text(14));
        chart.draw_series(std::iter::once(label)).map_err(e2s)?;
    }
    Ok(())
}
