//! Changing the set of Gaussians: one densification plan resizes every per-Gaussian
//! container in lock-step, sensitivity pruning removes the lowest scores, and the
//! motion filter's observations are capped at max_views.

use super::*;

/// After clone, split and prune through `Trainer::apply_plan`, the parameters, their
/// Adam moments, the motion filter's curves, the observation table and the
/// densification statistics all have the new length, survivors keep their values
/// bit for bit, the overwritten rows carry the planned centres and scales, and
/// training goes on at the new size.
#[test]
fn one_plan_resizes_every_container_in_lock_step() {
    let (_tmp, data) = scene();
    let mut t = Trainer::new(&data, tiny_config(FilterKind::Motion)).expect("trainer");
    for _ in 0..45 {
        t.step();
    }
    let n = t.num_gaussians();
    assert!(n > 20, "{n} Gaussians");
    let before = params(&mut t);
    let per_gaussian: Vec<String> = t.state.model.params().per_gaussian_names();
    let moments: Vec<_> = per_gaussian
        .iter()
        .map(|p| {
            t.state
                .adam
                .moments(p)
                .expect("moments after 45 steps")
                .clone()
        })
        .collect();
    let nu_before = t.state.filter.variance_at(0.4);
    assert!(nu_before.iter().any(|&v| v > 0.0), "the filter has state");
    let obs_before: Vec<Vec<f32>> = (0..n)
        .map(|i| t.state.observations.row(i).to_vec())
        .collect();
    t.state.liveness.lowered[3] = true;
    let live_before = t.state.liveness.clone();

    // Prune rows 0 and 5, keep the rest, clone row 3, split row 7 (two halves, the
    // original dropped).
    let mut index: Vec<usize> = (0..n).filter(|&i| i != 0 && i != 5 && i != 7).collect();
    let survivors = index.len();
    index.extend([3, 7, 7]);
    let new_rows = vec![survivors + 1, survivors + 2];
    let new_means = vec![0.1, 0.2, 0.3, -0.1, -0.2, -0.3];
    let new_scales = vec![0.01, 0.02, 0.03, 0.04, 0.05, 0.06];
    let plan = DensifyPlan {
        index: index.clone(),
        new_rows: new_rows.clone(),
        new_means: new_means.clone(),
        new_scales: new_scales.clone(),
        cloned: 1,
        split: 1,
        pruned: 2,
    };
    t.state.apply_plan(&plan);

    let m = index.len();
    assert_eq!(t.num_gaussians(), m);
    assert_eq!(t.state.filter.rows(), m);
    assert_eq!(t.state.observations.rows(), m);
    assert_eq!(t.state.stats.grad_accum.len(), m);
    assert_eq!(t.state.stats.denom.len(), m);
    assert_eq!(t.state.stats.max_radii.len(), m);
    assert_eq!(t.state.liveness.rows(), m);
    let after = params(&mut t);
    for ((name, old), (_, new)) in before.iter().zip(&after) {
        if !per_gaussian.contains(name) {
            assert_eq!(old.data(), new.data(), "{name}: shared parameter changed");
            continue;
        }
        assert_eq!(new.rows(), m, "{name}");
        let w = old.len() / n;
        for (r, &i) in index.iter().enumerate() {
            if new_rows.contains(&r) && (name == "xyz" || name == "log_scale") {
                continue;
            }
            assert_eq!(
                &new.data()[r * w..(r + 1) * w],
                &old.data()[i * w..(i + 1) * w],
                "{name}: row {r} (old {i})"
            );
        }
    }
    for (p, old) in per_gaussian.iter().zip(&moments) {
        let new = t.state.adam.moments(p).expect("moments kept");
        assert_eq!(new.rows(), m, "{p} moments");
        let w = old.m.len() / n;
        for (r, &i) in index.iter().enumerate() {
            assert_eq!(
                &new.m.data()[r * w..(r + 1) * w],
                &old.m.data()[i * w..(i + 1) * w]
            );
            assert_eq!(
                &new.v.data()[r * w..(r + 1) * w],
                &old.v.data()[i * w..(i + 1) * w]
            );
        }
    }
    let nu_after = t.state.filter.variance_at(0.4);
    for (r, &i) in index.iter().enumerate() {
        assert_eq!(
            nu_after[r].to_bits(),
            nu_before[i].to_bits(),
            "filter row {r}"
        );
        assert_eq!(
            t.state.observations.row(r),
            obs_before[i].as_slice(),
            "observations row {r}"
        );
        assert_eq!(
            (t.state.liveness.last_grad[r], t.state.liveness.lowered[r]),
            (live_before.last_grad[i], live_before.lowered[i]),
            "liveness row {r}"
        );
    }
    // The planned centres and scales landed in the new rows.
    let canon = t.state.canonical();
    for (j, &r) in new_rows.iter().enumerate() {
        assert_eq!(
            &canon.means.data()[3 * r..3 * r + 3],
            &new_means[3 * j..3 * j + 3]
        );
        let s = &canon.scales.data()[3 * r..3 * r + 3];
        for (a, b) in s.iter().zip(&new_scales[3 * j..3 * j + 3]) {
            assert!((a - b).abs() <= 1e-6 * b, "scale of row {r}: {a} vs {b}");
        }
    }
    for _ in 0..3 {
        t.step();
    }
    assert_eq!(t.skipped_steps, 0);
    assert_eq!(t.num_gaussians(), m);
}

