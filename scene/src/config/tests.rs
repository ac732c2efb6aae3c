//! Tests of the training configuration: defaults, validation, scaling and the
//! sections' JSON.

use super::*;
use maaf_filter::FilterKind;

/// The backdrop layer is a static, single-view-per-step run on the background
/// pixels whose filter is `backdrop.filter` (the static one unless set), with the
/// run's other filter settings.
#[test]
fn the_backdrop_layer_is_static_with_its_own_filter_kind() {
    let mut run: TrainConfig = serde_json::from_str(
        r#"{"filter": {"kind": "motion", "s3d": 0.3}, "backdrop": {"iterations": 50}}"#,
    )
    .expect("parses");
    let layer = run.backdrop_layer();
    assert_eq!(layer.filter.kind, FilterKind::Mip3d);
    assert_eq!(layer.filter.s3d, 0.3);
    assert_eq!(layer.loss_region, LossRegion::Background);
    assert_eq!((layer.iterations, layer.batch), (50, 1));
    assert!(!layer.backdrop.enabled());
    run.backdrop.filter = FilterKind::None;
    assert_eq!(run.backdrop_layer().filter.kind, FilterKind::None);
}

/// A run shorter than its schedule is told what it skips; the full schedule and a
/// filterless run's refreshes are not.
#[test]
fn short_runs_are_told_what_their_schedule_skips() {
    assert!(TrainConfig::default().schedule_warnings().is_empty());
    let short = TrainConfig {
        iterations: 20,
        ..TrainConfig::default()
    };
    let warnings = short.schedule_warnings();
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings[0].contains("densify.from") && warnings[0].contains("at 20"));
    assert!(warnings[1].contains("filter.refresh.start"));
    let mut unfiltered = short.clone();
    unfiltered.filter.kind = maaf_filter::FilterKind::None;
    assert_eq!(unfiltered.schedule_warnings().len(), 1);
    // Densification inside the run refreshes the filter after it.
    let mut densifying = short;
    densifying.densify.from = 5;
    assert!(densifying.schedule_warnings().is_empty());
}

/// Each bad value is refused with its field's name; the defaults pass.
#[test]
fn every_bad_setting_names_its_field() {
    TrainConfig::default()
        .validate()
        .expect("defaults are valid");
    type Change = Box<dyn Fn(&mut TrainConfig)>;
    let cases: Vec<(&str, Change)> = vec![
        ("iterations", Box::new(|c| c.iterations = 0)),
        ("batch", Box::new(|c| c.batch = 0)),
        ("train_scale", Box::new(|c| c.train_scale = -1.0)),
        ("train_scale", Box::new(|c| c.train_scale = f64::NAN)),
        ("init_points", Box::new(|c| c.init_points = 0)),
        ("hull_fraction", Box::new(|c| c.hull_fraction = 1.5)),
        ("lambda_dssim", Box::new(|c| c.lambda_dssim = 2.0)),
        (
            "terms.depth_tv",
            Box::new(|c| {
                c.terms.insert("depth_tv".into(), f64::NAN);
            }),
        ),
        ("checkpoint_every", Box::new(|c| c.checkpoint_every = 0)),
        ("log_every", Box::new(|c| c.log_every = 0)),
        ("val_every", Box::new(|c| c.val_every = 150)),
        (
            "max_skipped_fraction",
            Box::new(|c| c.max_skipped_fraction = 1.5),
        ),
        (
            "densify.max_gaussians",
            Box::new(|c| c.densify.max_gaussians = 0),
        ),
        ("densify.from", Box::new(|c| c.densify.from = 20_000)),
        (
            "prune.from",
            Box::new(|c| {
                c.prune.every = 100;
                c.prune.from = 40_000;
            }),
        ),
        (
            "prune.ratio_densifying",
            Box::new(|c| c.prune.ratio_densifying = 1.0),
        ),
        (
            "prune.ratio_after",
            Box::new(|c| c.prune.ratio_after = -0.1),
        ),
        (
            "densify.min_opacity",
            Box::new(|c| c.densify.min_opacity = -0.1),
        ),
    ];
    for (field, change) in cases {
        let mut c = TrainConfig::default();
        change(&mut c);
        let msg = c.validate().expect_err(field).to_string();
        assert!(
            msg.starts_with(&format!("config: {field} = ")),
            "{field}: {msg}"
        );
        assert!(!msg.contains('\n'), "{msg}");
    }
}

#[test]
fn the_tracking_model_densifies_and_prunes_only_in_frame_zero() {
    let mut c = TrainConfig {
        model: ModelConfig::default_of("track").expect("built in"),
        iterations: 10_000,
        ..TrainConfig::default()
    };
    // Frame 0 is the first 0.2 x 10 000 = 2000 iterations.
    let msg = c.validate().expect_err("default densify.until").to_string();
    assert!(
        msg.starts_with(
            "config: densify.until = 15000: must be <= 2000, the last iteration of frame 0"
        ),
        "{msg}"
    );
    // The default reset every 2000 iterations would come at the last iteration
    // of frame 0 and leave the opacities there.
    c.densify.until = 2000;
    let msg = c.validate().expect_err("a reset at 2000").to_string();
    assert!(
        msg.starts_with("config: densify.opacity_reset_every = 2000: must be no divisor of 2000"),
        "{msg}"
    );
    c.densify.opacity_reset_every = 1000;
    c.densify.until = 1999;
    c.validate()
        .expect("densification within frame 0, the last reset at 1000");
    c.prune.every = 100;
    let msg = c.validate().expect_err("default prune.until").to_string();
    assert!(
        msg.starts_with("config: prune.until = 30000: must be <= 2000"),
        "{msg}"
    );
    c.prune.until = 1500;
    c.prune.from = 1000;
    c.validate().expect("pruning within frame 0");
}

#[test]
fn a_term_name_must_be_a_log_column_of_its_own() {
    for (name, says) in [
        ("l1", "reserved"),
        ("total", "reserved"),
        ("a,b", "not a term name"),
        ("", "not a term name"),
    ] {
        let mut c = TrainConfig::default();
        c.terms.insert(name.into(), 0.1);
        let msg = c.validate().expect_err(name).to_string();
        assert!(msg.starts_with("config: terms: "), "{msg}");
        assert!(msg.contains(says), "{name}: {msg}");
    }
    let mut c = TrainConfig::default();
    c.terms.insert("my_term_2".into(), 0.0);
    c.validate()
        .expect("any registered-looking name with a weight >= 0");
}
