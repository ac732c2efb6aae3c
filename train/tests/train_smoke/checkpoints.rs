//! Checkpoints of a training run: a resume is bit-identical, an older checkpoint
//! without the liveness record loads, a branch continues with its own settings, and a
//! run with a program's own term loads for rendering but trains only with the term.

use super::*;

#[test]
fn resume_is_bit_identical() {
    let (_tmp, data) = scene();
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
        .state
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
    assert_eq!(straight.state.filter, resumed.state.filter);
    assert_eq!(
        straight.state.liveness, resumed.state.liveness,
        "{kind}: liveness"
    );
}

/// A checkpoint written before the liveness record existed (no `liveness/*` tensors)
/// loads with every Gaussian alive at its iteration; a current one restores the
/// record exactly.
#[test]
fn a_checkpoint_without_the_liveness_record_loads() {
    let (_tmp, data) = scene();
    let mut t = Trainer::new(&data, tiny_config(FilterKind::Mip3d)).expect("trainer");
    for _ in 0..30 {
        t.step();
    }
    let n = t.num_gaussians();
    assert!(
        t.state.liveness.last_grad.iter().any(|&g| g < 30),
        "some rows had no gradient at the last step"
    );
    let dir = std::env::temp_dir().join(format!("maaf_liveness_{}", std::process::id()));
    save_checkpoint(&t, &dir).expect("checkpoint");
    let loaded = load_checkpoint(&data, &dir).expect("load");
    assert_eq!(loaded.state.liveness, t.state.liveness);

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
    assert_eq!(loaded.state.liveness, Liveness::alive_at(n, 30));
    assert_eq!(loaded.state.liveness.dead(loaded.state.last_reset), 0);
}

#[test]
fn a_branch_continues_a_checkpoint_with_its_own_settings() {
    let (_tmp, data) = scene();
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
        t.state
            .model
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

/// A run whose config names a program's own term: rendering loads it without the
/// term; continuing it needs the term registered, and is refused, naming it, without.
#[test]
fn a_run_with_its_own_term_loads_for_rendering_and_trains_only_with_the_term() {
    use maaf_train::Plugins;
    use maaf_train::loss::TermRegistry;
    use maaf_train::trainer::{
        load_checkpoint_with_plugins, train_run_with, train_run_with_plugins,
    };
    let (_tmp, data) = scene();
    let dir = std::env::temp_dir().join(format!("maaf_own_term_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut config = tiny_config(FilterKind::None);
    config.iterations = 2;
    config.val_every = 0;
    config.terms.insert("alpha_mean".into(), 0.01);
    let mut registry = TermRegistry::builtin();
    registry
        .register_fn("alpha_mean", |ctx| ctx.alpha().mean())
        .expect("a new name");
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
