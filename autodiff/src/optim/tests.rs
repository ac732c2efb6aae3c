//! Tests of Adam and its learning-rate schedules: the update against its formula by
//! hand, the subnormal guards, row scales across parallel blocks, L2 decay, zeroed
//! moments and the exponential schedule.

use super::*;

#[test]
fn first_two_steps_match_the_formula_by_hand() {
    let mut adam = Adam::<f64>::new(AdamConfig {
        beta1: 0.9,
        beta2: 0.999,
        eps: 1e-8,
    });
    let mut p = Tensor::from_vec(vec![1.0, -2.0], &[2]);
    adam.step("p", &mut p, &Tensor::from_vec(vec![0.5, -4.0], &[2]), 0.1);
    // Step 1: m_hat = g, v_hat = g^2, so the update is lr * g / (|g| + eps).
    let want0 = 1.0 - 0.1 * 0.5 / (0.5 + 1e-8);
    let want1 = -2.0 + 0.1 * 4.0 / (4.0 + 1e-8);
    assert!((p.data()[0] - want0).abs() < 1e-15 && (p.data()[1] - want1).abs() < 1e-15);
    adam.step("p", &mut p, &Tensor::from_vec(vec![1.0, 0.0], &[2]), 0.1);
    let m = 0.9 * 0.05 + 0.1 * 1.0;
    let v = 0.999 * 0.001 * 0.25 + 0.001 * 1.0;
    let (mh, vh) = (m / (1.0 - 0.81), v / (1.0 - 0.999f64.powi(2)));
    let want = want0 - 0.1 * mh / (vh.sqrt() + 1e-8);
    assert!(
        (p.data()[0] - want).abs() < 1e-14,
        "{} vs {want}",
        p.data()[0]
    );
}

/// Adam as written in the paper, with no guard: the oracle of the tests below.
fn plain_step(p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], t: i32, wd: f32) {
    // The constants as `step_rows` rounds them: bias corrections in f64.
    let (b1, b2, eps) = (0.9f32, 0.999f32, 1e-15f32);
    let step = (1e-3 / (1.0 - 0.9f64.powi(t))) as f32;
    let inv_c2 = (1.0 / (1.0 - 0.999f64.powi(t))) as f32;
    for i in 0..p.len() {
        let g = g[i] + wd * p[i];
        m[i] = b1 * m[i] + (1.0 - b1) * g;
        v[i] = b2 * v[i] + (1.0 - b2) * g * g;
        p[i] -= step * m[i] / ((v[i] * inv_c2).sqrt() + eps);
    }
}

fn subnormal(x: f32) -> bool {
    x != 0.0 && x.abs() < f32::MIN_POSITIVE
}

fn trainer_like_adam() -> Adam<f32> {
    Adam::new(AdamConfig {
        beta1: 0.9,
        beta2: 0.999,
        eps: 1e-15,
    })
}

#[test]
fn in_the_normal_range_the_guards_change_no_bit() {
    let n = 64;
    let mut adam = trainer_like_adam();
    let mut p = Tensor::from_vec((0..n).map(|i| (i as f32 * 0.37).sin()).collect(), &[n]);
    let (mut q, mut m, mut v) = (p.data().to_vec(), vec![0.0; n], vec![0.0; n]);
    for t in 1..=50 {
        let g: Vec<f32> = (0..n).map(|i| ((i * t) as f32 * 0.11).cos()).collect();
        adam.step_l2("p", &mut p, &Tensor::from_vec(g.clone(), &[n]), 1e-3, 8e-7);
        plain_step(&mut q, &g, &mut m, &mut v, t as i32, 8e-7);
        assert_eq!(p.data(), &q[..], "step {t}");
    }
}

