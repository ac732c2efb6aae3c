//! The observations the motion filter is computed from: the incremental recorder, row
//! selection, and the capped set of observed frames.

use super::*;

#[test]
fn incremental_recorder_equals_full_pass_when_fresh() {
    let cfg = FilterConfig::default();
    let cameras = [cam(3.0, 120.0, 0.0), cam(4.0, 200.0, 0.5)];
    let frames: Vec<CameraTime> = (0..20)
        .map(|i| CameraTime {
            camera: i % 2,
            time: i as f32 / 19.0,
        })
        .collect();
    let deform = |t: f32| -> Vec<[f32; 3]> {
        (0..50)
            .map(|i| {
                let a = i as f32 * 0.1;
                [a.sin(), a.cos() * t, 2.0 * t - a * 0.1]
            })
            .collect()
    };
    let mut full = ObservationTable::for_frames(&frames, 50);
    full.observe_all(&frames, &cameras, &cfg, deform)
        .expect("observe");
    let mut inc = ObservationTable::for_frames(&frames, 50);
    for (f, fr) in frames.iter().enumerate().rev() {
        inc.record_centres(f, &cameras[fr.camera], &deform(fr.time), &cfg)
            .expect("record");
    }
    assert_eq!(full, inc);
    // record_depths with the same visibility gives the same slots.
    let mut dep = ObservationTable::for_frames(&frames, 50);
    for (f, fr) in frames.iter().enumerate() {
        let v = maaf_filter::Viewer::new(&cameras[fr.camera], &cfg);
        let depths: Vec<f32> = deform(fr.time)
            .iter()
            .map(|&p| v.visible_depth(p).map_or(-1.0, |z| z as f32))
            .collect();
        dep.record_depths(f, v.focal as f32, &depths)
            .expect("record");
    }
    for n in 0..50 {
        for (a, b) in full.row(n).iter().zip(dep.row(n)) {
            // focal/z in f64 then rounded vs f32 division: 1 ulp.
            assert!((a - b).abs() <= 1e-6 * a.abs(), "{a} vs {b}");
        }
    }
    // record_present: flagged rows as record_centres, the others empty.
    let present: Vec<bool> = (0..50).map(|n| n % 3 != 0).collect();
    let mut part = ObservationTable::for_frames(&frames, 50);
    for (f, fr) in frames.iter().enumerate() {
        part.record_present(f, &cameras[fr.camera], &deform(fr.time), &present, &cfg)
            .expect("record");
    }
    for (n, &seen) in present.iter().enumerate() {
        if seen {
            assert_eq!(part.row(n), full.row(n), "row {n}");
        } else {
            assert!(part.row(n).iter().all(|&x| x == 0.0), "row {n} not empty");
        }
    }
    assert!(
        full.row(0).iter().any(|&x| x > 0.0),
        "row 0 is seen somewhere"
    );
    assert!(
        part.record_present(0, &cameras[0], &deform(0.0), &present[..3], &cfg)
            .is_err()
    );
    assert!(
        inc.record_centres(20, &cameras[0], &deform(0.0), &cfg)
            .is_err()
    );
    assert!(
        inc.record_centres(0, &cameras[0], &deform(0.0)[..3], &cfg)
            .is_err()
    );
}

