//! Analysis export round trip (JSON and CSV, atomic writes).

use maaf_filter::{AnalysisExport, FilterConfig, MotionCurves, MotionEstimator, ObservationTable};

#[test]
fn export_round_trips_and_writes_atomically() {
    let cfg = FilterConfig::default();
    let times: Vec<f32> = (0..30).map(|i| i as f32 / 29.0).collect();
    let mut table = ObservationTable::new(times.clone(), 3);
    // Gaussian 0 static (constant f/d), 1 moving toward the camera, 2 never seen.
    table.row_mut(0).fill(80.0);
    for (x, t) in table.row_mut(1).iter_mut().zip(&times) {
        *x = 100.0 / (10.0 - 8.0 * t);
    }
    let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
    let window_cfg = FilterConfig {
        estimator: MotionEstimator::WindowMax,
        ..cfg.clone()
    };
    let window = MotionCurves::refresh(&table, &window_cfg).expect("refresh");
    let chosen = vec![(0, "static".to_string()), (1, "moving".to_string())];
    let mut export = AnalysisExport::collect(
        &table,
        &curves,
        cfg.estimator,
        &chosen,
        Some(&[80.0, 50.0, 10.0]),
    )
    .expect("collect");
    export
        .compare(MotionEstimator::WindowMax, &window)
        .expect("compare");
    assert_eq!(export.estimator, "kde");
    assert_eq!(export.gaussians[1].observations.len(), 30);
    assert_eq!(export.gaussians[1].nu.len(), cfg.grid_t);
    assert_eq!(export.gaussians[0].static_nu, Some(80.0));
    let compared = &export.gaussians[1].compared[0];
    assert_eq!(compared.estimator, "window_max");
    // The windowed maximum of f/d = 100 / (10 - 8 t) at the first bin (t = 0) is the
    // largest f/d within h_t of it, rounded up to the grid: above 10 = f/d(0) and
    // below the KDE's value there.
    let (first_window, first_kde) = (compared.nu[0][1], export.gaussians[1].nu[0][1]);
    assert!(
        first_window > 10.0 && first_window < first_kde,
        "window {first_window}, kde {first_kde}"
    );

    let dir = std::env::temp_dir().join(format!("maaf-filter-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let json = dir.join("nu.json");
    let csv = dir.join("nu.csv");
    export.write_json(&json).expect("json");
    export.write_csv(&csv).expect("csv");
    let back: AnalysisExport =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("read")).expect("parse");
    assert_eq!(back, export);
    let text = std::fs::read_to_string(&csv).expect("read");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("gaussian,label,series,t,value"));
    // 30 observations, 100 + 100 curve points per Gaussian plus one static_nu row each.
    assert_eq!(lines.count(), 2 * (30 + 2 * 100 + 1));
    assert!(
        text.contains("1,moving,nu,1,50\n"),
        "last bin of the moving one is x_max"
    );
    assert!(text.contains("1,moving,nu_window_max,1,50\n"), "{text}");
    // No temporary file is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .expect("list")
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty());
    std::fs::remove_dir_all(&dir).expect("cleanup");

    assert!(
        AnalysisExport::collect(&table, &curves, cfg.estimator, &[(3, "x".into())], None).is_err()
    );
}

#[test]
fn estimator_names_are_the_config_spellings() {
    for e in [MotionEstimator::Kde, MotionEstimator::WindowMax] {
        let json = serde_json::to_string(&e).expect("serialise");
        assert_eq!(json, format!("\"{}\"", e.name()));
    }
}

#[test]
fn exports_without_the_new_fields_still_parse() {
    // An export written before `estimator`, `compared` and `drawn_motion` existed.
    let old = r#"{"gaussians": [{"index": 4, "label": "moving", "x_max": 50.0,
        "static_nu": null, "observations": [[0.0, 40.0]], "nu": [[0.0, 45.0]]}]}"#;
    let back: AnalysisExport = serde_json::from_str(old).expect("parse");
    assert_eq!(back.estimator, "kde");
    assert!(back.gaussians[0].compared.is_empty());
    assert_eq!(back.gaussians[0].drawn_motion, None);
}
