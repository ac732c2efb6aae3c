//! Training smoke tests on the real D-NeRF mutant scene at a tiny scale: the loss
//! falls, resume is bit-identical, a NaN is caught and never checkpointed, and one
//! densification plan resizes every per-Gaussian container in lock-step.

mod mutant;

use maaf_autodiff::{PerGaussian, Tensor};
use maaf_filter::{CameraTime, FilterKind, observed_frames};
use maaf_models::params::Rows;
use maaf_scene::{DensifyGradient, TrainConfig};
use maaf_train::data::{Dataset, DatasetOptions, Split};
use maaf_train::models::ModelConfig;
use maaf_train::trainer::{
    DensifyPlan, Liveness, Trainer, keep_highest, load_checkpoint, save_checkpoint,
};

fn mutant() -> Dataset {
    Dataset::open(&mutant::mutant_root(), DatasetOptions::default()).expect("mutant loads")
}

/// 100x100 training images, 600 random points, densification every 20 iterations.
fn tiny_config(filter: FilterKind) -> TrainConfig {
    tiny_config_of("saro", filter)
}

/// [`tiny_config`] with the representation `kind` (its stage switch at 20).
fn tiny_config_of(kind: &str, filter: FilterKind) -> TrainConfig {
    let mut c = TrainConfig {
        model: ModelConfig::default_of(kind).expect("known kind"),
        iterations: 60,
        train_scale: 0.125,
        init_points: 600,
        seed: 3,
        ..TrainConfig::default()
    };
    c.filter.kind = filter;
    c.filter.refresh.start = 20;
    c.filter.refresh.every = 20;
    c.densify.from = 20;
    c.densify.every = 20;
    c.densify.opacity_reset_every = 0;
    *c.model.warm_up_mut().expect("a built-in model") = 20;
    c
}

fn params(t: &mut Trainer) -> Vec<(String, Tensor<f32>)> {
    t.model
        .params()
        .named_tensors()
        .map(|(n, v)| (n.to_string(), v.clone()))
        .collect()
}

/// Asserts that two trainers hold the same parameters, bit for bit (`what` names the
/// case in the message).
fn assert_same_params(a: &mut Trainer, b: &mut Trainer, what: &str) {
    let (a, b) = (params(a), params(b));
    assert_eq!(a.len(), b.len(), "{what}: parameter count");
    for ((na, ta), (nb, tb)) in a.iter().zip(&b) {
        assert_eq!(na, nb);
        assert!(
            ta.data()
                .iter()
                .zip(tb.data())
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "{what}: {na} differs"
        );
    }
}