#[test]
fn per_gaussian_resize_keeps_survivors_values() {
    let mut rng = Pcg64::seed_from_u64(3);
    let cfg = FilterConfig::default();
    let table = random_table(frame_times(0, &mut rng), 12, &mut rng);
    let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
    // keep 0, clone 2, split 5 (twice, original dropped), prune the rest.
    let index = [0, 2, 2, 5, 5];
    let mut t2 = table.clone();
    t2.select_rows(&index);
    let mut c2 = curves.clone();
    c2.select_rows(&index);
    assert_eq!((t2.rows(), c2.rows()), (5, 5));
    for (new, &old) in index.iter().enumerate() {
        assert_eq!(t2.row(new), table.row(old));
        assert_eq!(c2.curve(new), curves.curve(old));
        assert_eq!(c2.x_max()[new], curves.x_max()[old]);
    }
    let mut state = FilterState::Motion {
        s3d: 0.2,
        curves: curves.clone(),
    };
    let before = state.variance_at(0.4);
    state.select_rows(&index);
    let after = state.variance_at(0.4);
    for (new, &old) in index.iter().enumerate() {
        assert_eq!(after[new], before[old]);
    }
    let mut mip = FilterState::Mip3d {
        s3d: 0.2,
        nu: vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
    };
    mip.select_rows(&index);
    assert_eq!(mip.variance_at(0.0)[3], 0.2 / 36.0);
    let mut none = FilterState::None { rows: 6 };
    none.select_rows(&index);
    assert_eq!(none.variance_at(0.0), vec![0.0; 5]);
}

#[test]
fn observed_frames_keep_every_camera_of_an_even_stride_of_times() {
    // Panoptic basketball's layout: 27 training cameras at 150 times.
    let frames = multiview_frames(150, 27);
    let few = &frames[..100];
    assert_eq!(observed_frames(few, 1024), (0..100).collect::<Vec<_>>());
    let kept = observed_frames(&frames, 1024);
    // 1024 / 27 = 37 whole times, 999 frames, every camera of each.
    assert_eq!(kept.len(), 37 * 27);
    let mut per_time = vec![0usize; 150];
    for &f in &kept {
        per_time[f / 27] += 1;
    }
    let times: Vec<usize> = (0..150).filter(|&t| per_time[t] > 0).collect();
    assert!(times.iter().all(|&t| per_time[t] == 27), "{per_time:?}");
    assert_eq!(times.len(), 37);
    // Evenly spread: the first time, and steps of 4 or 5 of the 150.
    assert_eq!(times[0], 0);
    assert!(
        times
            .windows(2)
            .all(|w| w[1] - w[0] == 4 || w[1] - w[0] == 5),
        "{times:?}"
    );
    // One time with more cameras than the bound: an even stride of its cameras.
    let one: Vec<CameraTime> = (0..27)
        .map(|camera| CameraTime { camera, time: 0.5 })
        .collect();
    assert_eq!(
        observed_frames(&one, 9),
        (0..27).step_by(3).collect::<Vec<_>>()
    );
}

#[test]
fn capped_observations_follow_an_approaching_gaussian_like_all_of_them() {
    // Nine cameras at several distances and focals, 60 times; one Gaussian comes
    // from depth 8 to 1.5 along the axis, one stays.
    let cameras: Vec<Camera> = (0..9)
        .map(|c| {
            cam(
                1.0 + 0.5 * c as f64,
                80.0 + 15.0 * c as f64,
                0.05 * c as f64,
            )
        })
        .collect();
    let frames = multiview_frames(60, 9);
    let centres = |t: f32| vec![[0.0f32, 0.0, 8.0 - 6.5 * t], [0.1, -0.1, 3.0]];
    let cfg = FilterConfig::default();
    let curves = |kept: &[usize]| {
        let sub: Vec<CameraTime> = kept.iter().map(|&f| frames[f]).collect();
        let mut table = ObservationTable::for_frames(&sub, 2);
        table
            .observe_all(&sub, &cameras, &cfg, centres)
            .expect("observe");
        MotionCurves::refresh(&table, &cfg).expect("refresh")
    };
    let all = curves(&observed_frames(&frames, frames.len()));
    // A third of the views: every camera at 20 of the 60 times.
    let third = curves(&observed_frames(&frames, frames.len() / 3));
    for n in 0..2 {
        let (a, b) = (all.curve(n), third.curve(n));
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs() / x)
            .fold(0.0f32, f32::max);
        assert!(
            worst < 0.1,
            "Gaussian {n}: nu(t) off by {worst}: {a:?} vs {b:?}"
        );
        eprintln!("Gaussian {n}: worst relative nu difference {worst}");
    }
}
