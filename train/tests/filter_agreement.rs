//! `eval::filter_agreement` on a fresh SaRO model of the mutant scene (100x100
//! training images): its observations are the canonical centres' projections, so
//! neither estimator may exceed Mip-Splatting's static nu, and the pairs it counts
//! are exactly the drawn (Gaussian, time bin) pairs.

use std::path::PathBuf;

use maaf_filter::{FilterKind, MotionCurves};
use maaf_train::data::{Dataset, DatasetOptions};
use maaf_train::eval::filter_agreement::filter_agreement;
use maaf_train::trainer::{TrainConfig, Trainer};

#[test]
fn agreement_counts_drawn_pairs_and_never_exceeds_the_static_nu_of_a_static_model() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/dnerf/mutant");
    if !root.exists() {
        eprintln!("skipping: {} is absent", root.display());
        return;
    }
    let data = Dataset::open(&root, DatasetOptions::default()).expect("mutant");
    let mut config = TrainConfig {
        train_scale: 0.125,
        init_points: 400,
        seed: 2,
        ..TrainConfig::default()
    };
    config.filter.kind = FilterKind::Motion;
    let mut trainer = Trainer::new(&data, config).expect("trainer");
    trainer.ensure_filter();
    let agreement = filter_agreement(&trainer).expect("a motion run");

    // Independent count of the drawn pairs at the curves' bin times.
    let curves =
        MotionCurves::refresh(&trainer.observations, &trainer.config.filter).expect("curves");
    let drawn: usize = (0..curves.grid_t())
        .map(|s| {
            let frame = trainer.frame_at(f64::from(curves.bin_time(s)));
            frame[3]
                .data()
                .iter()
                .filter(|&&o| o >= 1.0 / 255.0)
                .count()
        })
        .sum();
    assert!(drawn > 0);
    assert_eq!(agreement.pairs, drawn);
    assert!(agreement.gaussians > 0 && agreement.gaussians <= trainer.num_gaussians());

    let names: Vec<&str> = agreement
        .ratios
        .iter()
        .map(|r| r.estimator.as_str())
        .collect();
    assert_eq!(names, ["kde", "window_max"]);
    for r in &agreement.ratios {
        // Every curve is capped by x_max, the largest f/d of the canonical centre,
        // which is the static nu: ratio <= 1.
        assert!(
            r.p05 <= r.p50 && r.p50 <= r.p95 && r.p95 <= 1.0 + 1e-6,
            "{r:?}"
        );
        assert_eq!(r.above_1_1, 0.0, "{r:?}");
        assert!(r.p05 > 0.0, "{r:?}");
    }
    // Nothing moves before training: no moving Gaussian, no moving summary.
    assert_eq!((agreement.moving_gaussians, agreement.moving_pairs), (0, 0));
    assert!(agreement.moving_ratios.is_empty());
    // One camera per time (D-NeRF): a +-h_t window holds 15 of the 150 views, so
    // the windowed maximum is below the static nu for most drawn pairs.
    let window = &agreement.ratios[1];
    assert!(window.p50 < 1.0, "{window:?}");
}