/// Sensitivity pruning at its scheduled iteration removes exactly the lowest-scoring
/// fraction (the scores of the model it prunes, `keep_highest` of them), keeps the
/// survivors' parameters and densification statistics, and training goes on.
#[test]
fn sensitivity_pruning_removes_the_lowest_scores_at_its_iteration() {
    let (_tmp, data) = scene();
    for kind in ["saro", "deform"] {
        let mut c = tiny_config_of(kind, FilterKind::Motion);
        c.prune.every = 30;
        c.prune.from = 30;
        c.prune.until = 30;
        c.prune.ratio_densifying = 0.5;
        let mut t = Trainer::new(&data, c).expect("trainer");
        for _ in 0..29 {
            t.step();
        }
        t.update();
        let n = t.num_gaussians();
        let scores = t.sensitivity_scores(t.iteration).expect("scores");
        assert_eq!(scores.len(), n);
        assert!(scores.iter().all(|s| s.is_finite() && *s >= 0.0));
        assert!(scores.iter().any(|&s| s > 0.0), "{kind}: every score is 0");
        let keep = keep_highest(&scores, 0.5);
        let xyz = t.state.canonical().means;
        let grad_accum = t.state.stats.grad_accum.clone();
        t.schedule();
        assert_eq!(t.num_gaussians(), keep.len(), "{kind}");
        assert_eq!(keep.len(), n - n / 2);
        assert_eq!(t.state.filter.rows(), keep.len());
        assert_eq!(t.state.observations.rows(), keep.len());
        let after = t.state.canonical().means;
        for (r, &i) in keep.iter().enumerate() {
            assert_eq!(
                &after.data()[3 * r..3 * r + 3],
                &xyz.data()[3 * i..3 * i + 3]
            );
            assert_eq!(
                t.state.stats.grad_accum[r], grad_accum[i],
                "{kind}: stats row {r}"
            );
        }
        for _ in 0..3 {
            t.step();
        }
        assert_eq!(t.skipped_steps, 0, "{kind}");
    }
}

#[test]
fn the_motion_filter_observes_at_most_max_views_and_the_others_none() {
    let (_tmp, data) = scene();
    let cfg = tiny_config(FilterKind::Motion);
    let mut full = Trainer::new(&data, cfg.clone()).expect("trainer");
    for _ in 0..25 {
        full.step();
    }
    let views = full.state.observations.num_frames();
    assert!(
        views > 50,
        "the scene has more than 50 training views ({views})"
    );
    let dir = std::env::temp_dir().join(format!("maaf_max_views_{}", std::process::id()));
    save_checkpoint(&full, &dir).expect("checkpoint");

    // Capped at 50: the table holds 50 frames, and a branch from a checkpoint that
    // observed every view reads exactly the kept views' columns.
    let mut capped_cfg = cfg.clone();
    capped_cfg.filter.max_views = 50;
    let mut capped = Trainer::new(&data, capped_cfg).expect("trainer");
    assert_eq!(capped.state.observations.num_frames(), 50);
    capped.branch_from(&dir).expect("branch");
    let frames: Vec<CameraTime> = full
        .state
        .observations
        .times()
        .iter()
        .enumerate()
        .map(|(camera, &time)| CameraTime { camera, time })
        .collect();
    let kept = observed_frames(&frames, 50);
    for (k, &f) in kept.iter().enumerate() {
        assert_eq!(
            capped.state.observations.times()[k],
            frames[f].time,
            "frame {k}"
        );
    }
    assert_eq!(capped.num_gaussians(), full.num_gaussians());
    for n in 0..full.num_gaussians() {
        let (a, b) = (
            full.state.observations.row(n),
            capped.state.observations.row(n),
        );
        assert!(
            kept.iter().zip(b).all(|(&f, &x)| a[f] == x),
            "Gaussian {n}: columns not the kept views'"
        );
    }
    for _ in 0..10 {
        capped.step();
    }
    assert!(
        (0..capped.num_gaussians()).any(|n| capped
            .state
            .observations
            .row(n)
            .iter()
            .any(|&x| x > 0.0)),
        "the capped table is recorded"
    );

    // The static filter reads no observation: none are kept or saved.
    let mut stat = Trainer::new(&data, tiny_config(FilterKind::Mip3d)).expect("trainer");
    stat.step();
    assert_eq!(stat.state.observations.num_frames(), 0);
    save_checkpoint(&stat, &dir).expect("checkpoint");
    let blob = std::fs::read(dir.join("tensors.safetensors")).expect("blob");
    let names = safetensors::SafeTensors::deserialize(&blob)
        .expect("safetensors")
        .names()
        .into_iter()
        .map(str::to_string)
        .collect::<Vec<_>>();
    assert!(!names.iter().any(|n| n == "observations"), "{names:?}");
    let loaded = load_checkpoint(&data, &dir).expect("load");
    assert_eq!(loaded.iteration, 1);
    std::fs::remove_dir_all(&dir).ok();
}