#[test]
fn loss_falls_with_every_filter_and_representation() {
    let data = mutant();
    let runs = [
        ("saro", FilterKind::None),
        ("saro", FilterKind::Mip3d),
        ("saro", FilterKind::Motion),
        ("deform", FilterKind::Motion),
    ];
    for (kind, filter) in runs {
        let mut t = Trainer::new(&data, tiny_config_of(kind, filter.clone())).expect("trainer");
        let mut first = Vec::new();
        let mut last = Vec::new();
        for i in 0..60 {
            t.step();
            let l1 = t
                .last_terms
                .iter()
                .find(|(n, _)| n == "l1")
                .map(|(_, v)| *v)
                .expect("l1 logged");
            if i < 10 {
                first.push(l1);
            } else if i >= 50 {
                last.push(l1);
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        assert_eq!(t.skipped_steps, 0, "{kind} {filter:?}");
        assert!(
            mean(&last) < 0.8 * mean(&first),
            "{kind} {filter:?}: L1 {} -> {}",
            mean(&first),
            mean(&last)
        );
    }
}

/// Iteration i of a batch-3 run trains on the views batch-1 iterations 3i-2..3i
/// would, so every view is still seen once per epoch.
#[test]
fn a_batch_walks_the_same_view_sequence() {
    let data = mutant();
    let one = Trainer::new(&data, tiny_config(FilterKind::None)).expect("trainer");
    let three = Trainer::new(
        &data,
        TrainConfig {
            batch: 3,
            ..tiny_config(FilterKind::None)
        },
    )
    .expect("trainer");
    let n = data.len(Split::Train);
    assert_eq!(n % 3, 0, "mutant has {n} training views");
    let mut epoch = Vec::new();
    for i in 1..=n / 3 {
        let got = three.views_at(i);
        let want: Vec<usize> = (3 * i - 2..=3 * i).flat_map(|k| one.views_at(k)).collect();
        assert_eq!(got, want, "iteration {i}");
        epoch.extend(got);
    }
    epoch.sort_unstable();
    assert_eq!(epoch, (0..n).collect::<Vec<_>>());
}

#[test]
fn resume_is_bit_identical() {
    let data = mutant();
    // A batch of views per iteration resumes on the same view sequence.
    for (kind, batch) in [("saro", 1), ("deform", 1), ("saro", 3)] {
        let cfg = TrainConfig {
            iterations: 50,
            batch,
            ..tiny_config_of(kind, FilterKind::Motion)
        };
        resume_is_bit_identical_for(&data, &format!("{kind}_{batch}"), cfg);
    }
    // GroupFlow fitted before the checkpoint at 25, and at 25 itself (loading that
    // checkpoint passes the fitting iteration again: the saved groups must win).
    for at in [22, 25] {
        let mut cfg = TrainConfig {
            iterations: 50,
            ..tiny_config_of("deform", FilterKind::Motion)
        };
        let ModelConfig::Deform(d) = &mut cfg.model else {
            unreachable!("a deform config")
        };
        d.group_flow.groups = 16;
        d.group_flow.at = at;
        resume_is_bit_identical_for(&data, &format!("deform_groups_at_{at}"), cfg);
    }
}

fn resume_is_bit_identical_for(data: &Dataset, kind: &str, cfg: TrainConfig) {
    let mut straight = Trainer::new(data, cfg.clone()).expect("trainer");
    for _ in 0..50 {
        straight.step();
    }
    let grouped = straight
        .model
        .hooks()
        .expect("deform has hooks")
        .buffers()
        .iter()
        .any(|(n, _)| n == "group_flow/labels");
    assert_eq!(grouped, kind.contains("groups"), "{kind}: GroupFlow stage");
    let mut first = Trainer::new(data, cfg).expect("trainer");
    for _ in 0..25 {
        first.step();
    }
    let dir = std::env::temp_dir().join(format!("maaf_resume_{kind}_{}", std::process::id()));
    save_checkpoint(&first, &dir).expect("checkpoint");
    let mut resumed = load_checkpoint(data, &dir).expect("resume");
    assert_eq!(resumed.iteration, 25);
    // A loaded run renders what the saved one did: the model is in the same stage
    // (dynamic after the static warm-up), so evaluation sees the deformed scene.
    for time in [0.0, 0.37, 1.0] {
        let (a, b) = (first.frame_at(time), resumed.frame_at(time));
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(
                x.data(),
                y.data(),
                "{kind}: frame at t = {time} differs after load"
            );
        }
    }
    for _ in 0..25 {
        resumed.step();
    }
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(resumed.num_gaussians(), straight.num_gaussians());
    assert_same_params(&mut straight, &mut resumed, kind);
    assert_eq!(straight.filter, resumed.filter);
    assert_eq!(straight.liveness, resumed.liveness, "{kind}: liveness");
}

/// A checkpoint written before the liveness record existed (no `liveness/*` tensors)
/// loads with every Gaussian alive at its iteration; a current one restores the
/// record exactly.
#[test]
fn a_checkpoint_without_the_liveness_record_loads() {
    let data = mutant();
    let mut t = Trainer::new(&data, tiny_config(FilterKind::Mip3d)).expect("trainer");
    for _ in 0..30 {
        t.step();
    }
    let n = t.num_gaussians();
    assert!(
        t.liveness.last_grad.iter().any(|&g| g < 30),
        "some rows had no gradient at the last step"
    );
    let dir = std::env::temp_dir().join(format!("maaf_liveness_{}", std::process::id()));
    save_checkpoint(&t, &dir).expect("checkpoint");
    let loaded = load_checkpoint(&data, &dir).expect("load");
    assert_eq!(loaded.liveness, t.liveness);

    // The same checkpoint as an older build wrote it: the tensors without the record
    // and the state's CRC-32 of that file.
    let path = dir.join("tensors.safetensors");
    let blob = std::fs::read(&path).expect("tensors");
    let st = safetensors::SafeTensors::deserialize(&blob).expect("safetensors");
    let kept: Vec<_> = st
        .tensors()
        .into_iter()
        .filter(|(name, _)| !name.starts_with("liveness/"))
        .collect();
    assert_eq!(kept.len() + 2, st.len());
    let old = safetensors::serialize(kept, None).expect("serialise");
    std::fs::write(&path, &old).expect("write tensors");
    let state_path = dir.join("state.json");
    let mut state: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&state_path).expect("state")).expect("json");
    state["tensors_crc32"] = format!("{:08x}", crc32fast::hash(&old)).into();
    std::fs::write(&state_path, serde_json::to_vec(&state).expect("json")).expect("write");
    let loaded = load_checkpoint(&data, &dir).expect("an old checkpoint loads");
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(loaded.liveness, Liveness::alive_at(n, 30));
    assert_eq!(loaded.liveness.dead(loaded.last_reset), 0);
}

