//! `write_report` on hand-made eval.json files (no training needed): the markdown
//! has the Tab. 2-shaped tables and every chart is a non-empty PNG; bad input fails.

use std::path::{Path, PathBuf};

use maaf_eval::report::write_report;
use maaf_eval::write_atomic;
use maaf_eval::{EvalReport, ScaleResult};
use maaf_filter::{AnalysisExport, EstimatorCurve, GaussianTrace};

fn fake_run(dir: &Path, filter: &str, psnr_at: impl Fn(f64) -> f64, seconds: f64) {
    std::fs::create_dir_all(dir.join("eval")).expect("mkdir");
    let scales = [0.25, 0.5, 1.0, 2.0, 4.0]
        .iter()
        .map(|&s| {
            ScaleResult::new(
                s,
                ((100.0 * s) as u32, (100.0 * s) as u32),
                psnr_at(s),
                0.9 - 0.01 * (s.log2().abs()),
            )
        })
        .collect();
    let report = EvalReport {
        model: "saro".into(),
        filter: filter.into(),
        train_scale: 0.25,
        iterations: 1000,
        train_seconds: seconds,
        num_gaussians: 20_000,
        model_bytes: 20_000 * 59 * 4,
        filter_bytes: if filter == "motion" { 20_000 * 72 } else { 0 },
        background: [1.0; 3],
        trained_background: None,
        quantized_8bit: false,
        frame_stride: 1,
        lpips_net: "alex".into(),
        scales,
        skipped_scales: Vec::new(),
        extra_metrics: Default::default(),
    };
    write_atomic(
        &dir.join("eval.json"),
        &serde_json::to_vec_pretty(&report).expect("json"),
    )
    .expect("write");
    if filter == "motion" {
        let trace = |label: &str, amp: f32| GaussianTrace {
            index: 7,
            label: label.into(),
            x_max: 300.0,
            static_nu: Some(215.0),
            observations: (0..40)
                .map(|i| {
                    let t = i as f32 / 39.0;
                    [t, 200.0 + amp * (6.0 * t).sin() + (i % 5) as f32 * 3.0]
                })
                .collect(),
            nu: (0..20)
                .map(|i| {
                    let t = i as f32 / 19.0;
                    [t, 210.0 + amp * (6.0 * t).sin()]
                })
                .collect(),
            compared: vec![EstimatorCurve {
                estimator: "window_max".into(),
                nu: (0..20)
                    .map(|i| {
                        let t = i as f32 / 19.0;
                        [t, 205.0 + amp * (6.0 * t).sin()]
                    })
                    .collect(),
            }],
            drawn_motion: Some(amp / 1000.0),
        };
        let export = AnalysisExport {
            estimator: "kde".into(),
            gaussians: vec![trace("static", 2.0), trace("moving", 80.0)],
        };
        export
            .write_json(&dir.join("eval/filter_analysis.json"))
            .expect("export");
    }
}

#[test]
fn report_writes_tables_and_charts() {
    let tmp = std::env::temp_dir().join(format!("maaf_report_{}", std::process::id()));
    let runs: Vec<PathBuf> = ["none", "mip3d", "motion"]
        .iter()
        .map(|f| tmp.join(f))
        .collect();
    fake_run(&runs[0], "none", |s| 30.0 - 3.0 * s.log2().abs(), 100.0);
    fake_run(&runs[1], "mip3d", |s| 30.5 - 1.5 * s.log2().abs(), 110.0);
    fake_run(&runs[2], "motion", |s| 31.0 - 1.0 * s.log2().abs(), 120.0);
    let out = tmp.join("report");
    let result = write_report(&runs, &out).expect("report");

    let md = std::fs::read_to_string(&result.markdown).expect("report.md");
    assert!(md.contains("| Method | PSNR 1x | PSNR 2x | PSNR 4x | PSNR avg |"));
    assert!(md.contains("PSNR 1/2x | PSNR 1/4x"));
    assert!(md.contains("saro + motion-aware filter"));
    // none at 1x/2x/4x: 30, 27, 24 -> avg 27.00, below the motion run's in every
    // column, so not bold; the motion run's best values are.
    assert!(
        md.contains("| saro no 3D filter | 30.00 | 27.00 | 24.00 | 27.00 |"),
        "{md}"
    );
    assert!(
        md.contains("| **31.00** | **30.00** | **29.00** | **30.00** |"),
        "{md}"
    );
    assert!(result.table.lines().count() == 5, "{}", result.table);
    // The printed table has every evaluated scale, zoom-out included.
    for col in ["PSNR 1/4x", "PSNR 1/2x", "PSNR 1x", "PSNR 2x", "PSNR 4x"] {
        assert!(result.table.contains(col), "{col}: {}", result.table);
    }
    assert_eq!(result.charts.len(), 4);
    for c in &result.charts {
        let bytes = std::fs::read(c).expect("chart");
        assert!(bytes.len() > 1000, "{}", c.display());
        assert_eq!(&bytes[1..4], b"PNG", "{}", c.display());
        let img = image::load_from_memory(&bytes).expect("decodes");
        assert!(img.width() >= 600);
    }

    // Bad input: a folder without eval.json.
    let e = write_report(&[tmp.join("missing")], &out).expect_err("no eval.json");
    assert!(e.to_string().contains("no eval.json"), "{e}");
    assert!(!e.to_string().contains('\n'));
    let e = write_report(&[], &out).expect_err("no runs");
    assert!(!e.to_string().is_empty());
    std::fs::remove_dir_all(&tmp).ok();
}
