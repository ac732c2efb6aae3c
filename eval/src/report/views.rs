//! The report's pictures: for one test view at each evaluated scale, the ground
//! truth, every run's render and its error map (copied from `RUN/eval/<scale>x/`,
//! where `maaf eval` saved them, into `OUT/views/<scale>x/`, those below 1x enlarged
//! back to the 1x size without interpolation), and the colour bar that says what error
//! each colour of the maps means.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::charts::{e2s, save_chart, text};
use super::zoom::{copy_enlarged, enlargement};
use super::{ReportRun, scale_header};
use crate::Error;
use crate::images::{ERROR_MAP_MAX, ramp};
use crate::scale_label;

/// The colour bar of the error maps, in the report folder.
pub const COLOUR_BAR: &str = "error_colour_bar.png";

/// How to read the pictures (the report's text above them).
const HOW_TO_READ: &str = "Each table is one test view at one render scale: the ground \
truth, then each run's render, and below each render its error map. The error map is the \
per-pixel absolute error |render - ground truth| averaged over R, G and B, coloured by \
the bar (left of the error maps): black is exact, purple and red are small errors, \
orange larger, and pale yellow is an error of {max} or more (the maps saturate there). \
The scale is fixed, so maps of different runs and scales compare directly: at zoom-out \
(below 1x) aliasing shows as bright speckle and edges on fine detail, at zoom-in (above \
1x) too-thin Gaussians show as bright cracks and dilation as halos around edges.";

/// The `render_NNN.png` view indices saved in `dir`.
fn saved_views(dir: &Path) -> Vec<usize> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<usize> = entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.strip_prefix("render_")?
                .strip_suffix(".png")?
                .parse()
                .ok()
        })
        .filter(|i| dir.join(format!("error_{i:03}.png")).is_file())
        .collect();
    v.sort_unstable();
    v
}

/// The smallest view index every run evaluated at `s` saved images of, with the
/// runs' eval folders at that scale (`None` for a run not evaluated there).
fn common_view(runs: &[ReportRun], s: f64) -> Option<(usize, Vec<Option<PathBuf>>)> {
    let dirs: Vec<Option<PathBuf>> = runs
        .iter()
        .map(|r| {
            r.at_scale(s)
                .map(|_| r.dir.join("eval").join(scale_label(s)))
        })
        .collect();
    let saved: Vec<Vec<usize>> = dirs.iter().flatten().map(|d| saved_views(d)).collect();
    let first = saved.first()?;
    let view = first
        .iter()
        .copied()
        .find(|i| saved.iter().all(|v| v.contains(i)))?;
    Some((view, dirs))
}

/// Writes the pictures of every scale in `scales` under `OUT/views/` and the colour
/// bar, and returns the markdown that shows them; empty (nothing written) when no
/// run saved images.
pub fn view_section(runs: &[ReportRun], scales: &[f64], out: &Path) -> Result<String, Error> {
    let mut md = String::new();
    for &s in scales {
        let Some((view, dirs)) = common_view(runs, s) else {
            continue;
        };
        let rel = format!("views/{}", scale_label(s));
        let folder = out.join(&rel);
        std::fs::create_dir_all(&folder).map_err(|e| Error::io(&folder, e))?;
        let gt_name = format!("gt_{view:03}.png");
        let gt = dirs
            .iter()
            .flatten()
            .map(|d| d.join(&gt_name))
            .find(|p| p.is_file());
        let factor = enlargement(s);
        let enlarged = if factor > 1 {
            format!(", enlarged {factor}x without interpolation")
        } else {
            String::new()
        };
        let _ = writeln!(md, "### {} (test view {view}{enlarged})\n", scale_header(s));
        let mut head = String::from("| ground truth |");
        let mut sep = String::from("|---|");
        let mut renders = match &gt {
            Some(p) => {
                copy_enlarged(p, &folder.join(&gt_name), factor)?;
                format!("| ![ground truth]({rel}/{gt_name}) |")
            }
            None => "| not saved (evaluated before ground truth was saved; re-run `maaf eval`) |"
                .to_string(),
        };
        let mut errors = format!("| ![error colour bar]({COLOUR_BAR}) |");
        for (k, (r, dir)) in runs.iter().zip(&dirs).enumerate() {
            let _ = write!(head, " {} |", r.label);
            sep.push_str("---|");
            let Some(dir) = dir else {
                renders.push_str(" not evaluated at this scale |");
                errors.push_str(" - |");
                continue;
            };
            for (kind, cells) in [("render", &mut renders), ("error", &mut errors)] {
                let name = format!("run{k:02}_{kind}_{view:03}.png");
                copy_enlarged(
                    &dir.join(format!("{kind}_{view:03}.png")),
                    &folder.join(&name),
                    factor,
                )?;
                let _ = write!(cells, " ![{kind} of {}]({rel}/{name}) |", r.label);
            }
        }
        let _ = writeln!(md, "{head}\n{sep}\n{renders}\n{errors}\n");
    }
    if md.is_empty() {
        return Ok(md);
    }
    colour_bar(&out.join(COLOUR_BAR))?;
    let how = HOW_TO_READ.replace("{max}", &format!("{ERROR_MAP_MAX}"));
    Ok(format!("{how}\n\n{md}"))
}

