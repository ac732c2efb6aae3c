//! The motion-aware filter against brute-force Algorithm 1, and its properties (the
//! windowed-maximum estimator in `window_max.rs`, the observations both are computed
//! from in `observations.rs`).

use maaf_autodiff::PerGaussian;
use maaf_filter::reference::{algorithm1, window_max};
use maaf_filter::{
    CameraTime, FALLBACK, FilterConfig, FilterState, Kernels, MotionCurves, MotionEstimator,
    ObservationTable, observed_frames, static_nu,
};
use maaf_splat::Camera;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

mod observations;
mod window_max;

/// Random observation table: `times` per frame; per Gaussian one of several
/// patterns (uniform noise, smooth trajectory + noise, constant, empty, sparse).
fn random_table(times: Vec<f32>, rows: usize, rng: &mut Pcg64) -> ObservationTable {
    let mut table = ObservationTable::new(times.clone(), rows);
    for n in 0..rows {
        let pattern = n % 6;
        let base = rng.random_range(5.0f32..500.0);
        let amp = rng.random_range(0.0f32..0.9);
        let phase = rng.random_range(0.0f32..std::f32::consts::TAU);
        let p_empty = [0.0f32, 0.3, 0.0, 0.8, 1.0, 0.1][pattern];
        let row = table.row_mut(n);
        for (f, x) in row.iter_mut().enumerate() {
            if rng.random_range(0.0f32..1.0) < p_empty {
                continue;
            }
            let t = times[f];
            *x = match pattern {
                0 | 3 => base * rng.random_range(0.2f32..1.0),
                2 => base,
                _ => {
                    base * (1.0 - amp * (0.5 + 0.5 * (6.0 * t + phase).sin()))
                        * rng.random_range(0.95f32..1.05)
                }
            };
        }
    }
    table
}

/// D-NeRF-like (distinct times), multi-view-like (shared times) and irregular
/// frame times with a gap.
fn frame_times(kind: usize, rng: &mut Pcg64) -> Vec<f32> {
    match kind {
        0 => (0..60).map(|i| i as f32 / 59.0).collect(),
        1 => (0..12)
            .flat_map(|i| std::iter::repeat_n(i as f32 / 11.0, 5))
            .collect(),
        _ => (0..40)
            .map(|_| {
                let t = rng.random_range(0.0f32..1.0);
                if (0.4..0.7).contains(&t) { t * 0.5 } else { t }
            })
            .collect(),
    }
}

/// One random table of 18 Gaussians per frame layout of [`frame_times`], with the
/// times mapped from [0, 1] to [-1, 3] when `wide_range` (exercises `time_range`).
fn layout_tables(wide_range: bool, rng: &mut Pcg64) -> Vec<ObservationTable> {
    (0..3)
        .map(|kind| {
            let mut times = frame_times(kind, rng);
            if wide_range {
                times.iter_mut().for_each(|t| *t = *t * 4.0 - 1.0);
            }
            random_table(times, 18, rng)
        })
        .collect()
}

/// Algorithm 1 (oracle) inputs for Gaussian `n`: normalised times with empty slots
/// flagged by t < 0 (Alg. 1 line 2) and x.
fn oracle_inputs(table: &ObservationTable, n: usize, cfg: &FilterConfig) -> (Vec<f64>, Vec<f64>) {
    table
        .row(n)
        .iter()
        .zip(table.times())
        .map(|(&x, &t)| {
            if x > 0.0 {
                (cfg.normalise_time(t) as f64, x as f64)
            } else {
                (-1.0, 0.0)
            }
        })
        .unzip()
}

