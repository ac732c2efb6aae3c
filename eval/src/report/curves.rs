//! Quality against training time as curves: the validation PSNR each run logged in
//! `RUN/log.csv` (`val_psnr`, every `val_every` iterations) against its
//! `elapsed_seconds`, one line per run, so a reader sees which configuration reaches a
//! given quality first.

use std::path::Path;

use plotters::prelude::*;

use super::ReportRun;
use super::charts::{draw_run, e2s, new_chart, padded_range, save_chart, text};
use super::style::{series_style, with_legend};
use crate::Error;

/// `(elapsed_seconds, val_psnr)` of every `log.csv` row of `run` that has a
/// validation value; empty when the log is missing or has no `val_psnr` column
/// (runs from before it existed).
pub fn validation_curve(run: &Path) -> Result<Vec<(f64, f64)>, Error> {
    maaf_scene::run_log::logged_pairs(&run.join("log.csv"), "elapsed_seconds", "val_psnr")
}

/// Draws the validation PSNR of every run against its training time into `path`;
/// returns false (and writes nothing) when no run logged a validation value.
pub fn validation_psnr_vs_time(runs: &[ReportRun], path: &Path) -> Result<bool, Error> {
    let curves: Vec<Vec<(f64, f64)>> = runs
        .iter()
        .map(|r| validation_curve(&r.dir))
        .collect::<Result<_, _>>()?;
    if curves.iter().all(Vec::is_empty) {
        return Ok(false);
    }
    let all = || curves.iter().flatten();
    let (x0, x1) = padded_range(all().map(|p| p.0), 0.03);
    let (y0, y1) = padded_range(all().map(|p| p.1), 0.08);
    save_chart(path, (900, 560), |root| {
        let plots = with_legend(root, runs)?;
        let mut chart = new_chart(
            &plots,
            "Validation PSNR during training",
            22,
            70,
            (x0.max(0.0), x1),
            (y0, y1),
        )?;
        chart
            .configure_mesh()
            .x_desc("training wall time (s)")
            .y_desc("validation PSNR (dB)")
            .label_style(text(16))
            .axis_desc_style(text(17))
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(e2s)?;
        for (i, curve) in curves.iter().enumerate() {
            draw_run(&mut chart, curve, series_style(runs, i))?;
        }
        Ok(())
    })?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_only_rows_with_a_validation_value_by_column_name() {
        let dir = std::env::temp_dir().join(format!("maaf-curves-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(
            dir.join("log.csv"),
            "iteration,l1,total,num_gaussians,elapsed_seconds,skipped_steps,val_psnr\n\
             100,0.1,0.1,10,1.5,0,\n\
             500,0.05,0.05,12,7.25,0,21.5\n\
             600,0.04,0.04,12,8.0,0,\n\
             1000,0.03,0.03,14,15.0,0,24.0\n",
        )
        .expect("write log");
        assert_eq!(
            validation_curve(&dir).expect("parse"),
            vec![(7.25, 21.5), (15.0, 24.0)]
        );
        std::fs::write(
            dir.join("log.csv"),
            "iteration,total,elapsed_seconds\n1,2,3\n",
        )
        .expect("write old log");
        assert!(validation_curve(&dir).expect("old log").is_empty());
        std::fs::write(
            dir.join("log.csv"),
            "iteration,elapsed_seconds,val_psnr\n5,abc,20\n",
        )
        .expect("write bad log");
        let err = validation_curve(&dir).expect_err("bad number").to_string();
        assert!(err.contains("line 2") && err.contains("abc"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
