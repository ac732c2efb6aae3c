//! Checks of the three neighbour ops: the forward against slow per-pair loops written
//! from the formulas (rotating by quaternion products, not matrices), the backward
//! against finite differences with a deliberately broken backward rejected, and the
//! same values on one thread as on two.

use std::sync::Arc;

use maaf_autodiff::check::tests_support::{random_tensor, with_threads};
use maaf_autodiff::check::{GradcheckConfig, GradcheckReport, gradcheck};
use maaf_autodiff::{Tape, Tensor};

use super::frames::Frame;
use super::neighbours::Neighbours;
use super::quat::{conj, mul, normalise};
use super::{Isometry, Rigidity, Similarity};

const N: usize = 24;

/// Current centres and quaternions, the previous frame (centres nearby, unit
/// quaternions) and neighbours on the first frame's centres, with weights of order 1.
fn fixture() -> (Tensor<f64>, Tensor<f64>, Arc<Frame<f64>>, Arc<Neighbours>) {
    let first = random_tensor::<f64>(&[N, 3], -1.0, 1.0, 1);
    let moved = random_tensor::<f64>(&[N, 3], -0.2, 0.2, 2);
    let previous_means = first.zip_map(&moved, |a, b| a + b);
    let previous = Frame::new(previous_means, &random_tensor(&[N, 4], -1.0, 1.0, 3));
    let means = previous
        .means
        .zip_map(&random_tensor(&[N, 3], -0.1, 0.1, 4), |a, b| a + b);
    let quats = random_tensor::<f64>(&[N, 4], -1.0, 1.0, 5);
    let points: Vec<[f64; 3]> = first
        .data()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let nb = Neighbours::new(&points, 5, 0.7);
    (means, quats, Arc::new(previous), Arc::new(nb))
}

fn at<const W: usize>(t: &Tensor<f64>, i: usize) -> [f64; W] {
    std::array::from_fn(|a| t.data()[W * i + a])
}

/// Rotates `v` by the unit quaternion `q`: the vector part of `q (0, v) conj(q)`.
fn turn(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let r = mul(mul(q, [0.0, v[0], v[1], v[2]]), conj(q));
    [r[1], r[2], r[3]]
}

/// Every pair `(i, j, w, d0)`.
fn pairs(nb: &Neighbours) -> Vec<(usize, usize, f64, f64)> {
    (0..nb.pairs())
        .map(|p| (p / nb.k, nb.index[p], nb.weight[p], nb.distance[p]))
        .collect()
}

fn relative(quats: &Tensor<f64>, previous: &Frame<f64>, i: usize) -> [f64; 4] {
    mul(normalise(at(quats, i)).0, conj(at(&previous.quats, i)))
}

fn rigidity_loop(m: &Tensor<f64>, q: &Tensor<f64>, prev: &Frame<f64>, nb: &Neighbours) -> f64 {
    let all = pairs(nb);
    let sum: f64 = all
        .iter()
        .map(|&(i, j, w, _)| {
            let (mi, mj) = (at::<3>(m, i), at::<3>(m, j));
            let (pi, pj) = (at::<3>(&prev.means, i), at::<3>(&prev.means, j));
            // R^T v is the rotation by the inverse, conj(r).
            let back = turn(conj(relative(q, prev, i)), [0, 1, 2].map(|a| mj[a] - mi[a]));
            let e2: f64 = (0..3).map(|a| (back[a] - (pj[a] - pi[a])).powi(2)).sum();
            (w * e2 + 1e-20).sqrt()
        })
        .sum();
    sum / all.len() as f64
}

fn rotation_loop(q: &Tensor<f64>, prev: &Frame<f64>, nb: &Neighbours) -> f64 {
    let all = pairs(nb);
    let sum: f64 = all
        .iter()
        .map(|&(i, j, w, _)| {
            let (ri, rj) = (relative(q, prev, i), relative(q, prev, j));
            let d2: f64 = (0..4).map(|a| (rj[a] - ri[a]).powi(2)).sum();
            (w * d2 + 1e-20).sqrt()
        })
        .sum();
    sum / all.len() as f64
}