#[test]
fn a_nan_is_caught_and_never_checkpointed() {
    let data = mutant();
    let mut t = Trainer::new(&data, tiny_config(FilterKind::Mip3d)).expect("trainer");
    t.step();
    let slot = t
        .model
        .params_mut()
        .iter_mut()
        .find(|s| s.rows == Rows::PerGaussian)
        .expect("a per-Gaussian parameter");
    slot.value.data_mut()[0] = f32::NAN;
    let name = slot.name.clone();
    t.step();
    assert_eq!(
        t.skipped_steps, 1,
        "the step with a NaN parameter must be skipped"
    );
    // The NaN is still in the parameter (it was injected), but no update used it, and
    // every other parameter stayed finite.
    for (n, p) in params(&mut t) {
        let bad = p.data().iter().filter(|v| !v.is_finite()).count();
        assert_eq!(bad, usize::from(n == name), "{n}");
    }
}

#[test]
fn a_run_without_gaussians_stops_with_one_line() {
    let data = mutant();
    let mut t = Trainer::new(&data, tiny_config(FilterKind::Mip3d)).expect("trainer");
    t.step();
    assert!(t.check_health().is_ok());
    t.apply_plan(&DensifyPlan::default());
    assert_eq!(t.num_gaussians(), 0);
    let e = t
        .check_health()
        .expect_err("an empty model is not healthy")
        .to_string();
    assert!(e.contains("pruned every Gaussian"), "{e}");
}

/// After clone, split and prune through `Trainer::apply_plan`, the parameters, their
/// Adam moments, the motion filter's curves, the observation table and the
/// densification statistics all have the new length, survivors keep their values
/// bit for bit, the overwritten rows carry the planned centres and scales, and
/// training goes on at the new size.
/// `densify.gradient` `abs` feeds the statistics AbsGS's sums of absolute per-pixel
/// gradients: from the same start, one step counts the same visible Gaussians with an
/// accumulated norm at least the 3DGS one (|sum| <= sum of |.| per axis), larger for
/// many, and leaves the parameters' update unchanged (the statistic is a by-product).
#[test]
fn the_abs_statistic_bounds_the_mean_one_and_changes_no_parameter() {
    let data = mutant();
    let mut runs = Vec::new();
    for gradient in [DensifyGradient::Mean, DensifyGradient::Abs] {
        let mut c = tiny_config(FilterKind::Mip3d);
        c.densify.gradient = gradient;
        let mut t = Trainer::new(&data, c).expect("trainer");
        t.update();
        runs.push(t);
    }
    let (mut mean, mut abs) = (runs.remove(0), runs.remove(0));
    assert_eq!(mean.stats.denom, abs.stats.denom);
    let (m, a) = (&mean.stats.grad_accum, &abs.stats.grad_accum);
    let seen = mean.stats.denom.iter().filter(|&&d| d > 0.0).count();
    assert!(seen > 100, "only {seen} Gaussians drawn");
    for i in 0..m.len() {
        assert!(
            a[i] >= m[i] * (1.0 - 1e-5),
            "Gaussian {i}: abs {} < mean {}",
            a[i],
            m[i]
        );
    }
    let larger = (0..m.len()).filter(|&i| a[i] > m[i] * 1.1).count();
    assert!(
        larger * 4 > seen,
        "abs exceeds mean by 10 % on only {larger} of {seen}"
    );
    assert_same_params(&mut mean, &mut abs, "abs statistic");
}

