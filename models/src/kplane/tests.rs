//! Checks of the K-plane lookup: forward against the slow oracle, partition of unity,
//! gradcheck of the planes with a corrupted backward as negative control.

use std::sync::Arc;

use super::sample::ROWS_PER_TASK;
use super::*;
use maaf_autodiff::Tape;
use maaf_autodiff::check::{
    GradcheckConfig, compare, gradcheck,
    tests_support::{random_tensor, with_threads},
};

/// A small field with random planes and queries that cover the interior, the
/// border (clamp) and every mip level, including fractional ones.
fn fixture() -> (KPlaneField, Vec<Tensor<f64>>, FieldQuery) {
    let config = KPlaneConfig {
        spatial_res: 8,
        time_res: 5,
        channels: 3,
        max_mip_level: 7,
    };
    let field = KPlaneField::new(config, [-1.0, -2.0, 0.0], [1.0, 2.0, 3.0]);
    let planes: Vec<Tensor<f64>> = field
        .zero_planes::<f64>()
        .iter()
        .enumerate()
        .map(|(p, plane)| random_tensor(plane.shape(), -1.0, 1.0, 10 + p as u64))
        .collect();
    let n = 12;
    let mut means = random_tensor::<f64>(&[n, 3], -1.2, 3.2, 1).into_vec();
    // Gaussian 0 outside the box (clamp), Gaussian 1 exactly on a texel centre.
    means[0..3].copy_from_slice(&[-1.5, 2.5, 3.4]);
    means[3..6].copy_from_slice(&[-1.0 + 2.0 * 0.5 / 8.0, 0.0, 1.5]);
    let times = random_tensor::<f64>(&[n], -0.1, 1.1, 2).into_vec();
    // Scales from below the clamp (level 0) to above it (level log2 8 = 3).
    let scales = random_tensor::<f64>(&[n, 3], -5.0, 1.0, 3).map(f64::exp);
    let q = field.query(&means, &times, scales.data());
    (field, planes, q)
}

#[test]
fn forward_matches_the_slow_reference() {
    let (field, planes, q) = fixture();
    assert!(q.levels.iter().flatten().any(|&l| l == 0.0));
    assert!(q.levels.iter().flatten().any(|&l| l == 3.0));
    assert!(q.levels.iter().flatten().any(|&l| l.fract() > 0.1));
    let tape = Tape::<f64>::new();
    let vars: Vec<_> = planes.iter().map(|p| tape.constant(p.clone())).collect();
    let out = tape.apply1(PlaneSample::new(&field, Arc::new(q.clone())), &vars);
    let want = reference_sample(&field, &planes, &q);
    // Same arithmetic up to summation order: a few ulps of O(1) values.
    let cmp = compare(&out.value(), &want, 1e-12, 1e-12);
    assert!(cmp.passed(), "{cmp:?}");
}

#[test]
fn constant_planes_give_six_times_the_constant() {
    // A partition-of-unity check of the taps, at every level and at the border.
    let (field, planes, q) = fixture();
    let tape = Tape::<f64>::new();
    let vars: Vec<_> = planes
        .iter()
        .map(|p| tape.constant(Tensor::full(p.shape(), 0.5)))
        .collect();
    let out = tape.apply1(PlaneSample::new(&field, Arc::new(q)), &vars);
    assert!(out.value().data().iter().all(|&v| (v - 3.0).abs() < 1e-14));
}

#[test]
fn plane_sample_passes_gradcheck_and_rejects_a_wrong_backward() {
    let (field, planes, q) = fixture();
    let q = Arc::new(q);
    // The op is linear in the planes, so central differences are exact up to
    // rounding (~1e-10 here); default tolerances (atol 1e-7, rtol 1e-5).
    let cfg = GradcheckConfig::default();
    let report = gradcheck(
        |t, v| t.apply1(PlaneSample::new(&field, q.clone()), v),
        &planes,
        &cfg,
    );
    report.assert_passed();
    let bad = gradcheck(
        |t, v| t.apply1(PlaneSample::new(&field, q.clone()).corrupted(), v),
        &planes,
        &cfg,
    );
    assert!(!bad.passed(), "the corrupted backward was not caught");
}

/// Forward value and plane gradients (cotangent: the output itself) of `n` random
/// queries, in f32, under a pool of `threads` threads.
fn run_threads(threads: usize, n: usize) -> (Vec<f32>, Vec<Vec<f32>>, Vec<f64>) {
    let (field, planes, _) = fixture();
    let means = random_tensor::<f64>(&[n, 3], -1.2, 3.2, 7).into_vec();
    let times = random_tensor::<f64>(&[n], -0.1, 1.1, 8).into_vec();
    let scales = random_tensor::<f64>(&[n, 3], -5.0, 1.0, 9).map(f64::exp);
    let q = field.query(&means, &times, scales.data());
    let want = reference_sample(&field, &planes, &q).into_vec();
    with_threads(threads, || {
        let tape = Tape::<f32>::new();
        let vars: Vec<_> = planes.iter().map(|p| tape.var(p.cast())).collect();
        let out = tape.apply1(PlaneSample::new(&field, Arc::new(q)), &vars);
        let loss = out.square().sum().scale(0.5);
        let grads = tape.backward(loss).expect("finite");
        let g = vars
            .iter()
            .map(|&v| grads.wrt(v).expect("plane gradient").data().to_vec())
            .collect();
        (out.value().data().to_vec(), g, want)
    })
}

#[test]
fn many_rows_match_the_reference_whatever_the_thread_count() {
    // Several rayon chunks of rows, the last one partial.
    let n = 3 * ROWS_PER_TASK + 17;
    let (out1, g1, want) = run_threads(1, n);
    for (i, (&o, &w)) in out1.iter().zip(&want).enumerate() {
        assert!((o as f64 - w).abs() < 1e-5, "row value {i}: {o} vs {w}");
    }
    let (out3, g3, _) = run_threads(3, n);
    assert_eq!(out1, out3);
    assert_eq!(g1, g3);
}