#[test]
fn fast_refresh_equals_brute_force_algorithm1() {
    let configs = [
        FilterConfig::default(),
        FilterConfig {
            h_x: 0.1,
            grid_x: 37,
            grid_t: 23,
            ..FilterConfig::default()
        },
        FilterConfig {
            weibull_k: 3.5,
            weibull_lambda: 0.5,
            h_t: 0.2,
            ..FilterConfig::default()
        },
        FilterConfig {
            weibull_k: 1.0,
            time_range: [-1.0, 3.0],
            time_support: 2.5,
            grid_x: 255,
            grid_t: 40,
            ..FilterConfig::default()
        },
    ];
    let mut rng = Pcg64::seed_from_u64(5);
    let (mut bins, mut ties, mut fallbacks) = (0usize, 0usize, 0usize);
    for (ci, cfg) in configs.iter().enumerate() {
        cfg.validate().expect("valid config");
        let kern = Kernels::new(cfg);
        for (kind, table) in layout_tables(ci == 3, &mut rng).into_iter().enumerate() {
            let curves = MotionCurves::refresh(&table, cfg).expect("refresh");
            for n in 0..table.rows() {
                let (ts, xs) = oracle_inputs(&table, n, cfg);
                let oracle = algorithm1(&ts, &xs, cfg, &kern);
                assert_eq!(curves.x_max()[n] as f64, oracle.x_max, "x_max, cfg {ci}");
                let want = oracle.codes(cfg.density_floor as f64);
                let got = curves.codes(n);
                for s in 0..cfg.grid_t {
                    bins += 1;
                    let (g, w) = (got[s], want[s]);
                    if w == FALLBACK {
                        fallbacks += 1;
                    }
                    if g == w {
                        continue;
                    }
                    // Only a tie within float error may differ: neighbouring bins whose
                    // f64 densities agree to 1e-5 relative. The f32 fast path sums up to J
                    // terms (relative error <= J eps32 = 60 x 6e-8 = 4e-6) of kernels whose
                    // f32 evaluation is good to ~1e-6 relative (k-fold amplification of
                    // the argument's rounding), so 1e-5 bounds its error.
                    assert!(
                        g != FALLBACK && w != FALLBACK && g.abs_diff(w) <= 1,
                        "cfg {ci} kind {kind} n {n} s {s}: fast {g} vs oracle {w}"
                    );
                    let (rg, rw) = (oracle.at(g as usize, s), oracle.at(w as usize, s));
                    assert!(
                        rg >= rw * (1.0 - 1e-5),
                        "cfg {ci} kind {kind} n {n} s {s}: not a tie: {rg} vs {rw}"
                    );
                    ties += 1;
                }
            }
        }
    }
    eprintln!("{bins} bins compared, {ties} float ties, {fallbacks} fallback bins");
    assert!(fallbacks > 0 && fallbacks < bins / 2, "fallback exercised");
    assert!(ties * 1000 < bins, "ties must be rare: {ties} of {bins}");
}

#[test]
fn kernel_truncation_changes_few_argmaxes() {
    // Measures the two truncations (time support 4 h_t, Weibull below 1e-7 of its
    // peak) against the untruncated kernels of Algorithm 1, on the oracle.
    let cfg = FilterConfig::default();
    let wide = FilterConfig {
        time_support: 40.0,
        weibull_cutoff: 1e-30,
        ..FilterConfig::default()
    };
    let (k1, k2) = (Kernels::new(&cfg), Kernels::new(&wide));
    let mut rng = Pcg64::seed_from_u64(9);
    let (mut both, mut same, mut fallback_only_truncated) = (0usize, 0usize, 0usize);
    for kind in 0..3 {
        let table = random_table(frame_times(kind, &mut rng), 12, &mut rng);
        for n in 0..table.rows() {
            let (ts, xs) = oracle_inputs(&table, n, &cfg);
            let a = algorithm1(&ts, &xs, &cfg, &k1).codes(cfg.density_floor as f64);
            let b = algorithm1(&ts, &xs, &wide, &k2).codes(cfg.density_floor as f64);
            for (x, y) in a.iter().zip(&b) {
                if *x == FALLBACK && *y != FALLBACK {
                    fallback_only_truncated += 1;
                } else if *y != FALLBACK {
                    both += 1;
                    same += usize::from(x == y);
                }
            }
        }
    }
    eprintln!(
        "truncation: {same}/{both} argmax bins identical, {fallback_only_truncated} bins fall back only when truncated"
    );
    assert!(same as f64 >= 0.99 * both as f64, "{same}/{both}");
}