fn isometry_loop(m: &Tensor<f64>, nb: &Neighbours) -> f64 {
    let all = pairs(nb);
    let sum: f64 = all
        .iter()
        .map(|&(i, j, w, d0)| {
            let (mi, mj) = (at::<3>(m, i), at::<3>(m, j));
            let l = ((0..3).map(|a| (mj[a] - mi[a]).powi(2)).sum::<f64>() + 1e-20).sqrt();
            (w * (l - d0).powi(2) + 1e-20).sqrt()
        })
        .sum();
    sum / all.len() as f64
}

/// The three ops' values at the fixture, on the thread pool in use.
fn values(
    means: &Tensor<f64>,
    quats: &Tensor<f64>,
    prev: &Arc<Frame<f64>>,
    nb: &Arc<Neighbours>,
) -> [f64; 3] {
    let tape = Tape::<f64>::new();
    let (m, q) = (tape.constant(means.clone()), tape.constant(quats.clone()));
    [
        tape.apply1(Rigidity::new(nb.clone(), prev.clone()), &[m, q]),
        tape.apply1(Similarity::new(nb.clone(), prev.clone()), &[q]),
        tape.apply1(Isometry::new(nb.clone()), &[m]),
    ]
    .map(|v| v.value().item())
}

#[test]
fn forwards_match_the_per_pair_loops() {
    let (means, quats, prev, nb) = fixture();
    assert!(nb.weight.iter().all(|&w| w > 0.05), "weights of order 1");
    let got = values(&means, &quats, &prev, &nb);
    let want = [
        rigidity_loop(&means, &quats, &prev, &nb),
        rotation_loop(&quats, &prev, &nb),
        isometry_loop(&means, &nb),
    ];
    for (g, w) in got.iter().zip(want) {
        // The same sums in another order, the rotation by another formula.
        assert!((g - w).abs() <= 1e-14 * w.abs(), "{got:?} vs {want:?}");
        assert!(w > 1e-3, "a term of the fixture vanishes: {want:?}");
    }
    let one = with_threads(1, || values(&means, &quats, &prev, &nb));
    let two = with_threads(2, || values(&means, &quats, &prev, &nb));
    assert_eq!(one, two);
    assert_eq!(one, got);
}

/// The gradient check of op `which` (0 rigidity, 1 rotation, 2 isometry) with its
/// deliberate fault on or off. Default tolerances: `atol` 1e-7, `rtol` 1e-5, far
/// below the gradients' size (the terms average over 120 pairs: gradients of order
/// 1e-3 to 1e-2).
fn check(which: usize, fault: bool) -> GradcheckReport {
    let (means, quats, prev, nb) = fixture();
    let cfg = GradcheckConfig::default();
    gradcheck(
        |t, v| match which {
            0 => t.apply1(
                Rigidity::new(nb.clone(), prev.clone()).faulty(fault),
                &[v[0], v[1]],
            ),
            1 => t.apply1(
                Similarity::new(nb.clone(), prev.clone()).faulty(fault),
                &[v[1]],
            ),
            _ => t.apply1(Isometry::new(nb.clone()).faulty(fault), &[v[0]]),
        },
        &[means, quats],
        &cfg,
    )
}

#[test]
fn backwards_match_finite_differences() {
    for which in 0..3 {
        let report = check(which, false);
        report.assert_passed();
        assert!(report.max_abs_err < 1e-9, "{report}");
    }
}

#[test]
fn a_broken_backward_is_rejected() {
    // Rigidity without the rotation's gradient, rotation similarity without the
    // neighbour's share, isometry with a factor 2.
    for which in 0..3 {
        let report = check(which, true);
        assert!(!report.passed(), "fault {which} was not caught");
    }
}