#[test]
fn one_plan_resizes_every_container_in_lock_step() {
    let data = mutant();
    let mut t = Trainer::new(&data, tiny_config(FilterKind::Motion)).expect("trainer");
    for _ in 0..45 {
        t.step();
    }
    let n = t.num_gaussians();
    assert!(n > 20, "{n} Gaussians");
    let before = params(&mut t);
    let per_gaussian: Vec<String> = t.model.params().per_gaussian_names();
    let moments: Vec<_> = per_gaussian
        .iter()
        .map(|p| t.adam.moments(p).expect("moments after 45 steps").clone())
        .collect();
    let nu_before = t.filter.variance_at(0.4);
    assert!(nu_before.iter().any(|&v| v > 0.0), "the filter has state");
    let obs_before: Vec<Vec<f32>> = (0..n).map(|i| t.observations.row(i).to_vec()).collect();
    t.liveness.lowered[3] = true;
    let live_before = t.liveness.clone();

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
    t.apply_plan(&plan);

    let m = index.len();
    assert_eq!(t.num_gaussians(), m);
    assert_eq!(t.filter.rows(), m);
    assert_eq!(t.observations.rows(), m);
    assert_eq!(t.stats.grad_accum.len(), m);
    assert_eq!(t.stats.denom.len(), m);
    assert_eq!(t.stats.max_radii.len(), m);
    assert_eq!(t.liveness.rows(), m);
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
        let new = t.adam.moments(p).expect("moments kept");
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
    let nu_after = t.filter.variance_at(0.4);
    for (r, &i) in index.iter().enumerate() {
        assert_eq!(
            nu_after[r].to_bits(),
            nu_before[i].to_bits(),
            "filter row {r}"
        );
        assert_eq!(
            t.observations.row(r),
            obs_before[i].as_slice(),
            "observations row {r}"
        );
        assert_eq!(
            (t.liveness.last_grad[r], t.liveness.lowered[r]),
            (live_before.last_grad[i], live_before.lowered[i]),
            "liveness row {r}"
        );
    }
    // The planned centres and scales landed in the new rows.
    let canon = t.canonical();
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
    let data = mutant();
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
        let xyz = t.canonical().means;
        let grad_accum = t.stats.grad_accum.clone();
        t.schedule();
        assert_eq!(t.num_gaussians(), keep.len(), "{kind}");
        assert_eq!(keep.len(), n - n / 2);
        assert_eq!(t.filter.rows(), keep.len());
        assert_eq!(t.observations.rows(), keep.len());
        let after = t.canonical().means;
        for (r, &i) in keep.iter().enumerate() {
            assert_eq!(
                &after.data()[3 * r..3 * r + 3],
                &xyz.data()[3 * i..3 * i + 3]
            );
            assert_eq!(
                t.stats.grad_accum[r], grad_accum[i],
                "{kind}: stats row {r}"
            );
        }
        for _ in 0..3 {
            t.step();
        }
        assert_eq!(t.skipped_steps, 0, "{kind}");
    }
}

