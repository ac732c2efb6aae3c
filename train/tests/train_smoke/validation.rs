//! Validation during training: `val_psnr` is logged and changes nothing, and it sees
//! the model before an opacity reset.

use super::*;

/// `val_psnr` is logged every `val_every` iterations (and at the end) and leaves the
/// training itself unchanged: the same seed with validation off gives the same
/// parameters.
#[test]
fn validation_psnr_is_logged_and_changes_nothing() {
    let (_tmp, data) = scene();
    let base = std::env::temp_dir().join(format!("maaf-val-{}", std::process::id()));
    let run = |val_every: usize, name: &str| {
        let mut c = tiny_config(FilterKind::Motion);
        c.iterations = 50;
        c.log_every = 10;
        c.val_every = val_every;
        c.val_views = 2;
        let out = base.join(name);
        maaf_train::trainer::train_run(&data, c, &out, false).expect("run");
        let model = load_checkpoint(&data, &out.join("model")).expect("model");
        let log = std::fs::read_to_string(out.join("log.csv")).expect("log");
        (model, log)
    };
    let (mut with, log) = run(20, "with");
    let (mut without, log_off) = run(0, "without");
    assert_eq!(params(&mut with), params(&mut without));
    let rows: Vec<Vec<&str>> = log.lines().map(|l| l.split(',').collect()).collect();
    assert_eq!(rows[0].last(), Some(&"val_psnr"));
    let logged: Vec<&str> = rows[1..]
        .iter()
        .filter(|r| !r.last().expect("cells").is_empty())
        .map(|r| r[0])
        .collect();
    assert_eq!(logged, ["20", "40", "50"]);
    for r in &rows[1..] {
        if let Ok(p) = r.last().expect("cells").parse::<f64>() {
            assert!(p > 5.0 && p < 60.0, "val_psnr {p}");
        }
    }
    // With validation off no row has a value.
    assert!(
        log_off.lines().skip(1).all(|l| l.ends_with(',')),
        "{log_off}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// Validation renders the model an iteration trained, before that iteration's
/// schedule: where an opacity reset falls on a validation iteration, the logged
/// `val_psnr` is the one of the same run without resets (rather than the near-empty
/// render just after the reset).
#[test]
fn validation_sees_the_model_before_an_opacity_reset() {
    let (_tmp, data) = scene();
    let base = std::env::temp_dir().join(format!("maaf-val-reset-{}", std::process::id()));
    let val_at_20 = |reset_every: usize, name: &str| {
        let mut c = tiny_config(FilterKind::Mip3d);
        c.iterations = 30;
        c.log_every = 10;
        c.val_every = 20;
        c.val_views = 2;
        c.densify.opacity_reset_every = reset_every;
        let out = base.join(name);
        maaf_train::trainer::train_run(&data, c, &out, false).expect("run");
        let log = std::fs::read_to_string(out.join("log.csv")).expect("log");
        let row = log
            .lines()
            .find(|l| l.starts_with("20,"))
            .expect("row of iteration 20")
            .to_string();
        let val = row.rsplit(',').next().expect("val_psnr cell").to_string();
        (val, log)
    };
    let (with_reset, log) = val_at_20(20, "reset");
    let (no_reset, _) = val_at_20(0, "no-reset");
    assert!(!with_reset.is_empty(), "{log}");
    assert_eq!(with_reset, no_reset, "{log}");
    // The reset did happen: the two runs' losses differ after iteration 20.
    let (_, log_no_reset) = val_at_20(0, "no-reset-2");
    let l1_at_30 = |l: &str| {
        let row = l.lines().find(|r| r.starts_with("30,")).expect("row 30");
        row.split(',').nth(1).expect("l1 cell").to_string()
    };
    assert_ne!(l1_at_30(&log), l1_at_30(&log_no_reset), "{log}");
    let _ = std::fs::remove_dir_all(&base);
}
