//! The nu(t) chart of a motion-filter run (the paper's Fig. 3): the observed sampling
//! rates of a static and of the most moving Gaussian over time, with the nu(t) of both
//! estimators and the static nu.

use std::path::Path;

use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::ReportRun;
use super::charts::{Chart, draw_legend, e2s, new_chart, padded_range, save_chart, text, widen};
use super::style::{method, method_colour};
use crate::Error;

/// The paper's f/d-over-time figure (its Fig. 3): for each exported Gaussian (one
/// that does not move and the one whose drawn centre moves most), its observed
/// sampling rates f/d over time (dots), the nu(t) the run's filter uses (solid), the
/// other estimator's nu(t) from the same observations (dashed) and Mip-Splatting's
/// static nu (dotted), one panel each.
pub fn nu_over_time(run: &ReportRun, path: &Path) -> Result<(), Error> {
    let Some(export) = &run.analysis else {
        return Err(Error::Input(format!(
            "{}: no nu(t) export for the chart",
            run.dir.display()
        )));
    };
    let traces = &export.gaussians;
    if traces.is_empty() {
        return Err(Error::Input(format!(
            "{}: the nu(t) export holds no Gaussian",
            run.dir.display()
        )));
    }
    let points = |v: &[[f32; 2]]| -> Vec<(f64, f64)> {
        v.iter()
            .map(|o| (f64::from(o[0]), f64::from(o[1])))
            .collect()
    };
    let n = traces.len() as u32;
    save_chart(path, (650 * n, 560), |root| {
        let panels = root.split_evenly((1, traces.len()));
        for (g, area) in traces.iter().zip(panels.iter()) {
            let obs = points(&g.observations);
            let nu = points(&g.nu);
            let compared: Vec<(&str, Vec<(f64, f64)>)> = g
                .compared
                .iter()
                .map(|c| (c.estimator.as_str(), points(&c.nu)))
                .collect();
            let (x0, x1) = padded_range(obs.iter().chain(&nu).map(|p| p.0), 0.03);
            let ys = obs
                .iter()
                .chain(&nu)
                .chain(compared.iter().flat_map(|c| &c.1))
                .map(|p| p.1)
                .chain(g.static_nu.map(f64::from));
            let (y0, y1) = widen(padded_range(ys, 0.05), 0.0, 0.3);
            let y0 = y0.max(0.0);
            let title = match g.drawn_motion {
                Some(m) => format!(
                    "{} Gaussian (#{}): drawn centre moves {:.1} % of the camera extent",
                    capitalise(&g.label),
                    g.index,
                    100.0 * m
                ),
                None => format!("{} Gaussian (#{})", capitalise(&g.label), g.index),
            };
            let mut chart = new_chart(area, &title, 18, 80, (x0, x1), (y0, y1))?;
            chart
                .configure_mesh()
                .x_desc("time t")
                .y_desc("sampling rate f/d (px per unit)")
                .label_style(text(16))
                .axis_desc_style(text(17))
                .light_line_style(WHITE.mix(0.0))
                .x_labels(6)
                .y_labels(6)
                .y_label_formatter(&|y| format!("{y:.0}"))
                .draw()
                .map_err(e2s)?;
            let grey = RGBColor(110, 110, 110);
            chart
                .draw_series(
                    obs.iter()
                        .map(|&p| Circle::new(p, 3, grey.mix(0.6).filled())),
                )
                .map_err(e2s)?
                .label("observed f/d (training views)")
                .legend(move |(x, y)| Circle::new((x + 12, y), 4, grey.filled()));
            if let Some(v) = g.static_nu {
                let v = f64::from(v);
                draw_dashed(
                    &mut chart,
                    vec![(x0, v), (x1, v)],
                    3,
                    RGBColor(30, 30, 30).stroke_width(2),
                    "static nu (Mip-Splatting, mip3d)".into(),
                )?;
            }
            for (estimator, curve) in compared {
                draw_dashed(
                    &mut chart,
                    curve,
                    10,
                    estimator_colour(estimator).stroke_width(3),
                    format!("nu(t), {}", estimator_label(estimator)),
                )?;
            }
            let own = method_colour(&method(run));
            chart
                .draw_series(LineSeries::new(nu, own.stroke_width(3)))
                .map_err(e2s)?
                .label(format!(
                    "nu(t), {}: the run's filter",
                    estimator_label(&export.estimator)
                ))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], own.stroke_width(3))
                });
            draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        }
        Ok(())
    })
}

/// Draws `points` as a dashed line (`dash` px on, 6 px off) with a legend entry
/// drawn the same way.
fn draw_dashed(
    chart: &mut Chart<'_, '_>,
    points: Vec<(f64, f64)>,
    dash: u32,
    style: ShapeStyle,
    label: String,
) -> Result<(), String> {
    chart
        .draw_series(DashedLineSeries::new(points, dash, 6, style))
        .map_err(e2s)?
        .label(label)
        .legend(move |(x, y)| DashedPathElement::new(vec![(x, y), (x + 24, y)], dash, 6, style));
    Ok(())
}

/// The colour of the motion filter with estimator `name` ([`method_colour`]).
fn estimator_colour(name: &str) -> RGBColor {
    match name {
        "kde" => method_colour("motion"),
        other => method_colour(other),
    }
}

/// A motion estimator's config name as the charts spell it.
fn estimator_label(name: &str) -> String {
    match name {
        "kde" => "KDE (paper)".into(),
        "window_max" => "window max (maaf's)".into(),
        other => other.into(),
    }
}

/// `s` with its first letter in upper case.
fn capitalise(s: &str) -> String {
    let mut c = s.chars();
    match c.next() {
        Some(f) => f.to_uppercase().collect::<String>() + c.as_str(),
        None => String::new(),
    }
}