#[test]
fn parameters_without_gradient_never_make_subnormal_moments() {
    // Plane cells that no Gaussian samples: zero gradient, L2 decay, values from
    // ordinary down to ones whose decay term underflows.
    let init: Vec<f32> = [1e-2, 3e-9, 1e-14, 1e-25, 1e-33, -1e-36, 0.0].to_vec();
    let n = init.len();
    let zero = vec![0.0f32; n];
    let mut adam = trainer_like_adam();
    let mut p = Tensor::from_vec(init.clone(), &[n]);
    let (mut q, mut m, mut v) = (init, vec![0.0; n], vec![0.0; n]);
    let mut plain_subnormals = 0;
    for t in 1..=3000 {
        adam.step_l2(
            "p",
            &mut p,
            &Tensor::from_vec(zero.clone(), &[n]),
            1e-3,
            8e-7,
        );
        plain_step(&mut q, &zero, &mut m, &mut v, t, 8e-7);
        plain_subnormals += m.iter().chain(&v).filter(|&&x| subnormal(x)).count();
        let mo = adam.moments("p").expect("moments");
        let stored = mo.m.data().iter().chain(mo.v.data()).chain(p.data());
        assert!(
            !stored.clone().any(|&x| subnormal(x)),
            "step {t}: {stored:?}"
        );
        assert!(p.data().iter().all(|x| x.is_finite()));
    }
    // The oracle does go subnormal on these inputs, so the check above is live.
    assert!(plain_subnormals > 100, "{plain_subnormals}");
}

#[test]
fn row_scales_stay_with_their_rows_across_parallel_blocks() {
    // Width 2: blocks of ADAM_BLOCK / 2 rows; rows on both sides of each boundary
    // must move at their own scaled rate.
    let (width, rows) = (2, 3 * ADAM_BLOCK / 4 + 5);
    let value = |k: usize| ((k as f64) * 0.713).sin();
    let init = Tensor::from_vec((0..rows * width).map(value).collect(), &[rows, width]);
    let grad = Tensor::from_vec(
        (0..rows * width).map(|k| value(k + 7) - 0.2).collect(),
        &[rows, width],
    );
    let scale: Vec<f64> = (0..rows).map(|r| 1.0 + (r % 7) as f64).collect();
    let cfg = AdamConfig::default();
    let mut all = Adam::<f64>::new(cfg.clone());
    let mut p = init.clone();
    for _ in 0..2 {
        all.step_rows("p", &mut p, &grad, 0.01, 0.1, Some(&scale));
    }
    let half = ADAM_BLOCK / width;
    for r in [0, half - 1, half, half + 1, rows - 1] {
        let mut one = Adam::<f64>::new(cfg.clone());
        let pick = |t: &Tensor<f64>| {
            Tensor::from_vec(t.data()[width * r..width * (r + 1)].to_vec(), &[1, width])
        };
        let mut q = pick(&init);
        for _ in 0..2 {
            one.step_l2("q", &mut q, &pick(&grad), 0.01 * scale[r], 0.1);
        }
        for c in 0..width {
            let (got, want) = (p.data()[width * r + c], q.data()[c]);
            assert!((got - want).abs() < 1e-14, "row {r}: {got} vs {want}");
        }
    }
}

#[test]
fn l2_decay_is_added_to_the_gradient_before_the_moments() {
    let cfg = AdamConfig {
        beta1: 0.9,
        beta2: 0.999,
        eps: 1e-8,
    };
    let (mut a, mut b) = (Adam::<f64>::new(cfg.clone()), Adam::<f64>::new(cfg));
    let (mut p, mut q) = (
        Tensor::from_vec(vec![2.0, -1.0], &[2]),
        Tensor::from_vec(vec![2.0, -1.0], &[2]),
    );
    for _ in 0..3 {
        let g = Tensor::from_vec(vec![0.3, 0.2], &[2]);
        a.step_l2("p", &mut p, &g, 0.1, 0.5);
        // The same update by hand: the decayed gradient through plain Adam.
        let g2 = g.zip_map(&q, |g, p| g + 0.5 * p);
        b.step("p", &mut q, &g2, 0.1);
    }
    assert_eq!(p, q);
    let m = a.moments("p").expect("moments");
    assert_ne!(m.m, Tensor::from_vec(vec![0.0; 2], &[2]));
}