/// Camera at `(0, 0, -dist)` looking down +z (OpenCV), 200x200 px, focal `f`.
fn cam(dist: f64, f: f64, x_offset: f64) -> Camera {
    let mut w2c = [[0.0; 4]; 4];
    for (i, row) in w2c.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    w2c[0][3] = x_offset;
    w2c[2][3] = dist;
    Camera::new(200, 200, f, f, 100.0, 100.0, w2c).expect("camera")
}

/// Three cameras at different distances, one with another focal.
fn three_cameras() -> [Camera; 3] {
    [
        cam(2.0, 100.0, 0.0),
        cam(3.0, 100.0, 0.1),
        cam(5.0, 150.0, -0.2),
    ]
}

/// Multi-view video layout: every one of `cameras` cameras at each of `times`
/// evenly spaced times in [0, 1].
fn multiview_frames(times: usize, cameras: usize) -> Vec<CameraTime> {
    (0..times)
        .flat_map(|i| {
            (0..cameras).map(move |c| CameraTime {
                camera: c,
                time: i as f32 / (times - 1) as f32,
            })
        })
        .collect()
}

#[test]
fn static_gaussian_at_constant_f_over_d_gives_constant_nu() {
    let cfg = FilterConfig::default();
    // Three cameras at different distances: each sees the static Gaussian at its own
    // constant f/d, at every one of 50 times (multi-view video layout).
    let cameras = three_cameras();
    let frames = multiview_frames(50, 3);
    let centres = vec![[0.0f32, 0.0, 0.0], [0.1, 0.2, 0.5]];
    let mut table = ObservationTable::for_frames(&frames, centres.len());
    table
        .observe_all(&frames, &cameras, &cfg, |_| centres.clone())
        .expect("observe");
    let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
    for n in 0..centres.len() {
        let curve = curves.curve(n);
        assert!(curve.iter().all(|&v| v == curve[0]), "{n}: {curve:?}");
        assert!(
            curves.codes(n).iter().all(|&c| c != FALLBACK),
            "density > 0"
        );
    }
    // A single camera: every observation sits at x_max, where the one-sided Weibull
    // kernel is zero (Alg. 1 line 1, K_w(0) = 0 for k > 1): the density is zero and
    // nu falls back to the static value x_max, constant.
    let mut single = ObservationTable::new(vec![0.0, 0.25, 0.5, 0.75, 1.0], 1);
    single.row_mut(0).fill(40.0);
    let curves = MotionCurves::refresh(&single, &cfg).expect("refresh");
    assert!(curves.curve(0).iter().all(|&v| v == 40.0));
}

/// Depth of [`approaching_gaussian`] at time t: from 10 down to 2 (x = f/z from 10
/// to 50 with f = 100).
fn depth(t: f32) -> f32 {
    10.0 - 8.0 * t
}

/// One Gaussian on the axis of one camera (focal 100) at 150 times, approaching it
/// from depth 10 to 2 (D-NeRF layout).
fn approaching_gaussian() -> ObservationTable {
    let cameras = [cam(0.0, 100.0, 0.0)];
    let frames: Vec<CameraTime> = (0..150)
        .map(|i| CameraTime {
            camera: 0,
            time: i as f32 / 149.0,
        })
        .collect();
    let mut table = ObservationTable::for_frames(&frames, 1);
    table
        .observe_all(&frames, &cameras, &FilterConfig::default(), |t| {
            vec![[0.0, 0.0, depth(t)]]
        })
        .expect("observe");
    table
}

#[test]
fn gaussian_moving_toward_the_camera_gets_increasing_nu() {
    let cfg = FilterConfig::default();
    let table = approaching_gaussian();
    let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
    let curve = curves.curve(0);
    for w in curve.windows(2) {
        assert!(w[1] >= w[0], "non-decreasing: {curve:?}");
    }
    // From f/d + 0.3 x_max = 25 at t = 0 up to x_max = 50 at t = 1.
    assert!(curve[99] >= 2.0 * curve[0], "{curve:?}");
    // The curve tracks the motion: nu(t) >= f/d(t) (the Weibull kernel biases the
    // mode upward, paper Sec. 4), and stays within 0.3 x_max + 2 grid steps of it.
    let x_max = curves.x_max()[0];
    for (s, &nu) in curve.iter().enumerate() {
        let x = 100.0 / depth(s as f32 / 99.0);
        assert!(nu >= x * 0.99, "s {s}: nu {nu} < f/d {x}");
        assert!(nu <= x + 0.32 * x_max, "s {s}: nu {nu} far above f/d {x}");
    }
}

