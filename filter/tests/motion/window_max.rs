//! maaf's windowed-maximum estimator against its brute-force oracle, on an approaching
//! Gaussian and on a static scene.

use super::*;

/// maaf's windowed-maximum estimator: the fast path against the literal oracle
/// ([`window_max`]) on the same random tables and layouts as the KDE, including a
/// time range other than [0, 1], a narrow and a wide window and a coarse grid.
#[test]
fn fast_window_max_equals_brute_force() {
    let window = |cfg: FilterConfig| FilterConfig {
        estimator: MotionEstimator::WindowMax,
        ..cfg
    };
    let configs = [
        window(FilterConfig::default()),
        window(FilterConfig {
            h_t: 0.01,
            grid_x: 21,
            grid_t: 23,
            ..FilterConfig::default()
        }),
        window(FilterConfig {
            h_t: 0.2,
            time_range: [-1.0, 3.0],
            grid_x: 255,
            grid_t: 40,
            ..FilterConfig::default()
        }),
    ];
    let mut rng = Pcg64::seed_from_u64(13);
    let (mut bins, mut fallbacks, mut exact) = (0usize, 0usize, 0usize);
    for (ci, cfg) in configs.iter().enumerate() {
        for (kind, table) in layout_tables(ci == 2, &mut rng).into_iter().enumerate() {
            let curves = MotionCurves::refresh(&table, cfg).expect("refresh");
            for n in 0..table.rows() {
                let (ts, xs) = oracle_inputs(&table, n, cfg);
                let want = window_max(&ts, &xs, cfg);
                let x_max = xs.iter().copied().fold(0.0f64, f64::max);
                assert_eq!(curves.x_max()[n] as f64, x_max, "x_max, cfg {ci}");
                let step = x_max / (cfg.grid_x - 1) as f64;
                for (s, w) in want.iter().enumerate() {
                    bins += 1;
                    let code = curves.codes(n)[s];
                    let Some(w) = *w else {
                        assert_eq!(code, FALLBACK, "cfg {ci} kind {kind} n {n} s {s}");
                        fallbacks += 1;
                        continue;
                    };
                    assert_ne!(code, FALLBACK, "cfg {ci} kind {kind} n {n} s {s}");
                    // Rounded up to the grid: never below the maximum, under a step above.
                    let nu = curves.nu(n, s) as f64;
                    assert!(
                        nu >= w * (1.0 - 1e-6) && nu < w + step * (1.0 + 1e-5),
                        "cfg {ci} kind {kind} n {n} s {s}: {nu} vs window max {w} (step {step})"
                    );
                    if (nu - w).abs() <= 1e-6 * w {
                        exact += 1;
                    }
                }
            }
        }
    }
    eprintln!("{bins} bins, {fallbacks} fallback, {exact} on a grid point");
    assert!(fallbacks > 0 && fallbacks < bins / 2, "fallback exercised");
    assert!(
        exact > 0 && exact < bins - fallbacks,
        "both roundings exercised"
    );
}

/// A Gaussian approaching a camera from f/d = 10 to 50: the windowed maximum
/// follows f/d(t) to within the window and a grid step, where the paper's KDE sits
/// up to `lambda h_x x_max = 15` above it (its Weibull bias, Sec. 4).
#[test]
fn window_max_follows_a_gaussian_moving_toward_the_camera() {
    let kde = FilterConfig::default();
    let ours = FilterConfig {
        estimator: MotionEstimator::WindowMax,
        ..FilterConfig::default()
    };
    let table = approaching_gaussian();
    let window = MotionCurves::refresh(&table, &ours)
        .expect("refresh")
        .curve(0);
    let paper = MotionCurves::refresh(&table, &kde)
        .expect("refresh")
        .curve(0);
    let step = 50.0 / 100.0;
    for (s, (&nu, &nu_kde)) in window.iter().zip(&paper).enumerate() {
        let t = s as f32 / 99.0;
        let (now, ahead) = (100.0 / depth(t), 100.0 / depth((t + 0.05).min(1.0)));
        assert!(nu >= now * 0.999, "s {s}: nu {nu} below f/d {now}");
        assert!(
            nu <= ahead + step * 1.001,
            "s {s}: nu {nu} above the window's {ahead}"
        );
        assert!(nu <= nu_kde, "s {s}: ours {nu} above the KDE's {nu_kde}");
    }
    // At t = 0 the KDE is near f/d + 0.3 x_max = 25; the window's maximum is 10.4.
    assert!(
        window[0] < 11.0 && paper[0] > 20.0,
        "{} vs {}",
        window[0],
        paper[0]
    );
}

/// Static Gaussians seen by several cameras at every time: the windowed maximum is
/// Mip-Splatting's static nu at every time bin.
#[test]
fn window_max_of_a_static_scene_is_the_static_nu() {
    let cfg = FilterConfig {
        estimator: MotionEstimator::WindowMax,
        ..FilterConfig::default()
    };
    let cameras = three_cameras();
    let frames = multiview_frames(40, 3);
    let centres = vec![[0.0f32, 0.0, 0.0], [0.1, 0.2, 0.5], [0.3, -0.2, 1.0]];
    let mut table = ObservationTable::for_frames(&frames, centres.len());
    table
        .observe_all(&frames, &cameras, &cfg, |_| centres.clone())
        .expect("observe");
    let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
    let nu = static_nu(&centres, &cameras, &cfg).expect("visible");
    for (n, &nu_n) in nu.iter().enumerate() {
        assert!(curves.curve(n).iter().all(|&v| v == nu_n), "{n}: {nu_n}");
    }
}