#[test]
fn a_row_scale_equals_plain_adam_at_the_scaled_rate_row_by_row() {
    let cfg = AdamConfig::default();
    let scale = [1.0, 0.25, 40.0];
    let mut rows = Adam::<f64>::new(cfg.clone());
    let mut p = Tensor::from_vec(vec![1.0, -2.0, 0.5, 0.3, -0.7, 2.0], &[3, 2]);
    let init = p.clone();
    let grads: Vec<Tensor<f64>> = (0..4)
        .map(|k| {
            Tensor::from_vec(
                (0..6).map(|j| ((k * 6 + j) as f64).sin()).collect(),
                &[3, 2],
            )
        })
        .collect();
    for g in &grads {
        rows.step_rows("p", &mut p, g, 0.01, 0.1, Some(&scale));
    }
    for (r, &s) in scale.iter().enumerate() {
        // Each row alone through plain Adam with lr 0.01 * s.
        let mut one = Adam::<f64>::new(cfg.clone());
        let pick = |t: &Tensor<f64>| Tensor::from_vec(t.data()[2 * r..2 * r + 2].to_vec(), &[1, 2]);
        let mut q = pick(&init);
        for g in &grads {
            one.step_l2("q", &mut q, &pick(g), 0.01 * s, 0.1);
        }
        for c in 0..2 {
            let (got, want) = (p.data()[2 * r + c], q.data()[c]);
            assert!(
                (got - want).abs() < 1e-14,
                "row {r} col {c}: {got} vs {want}"
            );
        }
    }
    // A scale of 1 is plain Adam, to the bit.
    let (mut a, mut b) = (Adam::<f64>::new(cfg.clone()), Adam::<f64>::new(cfg));
    let (mut x, mut y) = (init.clone(), init);
    a.step_rows("p", &mut x, &grads[0], 0.01, 0.0, Some(&[1.0; 3]));
    b.step("p", &mut y, &grads[0], 0.01);
    assert_eq!(x, y);
}

#[test]
fn exp_decay_hits_both_ends_and_is_log_linear() {
    let s = LrSchedule::ExpDecay {
        init: 1.6e-4,
        last: 1.6e-6,
        max_steps: 100,
    };
    assert!((s.at(0) - 1.6e-4).abs() < 1e-18);
    assert!((s.at(100) - 1.6e-6).abs() < 1e-18);
    assert!((s.at(500) - 1.6e-6).abs() < 1e-18);
    assert!((s.at(50) - 1.6e-5).abs() < 1e-15);
    let frozen = LrSchedule::Until {
        lr: 0.05,
        until: 10,
    };
    assert_eq!(
        (frozen.at(9), frozen.at(10), frozen.at(99)),
        (0.05, 0.0, 0.0)
    );
}

#[test]
fn zeroed_moments_keep_their_step_count() {
    let mut adam = Adam::<f64>::new(AdamConfig::default());
    let mut x = Tensor::from_vec(vec![1.0, 2.0], &[2]);
    adam.step("x", &mut x, &Tensor::from_vec(vec![0.5, -0.5], &[2]), 0.1);
    assert!(adam.zero_moments("x"));
    let m = adam.moments("x").expect("moments");
    assert_eq!(
        (m.m.data(), m.v.data(), m.steps),
        (&[0.0, 0.0][..], &[0.0, 0.0][..], 1)
    );
    assert!(!adam.zero_moments("y"));
}

#[test]
fn adam_minimises_a_quadratic() {
    let mut adam = Adam::<f32>::new(AdamConfig::default());
    let mut x = Tensor::from_vec(vec![3.0f32, -2.0], &[2]);
    for _ in 0..500 {
        let g = x.map(|v| 2.0 * (v - 1.0));
        adam.step("x", &mut x, &g, 0.05);
    }
    assert!(
        x.data().iter().all(|v| (v - 1.0).abs() < 1e-2),
        "{:?}",
        x.data()
    );
}