/// Draws the error maps' colour ramp from 0 to [`ERROR_MAP_MAX`] with its values.
pub fn colour_bar(path: &Path) -> Result<(), Error> {
    let max = f64::from(ERROR_MAP_MAX);
    save_chart(path, (420, 130), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption("error map colours", text(16))
            .margin(14)
            .margin_right(40)
            .x_label_area_size(55)
            .build_cartesian_2d(0.0..max, 0.0..1.0)
            .map_err(e2s)?;
        chart
            .configure_mesh()
            .disable_y_axis()
            .disable_mesh()
            .x_labels(6)
            .x_label_formatter(&|x| {
                if (x - max).abs() < 1e-9 {
                    format!(">={x:.2}")
                } else {
                    format!("{x:.2}")
                }
            })
            .x_desc("mean |render - truth| per pixel")
            .label_style(text(13))
            .axis_desc_style(text(13))
            .draw()
            .map_err(e2s)?;
        let steps = 200;
        chart
            .draw_series((0..steps).map(|i| {
                let (a, b) = (i as f64 / steps as f64, (i + 1) as f64 / steps as f64);
                let [r, g, bl] = ramp(((a + b) / 2.0) as f32);
                Rectangle::new(
                    [(a * max, 0.0), (b * max, 1.0)],
                    RGBColor(r, g, bl).filled(),
                )
            }))
            .map_err(e2s)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_view_shown_is_one_every_run_saved() {
        let root = std::env::temp_dir().join(format!("maaf-views-{}", std::process::id()));
        let (a, b) = (root.join("a/eval/1x"), root.join("b/eval/1x"));
        for (dir, views) in [(&a, [0, 3]), (&b, [3, 5])] {
            std::fs::create_dir_all(dir).expect("dir");
            for v in views {
                for kind in ["render", "error"] {
                    std::fs::write(dir.join(format!("{kind}_{v:03}.png")), b"png").expect("w");
                }
            }
        }
        std::fs::write(a.join("gt_003.png"), b"gt").expect("gt");
        let scale = crate::ScaleResult::new(1.0, (8, 6), 20.0, 0.5);
        let mut runs = vec![
            ReportRun::for_test("A", "saro", "none", vec![scale.clone()]),
            ReportRun::for_test("B", "saro", "motion", vec![scale]),
        ];
        runs[0].dir = root.join("a");
        runs[1].dir = root.join("b");
        let out = root.join("report");
        let md = view_section(&runs, &[1.0], &out).expect("section");
        assert!(md.contains("### 1x (test view 3)"), "{md}");
        assert!(md.contains("views/1x/gt_003.png") && md.contains("views/1x/run01_error_003.png"));
        assert_eq!(
            std::fs::read(out.join("views/1x/run00_render_003.png")).expect("copied"),
            b"png"
        );
        assert!(out.join(COLOUR_BAR).is_file());
        let _ = std::fs::remove_dir_all(&root);
    }
}