#[test]
fn nu_is_positive_and_finite_everywhere() {
    let mut rng = Pcg64::seed_from_u64(7);
    let cfg = FilterConfig::default();
    for kind in 0..3 {
        let times = frame_times(kind, &mut rng);
        let table = random_table(times, 60, &mut rng);
        let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
        for n in 0..table.rows() {
            for s in 0..cfg.grid_t {
                let nu = curves.nu(n, s);
                assert!(nu.is_finite() && nu > 0.0, "n {n} s {s}: {nu}");
            }
        }
        let bins: Vec<f32> = (0..cfg.grid_t).map(|s| curves.bin_time(s)).collect();
        let state = FilterState::Motion {
            s3d: cfg.s3d,
            curves,
        };
        // The widest filter over time is the largest variance at any bin's time.
        let widest = bins.iter().fold(vec![0.0f32; table.rows()], |acc, &t| {
            let v = state.variance_at(t);
            acc.iter().zip(&v).map(|(a, b)| a.max(*b)).collect()
        });
        assert_eq!(state.max_variance(), widest);
        for t in [-0.5f32, 0.0, 0.3, 1.0, 2.0] {
            assert!(
                state
                    .variance_at(t)
                    .iter()
                    .all(|v| v.is_finite() && *v >= 0.0)
            );
        }
    }
}

#[test]
fn static_scene_static_nu_equals_motion_x_max() {
    let cfg = FilterConfig::default();
    let cameras = [
        cam(3.0, 120.0, 0.0),
        cam(4.0, 200.0, 0.5),
        cam(2.5, 90.0, -0.3),
    ];
    // D-NeRF layout: one camera per time.
    let frames: Vec<CameraTime> = (0..30)
        .map(|i| CameraTime {
            camera: i % 3,
            time: i as f32 / 29.0,
        })
        .collect();
    let mut rng = Pcg64::seed_from_u64(11);
    // Some centres are off-screen for every camera (|x| up to 8 at depth ~3).
    let centres: Vec<[f32; 3]> = (0..200)
        .map(|_| {
            [
                rng.random_range(-8.0f32..8.0),
                rng.random_range(-2.0f32..2.0),
                rng.random_range(-1.0f32..3.0),
            ]
        })
        .collect();
    let mut table = ObservationTable::for_frames(&frames, centres.len());
    table
        .observe_all(&frames, &cameras, &cfg, |_| centres.clone())
        .expect("observe");
    let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
    let nu = static_nu(&centres, &cameras, &cfg).expect("visible");
    let mut unseen = 0;
    for (n, &nu_n) in nu.iter().enumerate() {
        if curves.x_max()[n] > 0.0 {
            assert_eq!(nu_n, curves.x_max()[n], "Gaussian {n}");
        } else {
            unseen += 1;
        }
        // Fallbacks equal the static nu too (unseen: smallest nu seen).
        assert_eq!(nu_n, curves.fallback()[n], "fallback {n}");
    }
    assert!(unseen > 0 && unseen < centres.len(), "both cases exercised");
}

#[test]
fn nothing_visible_is_an_error_not_a_zero_nu() {
    let cfg = FilterConfig::default();
    // An invalid config is refused by refresh too, before any work.
    let bad = FilterConfig {
        grid_x: 300,
        ..FilterConfig::default()
    };
    let err =
        MotionCurves::refresh(&ObservationTable::new(vec![0.0], 1), &bad).expect_err("bad config");
    assert!(err.to_string().contains("`grid_x`"), "{err}");
    let table = ObservationTable::new(vec![0.0, 1.0], 3);
    assert!(MotionCurves::refresh(&table, &cfg).is_err());
    let empty = ObservationTable::new(vec![0.0, 1.0], 0);
    assert_eq!(
        MotionCurves::refresh(&empty, &cfg)
            .expect("empty ok")
            .rows(),
        0
    );
}
