//! `eval::filter_agreement` on a fresh SaRO model of a generated scene in the D-NeRF
//! layout (100 views of 100x100 pixels, one camera per time): its observations are the canonical centres' projections, so
//! neither estimator may exceed Mip-Splatting's static nu, and the pairs it counts
//! are exactly the drawn (Gaussian, time bin) pairs. The nu(t) chart's export picks
//! its Gaussians by drawn-centre motion, checked against an independent loop.

use maaf_data::synthetic::{GenerateOptions, generate};
use maaf_data::{Dataset, DatasetOptions};
use maaf_eval::filter_agreement::{FilterStudy, MOVING, filter_agreement};
use maaf_filter::{FilterKind, MotionCurves};
use maaf_io::TempDir;
use maaf_scene::TrainedScene;
use maaf_scene::{TrainConfig, camera_extent};
use maaf_train::models::{ModelConfig, SaroConfig};
use maaf_train::trainer::Trainer;

/// A SaRO motion run on the generated scene (400 Gaussians) after `steps`
/// iterations, dynamic from the first one when `static_iterations` is 0, as the
/// trained scene it holds.
fn tiny_run(static_iterations: usize, steps: usize) -> TrainedScene {
    let tmp = TempDir::new("filter-agreement").expect("temp dir");
    let root = tmp.path().join("scene");
    generate(&root, &GenerateOptions::small(100, 100), &mut |_, _| {}).expect("generates");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    let mut config = TrainConfig {
        train_scale: 1.0,
        init_points: 400,
        seed: 2,
        model: ModelConfig::Saro(SaroConfig {
            static_iterations,
            ..SaroConfig::default()
        }),
        ..TrainConfig::default()
    };
    config.filter.kind = FilterKind::Motion;
    let mut trainer = Trainer::new(&data, config).expect("trainer");
    trainer.ensure_filter();
    for _ in 0..steps {
        trainer.step();
    }
    trainer.into_scene()
}

#[test]
fn agreement_counts_drawn_pairs_and_never_exceeds_the_static_nu_of_a_static_model() {
    let scene = tiny_run(SaroConfig::default().static_iterations, 0);
    let agreement = filter_agreement(&scene).expect("a motion run");

    // Independent count of the drawn pairs at the curves' bin times.
    let curves = MotionCurves::refresh(&scene.observations, &scene.config.filter).expect("curves");
    let drawn: usize = (0..curves.grid_t())
        .map(|s| {
            let frame = scene.gaussians_at(f64::from(curves.bin_time(s)));
            frame[3]
                .data()
                .iter()
                .filter(|&&o| o >= 1.0 / 255.0)
                .count()
        })
        .sum();
    assert!(drawn > 0);
    assert_eq!(agreement.pairs, drawn);
    assert!(agreement.gaussians > 0 && agreement.gaussians <= scene.num_gaussians());

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
    assert!(
        agreement.summary().ends_with("; no moving Gaussian"),
        "{}",
        agreement.summary()
    );
    // One camera per time (D-NeRF): a +-h_t window holds 10 of the 100 views, so
    // the windowed maximum is below the static nu for most drawn pairs.
    let window = &agreement.ratios[1];
    assert!(window.p50 < 1.0, "{window:?}");
}

#[test]
fn the_nu_t_chart_shows_the_least_and_the_most_moving_drawn_gaussian() {
    // A few dynamic iterations give the residual MLP something to move.
    let scene = tiny_run(0, 20);
    let curves = MotionCurves::refresh(&scene.observations, &scene.config.filter).expect("curves");
    // The chart's Gaussians: the least and the most moving of those drawn at a
    // quarter of the bins and observed in a quarter of the frames, by an independent
    // per-Gaussian loop over the same bins.
    let n = scene.num_gaussians();
    let mut boxes = vec![(0usize, [f64::INFINITY; 3], [f64::NEG_INFINITY; 3]); n];
    for s in 0..curves.grid_t() {
        let [means, _, _, opacity, _] = scene.gaussians_at(f64::from(curves.bin_time(s)));
        for (k, b) in boxes.iter_mut().enumerate() {
            if opacity.data()[k] >= 1.0 / 255.0 {
                b.0 += 1;
                for d in 0..3 {
                    let x = f64::from(means.data()[3 * k + d]);
                    b.1[d] = b.1[d].min(x);
                    b.2[d] = b.2[d].max(x);
                }
            }
        }
    }
    let extent = camera_extent(scene.cameras());
    let min_obs = (scene.observations.num_frames() / 4).max(2);
    let eligible: Vec<(usize, f64)> = boxes
        .iter()
        .enumerate()
        .filter(|(k, b)| {
            b.0 >= curves.grid_t() / 4
                && curves.x_max()[*k] > 0.0
                && scene.observations.observations(*k).len() >= min_obs
        })
        .map(|(k, b)| {
            let diag = (0..3).map(|d| (b.2[d] - b.1[d]).powi(2)).sum::<f64>();
            (k, if b.0 < 2 { 0.0 } else { diag.sqrt() / extent })
        })
        .collect();
    assert!(eligible.len() > 10, "{} eligible", eligible.len());
    let (lo, hi) = eligible
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), e| {
            (lo.min(e.1), hi.max(e.1))
        });
    let study = FilterStudy::of(&scene).expect("a motion run");
    let export = study.analysis().expect("an export");
    assert_eq!(export.estimator, "kde");
    let [still, mobile] = &export.gaussians[..] else {
        panic!("two traces expected");
    };
    let motion = |k: usize| eligible.iter().find(|e| e.0 == k).expect("eligible").1;
    assert_eq!(still.label, "static");
    assert!(
        (motion(still.index) - lo).abs() < 1e-9,
        "{} vs {lo}",
        motion(still.index)
    );
    assert!(
        (motion(mobile.index) - hi).abs() < 1e-9,
        "{} vs {hi}",
        motion(mobile.index)
    );
    assert!(hi > lo, "20 dynamic steps move some Gaussian: {hi}");
    let label = if hi >= MOVING {
        "moving"
    } else {
        "most mobile"
    };
    assert_eq!(mobile.label, label);
    for g in [still, mobile] {
        let m = f64::from(g.drawn_motion.expect("drawn motion"));
        assert!((m - motion(g.index)).abs() < 1e-6, "{m}");
        assert_eq!(g.compared.len(), 1);
        assert_eq!(g.compared[0].estimator, "window_max");
        assert_eq!(g.compared[0].nu.len(), curves.grid_t());
        assert!(g.static_nu.is_some_and(|v| v > 0.0));
    }
}