/// `val_psnr` is logged every `val_every` iterations (and at the end) and leaves the
/// training itself unchanged: the same seed with validation off gives the same
/// parameters.
#[test]
fn validation_psnr_is_logged_and_changes_nothing() {
    let data = mutant();
    let base = std::env::temp_dir().join(format!("maaf-val-{}", std::process::id()));
    let run = |val_every: usize, name: &str| {
        let mut c = tiny_config(FilterKind::Motion);
        c.iterations = 50;
        c.log_every = 10;
        c.val_every = val_every;
        c.val_views = 2;
        let out = base.join(name);
        maaf_train::trainer::train_run(&data, c, &out, false).expect("run");
        let model = load_checkpoint(&data, &out.join("model")).expect("model");
        let log = std::fs::read_to_string(out.join("log.csv")).expect("log");
        (model, log)
    };
    let (mut with, log) = run(20, "with");
    let (mut without, log_off) = run(0, "without");
    assert_eq!(params(&mut with), params(&mut without));
    let rows: Vec<Vec<&str>> = log.lines().map(|l| l.split(',').collect()).collect();
    assert_eq!(rows[0].last(), Some(&"val_psnr"));
    let logged: Vec<&str> = rows[1..]
        .iter()
        .filter(|r| !r.last().expect("cells").is_empty())
        .map(|r| r[0])
        .collect();
    assert_eq!(logged, ["20", "40", "50"]);
    for r in &rows[1..] {
        if let Ok(p) = r.last().expect("cells").parse::<f64>() {
            assert!(p > 5.0 && p < 60.0, "val_psnr {p}");
        }
    }
    // With validation off no row has a value.
    assert!(
        log_off.lines().skip(1).all(|l| l.ends_with(',')),
        "{log_off}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// Validation renders the model an iteration trained, before that iteration's
/// schedule: where an opacity reset falls on a validation iteration, the logged
/// `val_psnr` is the one of the same run without resets (rather than the near-empty
/// render just after the reset).
#[test]
fn validation_sees_the_model_before_an_opacity_reset() {
    let data = mutant();
    let base = std::env::temp_dir().join(format!("maaf-val-reset-{}", std::process::id()));
    let val_at_20 = |reset_every: usize, name: &str| {
        let mut c = tiny_config(FilterKind::Mip3d);
        c.iterations = 30;
        c.log_every = 10;
        c.val_every = 20;
        c.val_views = 2;
        c.densify.opacity_reset_every = reset_every;
        let out = base.join(name);
        maaf_train::trainer::train_run(&data, c, &out, false).expect("run");
        let log = std::fs::read_to_string(out.join("log.csv")).expect("log");
        let row = log
            .lines()
            .find(|l| l.starts_with("20,"))
            .expect("row of iteration 20")
            .to_string();
        let val = row.rsplit(',').next().expect("val_psnr cell").to_string();
        (val, log)
    };
    let (with_reset, log) = val_at_20(20, "reset");
    let (no_reset, _) = val_at_20(0, "no-reset");
    assert!(!with_reset.is_empty(), "{log}");
    assert_eq!(with_reset, no_reset, "{log}");
    // The reset did happen: the two runs' losses differ after iteration 20.
    let (_, log_no_reset) = val_at_20(0, "no-reset-2");
    let l1_at_30 = |l: &str| {
        let row = l.lines().find(|r| r.starts_with("30,")).expect("row 30");
        row.split(',').nth(1).expect("l1 cell").to_string()
    };
    assert_ne!(l1_at_30(&log), l1_at_30(&log_no_reset), "{log}");
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn a_branch_continues_a_checkpoint_with_its_own_settings() {
    let data = mutant();
    let cfg = TrainConfig {
        iterations: 40,
        ..tiny_config_of("deform", FilterKind::Motion)
    };
    let mut straight = Trainer::new(&data, cfg.clone()).expect("trainer");
    for _ in 0..25 {
        straight.step();
    }
    let dir = std::env::temp_dir().join(format!("maaf_branch_{}", std::process::id()));
    save_checkpoint(&straight, &dir).expect("checkpoint");
    for _ in 25..40 {
        straight.step();
    }

    // Same settings: the branch is the straight run, bit for bit.
    let mut same = Trainer::new(&data, cfg.clone()).expect("trainer");
    assert!(same.branch_from(&dir).expect("branch").is_empty());
    assert_eq!(same.iteration, 25);
    for _ in 25..40 {
        same.step();
    }
    assert_same_params(&mut straight, &mut same, "branch");

    // GroupFlow from the checkpoint's iteration: its node offsets start at zero,
    // the groups are fitted on load, and the branch keeps its own settings.
    let mut grouped_cfg = TrainConfig {
        iterations: 30,
        ..cfg.clone()
    };
    let ModelConfig::Deform(d) = &mut grouped_cfg.model else {
        unreachable!("a deform config")
    };
    d.group_flow.groups = 16;
    d.group_flow.at = 25;
    let mut grouped = Trainer::new(&data, grouped_cfg.clone()).expect("trainer");
    let fresh = grouped.branch_from(&dir).expect("branch");
    assert_eq!(fresh, ["group_nodes"]);
    assert_eq!(grouped.config, grouped_cfg);
    let fitted = |t: &Trainer| {
        t.model
            .hooks()
            .is_some_and(|h| h.buffers().iter().any(|(n, _)| n == "group_flow/labels"))
    };
    assert!(fitted(&grouped), "groups fitted when the branch loads");
    for _ in 25..30 {
        grouped.step();
    }
    assert!(fitted(&grouped));

    // GroupFlow due before the checkpoint's iteration: fitted when the branch loads
    // as well, not never.
    let mut late_cfg = grouped_cfg.clone();
    if let ModelConfig::Deform(d) = &mut late_cfg.model {
        d.group_flow.at = 20;
    }
    let mut late = Trainer::new(&data, late_cfg).expect("trainer");
    late.branch_from(&dir).expect("branch");
    assert!(
        fitted(&late),
        "groups fitted for a branch past group_flow.at"
    );

    // A plain resume of a checkpoint without the node offsets still refuses it.
    let err = Trainer::new(&data, grouped_cfg)
        .expect("trainer")
        .restore(&dir)
        .expect_err("the checkpoint lacks a parameter");
    assert!(err.to_string().contains("group_nodes"), "{err}");

    // The filter state belongs to the checkpoint's filter kind.
    let mut other = cfg.clone();
    other.filter.kind = FilterKind::Mip3d;
    let err = Trainer::new(&data, other)
        .expect("trainer")
        .branch_from(&dir)
        .expect_err("another filter kind is refused");
    assert!(err.to_string().contains("filter kind"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_motion_filter_observes_at_most_max_views_and_the_others_none() {
    let data = mutant();
    let cfg = tiny_config(FilterKind::Motion);
    let mut full = Trainer::new(&data, cfg.clone()).expect("trainer");
    for _ in 0..25 {
        full.step();
    }
    let views = full.observations.num_frames();
    assert!(
        views > 50,
        "mutant has more than 50 training views ({views})"
    );
    let dir = std::env::temp_dir().join(format!("maaf_max_views_{}", std::process::id()));
    save_checkpoint(&full, &dir).expect("checkpoint");

    // Capped at 50: the table holds 50 frames, and a branch from a checkpoint that
    // observed every view reads exactly the kept views' columns.
    let mut capped_cfg = cfg.clone();
    capped_cfg.filter.max_views = 50;
    let mut capped = Trainer::new(&data, capped_cfg).expect("trainer");
    assert_eq!(capped.observations.num_frames(), 50);
    capped.branch_from(&dir).expect("branch");
    let frames: Vec<CameraTime> = full
        .observations
        .times()
        .iter()
        .enumerate()
        .map(|(camera, &time)| CameraTime { camera, time })
        .collect();
    let kept = observed_frames(&frames, 50);
    for (k, &f) in kept.iter().enumerate() {
        assert_eq!(capped.observations.times()[k], frames[f].time, "frame {k}");
    }
    assert_eq!(capped.num_gaussians(), full.num_gaussians());
    for n in 0..full.num_gaussians() {
        let (a, b) = (full.observations.row(n), capped.observations.row(n));
        assert!(
            kept.iter().zip(b).all(|(&f, &x)| a[f] == x),
            "Gaussian {n}: columns not the kept views'"
        );
    }
    for _ in 0..10 {
        capped.step();
    }
    assert!(
        (0..capped.num_gaussians()).any(|n| capped.observations.row(n).iter().any(|&x| x > 0.0)),
        "the capped table is recorded"
    );

    // The static filter reads no observation: none are kept or saved.
    let mut stat = Trainer::new(&data, tiny_config(FilterKind::Mip3d)).expect("trainer");
    stat.step();
    assert_eq!(stat.observations.num_frames(), 0);
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

/// A run whose config names a program's own term: rendering loads it without the
/// term; continuing it needs the term registered, and is refused, naming it, without.
#[test]
fn a_run_with_its_own_term_loads_for_rendering_and_trains_only_with_the_term() {
    use maaf_train::Plugins;
    use maaf_train::loss::TermRegistry;
    use maaf_train::trainer::{
        load_checkpoint_with_plugins, train_run_with, train_run_with_plugins,
    };
    let data = mutant();
    let dir = std::env::temp_dir().join(format!("maaf_own_term_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut config = tiny_config(FilterKind::None);
    config.iterations = 2;
    config.val_every = 0;
    config.terms.insert("alpha_mean".into(), 0.01);
    let mut registry = TermRegistry::builtin();
    registry.register_fn("alpha_mean", |ctx| ctx.alpha().mean());
    let plugins = Plugins::with_terms(&registry);
    train_run_with_plugins(&data, config, &dir, false, &plugins).expect("trains with the term");
    let log = std::fs::read_to_string(dir.join("log.csv")).expect("log");
    assert!(
        log.starts_with("iteration,l1,dssim,l_sr,alpha_mean,"),
        "{log}"
    );

    let model = dir.join("model");
    let loaded = load_checkpoint(&data, &model).expect("rendering needs no term");
    assert_eq!(loaded.objective.unregistered(), ["alpha_mean"]);
    let msg = train_run_with(loaded, &dir, true)
        .expect_err("refused")
        .to_string();
    assert!(msg.contains("lacks the term `alpha_mean`"), "{msg}");
    let msg = load_checkpoint_with_plugins(&data, &model, &Plugins::builtin())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        msg.contains("state.json: the term `alpha_mean` is not registered"),
        "{msg}"
    );
    let t = load_checkpoint_with_plugins(&data, &model, &plugins).expect("with the term");
    assert!(t.objective.unregistered().is_empty());
    assert!(t.objective.names().iter().any(|n| n == "alpha_mean"));
    let _ = std::fs::remove_dir_all(&dir);
}
