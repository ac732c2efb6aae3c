//! `scene::TrainedScene` loaded from a checkpoint, without the data set, renders bit
//! for bit what the trainer that wrote it renders, for SaRO with the motion-aware
//! filter (nu(t) curves, K-plane box rebuilt from the scene record) and
//! Deformable-3DGS with the static filter, at training views and a zoomed camera; an
//! unregistered representation is refused with one line naming the run, the name and
//! what is registered.

use maaf_autodiff::Tensor;
use maaf_filter::FilterKind;
use maaf_io::TempDir;
use maaf_scene::TrainConfig;
use maaf_scene::forward::forward;
use maaf_scene::{ModelRegistry, TrainedScene};
use maaf_train::data::synthetic::{self, GenerateOptions};
use maaf_train::data::{Background, Dataset, DatasetOptions, Split, WHITE};
use maaf_train::models::ModelConfig;
use maaf_train::trainer::{Trainer, save_checkpoint};

/// 25 iterations of `kind` with `filter` (refreshed at 10 and 20, dynamic from 10).
fn config(kind: &str, filter: FilterKind) -> TrainConfig {
    let mut c = TrainConfig {
        model: ModelConfig::default_of(kind).expect("known kind"),
        iterations: 25,
        train_scale: 0.5,
        init_points: 300,
        seed: 5,
        sh_degree_every: 10,
        ..TrainConfig::default()
    };
    c.filter.kind = filter;
    c.filter.refresh.start = 10;
    c.filter.refresh.every = 10;
    c.densify.from = 10;
    c.densify.every = 10;
    c.densify.opacity_reset_every = 0;
    *c.model.warm_up_mut().expect("a built-in model") = 10;
    c
}

/// The trainer's own render: the training pipeline with its parameters as constants.
fn trainer_render(t: &Trainer, camera: &maaf_splat::Camera, time: f64) -> Tensor<f32> {
    let tape = maaf_autodiff::Tape::new();
    let params = t.state.model.params().bind_constants(&tape);
    let settings = t.render_settings(t.iteration);
    let out = forward(
        t.state.model.as_ref(),
        &params,
        &t.state.filter,
        camera,
        time,
        &settings,
    );
    // The binding ends the borrow of the tape before the tape is dropped.
    #[allow(clippy::let_and_return)]
    let image = out.render.image.value().clone();
    image
}

fn bits(t: &Tensor<f32>) -> Vec<u32> {
    t.data().iter().map(|v| v.to_bits()).collect()
}

#[test]
fn a_loaded_scene_renders_bit_identically_to_its_trainer() {
    let tmp = TempDir::new("scene").expect("temp dir");
    let data_dir = tmp.path().join("data");
    let opts = GenerateOptions {
        seed: 4,
        ..GenerateOptions::small(64, 6)
    };
    synthetic::generate(&data_dir, &opts, &mut |_, _| {}).expect("generate");
    let data = Dataset::open(&data_dir, DatasetOptions::default()).expect("open");
    let test = data.camera(Split::Test, 0, 0.5).expect("test camera");
    let zoomed = data.camera(Split::Test, 1, 1.0).expect("zoomed camera");
    for (kind, filter) in [("saro", FilterKind::Motion), ("deform", FilterKind::Mip3d)] {
        let mut trainer = Trainer::new(&data, config(kind, filter)).expect("trainer");
        for _ in 0..25 {
            trainer.step();
        }
        let dir = tmp.path().join(kind).join("model");
        save_checkpoint(&trainer, &dir).expect("save");
        // The data folder is not read: the scene comes from the checkpoint alone.
        let scene = TrainedScene::from_checkpoint(&dir, &ModelRegistry::builtin(), None)
            .expect("load without the data set");
        assert_eq!(scene.iteration, 25, "{kind}");
        assert_eq!(scene.num_gaussians(), trainer.num_gaussians(), "{kind}");
        assert_eq!(scene.filter, trainer.state.filter, "{kind}");
        assert_eq!(scene.cameras(), trainer.cameras(), "{kind}");
        assert_eq!(
            scene.render_settings().sh_degree,
            trainer.render_settings(25).sh_degree
        );
        let views = [(&trainer.cameras()[0], 0.0), (&test, 0.37), (&zoomed, 0.81)];
        for (camera, t) in views {
            let want = trainer_render(&trainer, camera, t);
            let got = scene.render(camera, t);
            assert!(bits(&want) == bits(&got), "{kind}: render at t = {t}");
            let (a, b) = (trainer.frame_at(t), scene.gaussians_at(t));
            for (x, y) in a.iter().zip(&b) {
                assert!(bits(x) == bits(y), "{kind}: Gaussians at t = {t}");
            }
        }
        // Negative control: the comparison sees a change of time.
        let other = scene.render(&test, 0.9);
        assert!(
            bits(&other) != bits(&trainer_render(&trainer, &test, 0.37)),
            "{kind}: t = 0.9 renders like t = 0.37"
        );
    }
    // A representation nobody registered: one line naming the run, the name and the
    // registered ones.
    let err = TrainedScene::from_checkpoint(
        &tmp.path().join("saro").join("model"),
        &ModelRegistry::empty(),
        None,
    )
    .err()
    .expect("refused")
    .to_string();
    assert!(
        err.contains("saro/model") && err.contains("`saro` is not registered"),
        "{err}"
    );
    assert!(
        err.contains("(registered: )") && !err.contains('\n'),
        "{err}"
    );
    let mut deform_only = ModelRegistry::empty();
    deform_only
        .register("deform", |c, init| {
            maaf_train::models::build_model(&c.model, init)
        })
        .expect("a new name");
    let err =
        TrainedScene::from_checkpoint(&tmp.path().join("saro").join("model"), &deform_only, None)
            .err()
            .expect("refused")
            .to_string();
    assert!(err.contains("(registered: deform)"), "{err}");

    // A trainer refuses a data set opened on another background than its config's;
    // a checkpoint from before the config had `background` reads it from its scene
    // record (here white, which the default, black, is not).
    let white = Dataset::open(&data_dir, DatasetOptions { background: WHITE }).expect("open");
    let err = Trainer::new(&white, config("saro", FilterKind::None))
        .err()
        .expect("refused")
        .to_string();
    assert!(
        err.contains("composited on white") && err.contains("background is black"),
        "{err}"
    );
    let on_white = TrainConfig {
        background: Background(WHITE),
        ..config("saro", FilterKind::None)
    };
    let trainer = Trainer::new(&white, on_white).expect("trainer");
    let dir = tmp.path().join("white").join("model");
    save_checkpoint(&trainer, &dir).expect("save");
    let state = dir.join("state.json");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&state).expect("state")).expect("json");
    let removed = json["config"]
        .as_object_mut()
        .and_then(|c| c.remove("background"));
    assert_eq!(removed, Some(serde_json::json!("white")));
    std::fs::write(&state, json.to_string()).expect("write");
    let older = maaf_scene::checkpoint_read::Opened::read_state(&dir).expect("reads");
    assert_eq!(older.config.background, Background(WHITE));
}

/// A filter of one's own that keeps a static state but asks for the 3DGS dilation
/// instead of the 2D Mip filter.
struct StaticWithoutMip;

impl maaf_filter::SamplingFilter for StaticWithoutMip {
    fn name(&self) -> &str {
        "static_no_mip"
    }

    fn smooths(&self) -> bool {
        false
    }

    fn compute(
        &self,
        inputs: &dyn maaf_filter::FilterInputs,
        cfg: &maaf_filter::FilterConfig,
    ) -> Result<maaf_filter::FilterState, maaf_filter::FilterError> {
        maaf_filter::StaticFilter.compute(inputs, cfg)
    }
}

#[test]
fn a_loaded_scene_renders_with_the_2d_filter_its_checkpoint_records() {
    let tmp = TempDir::new("scene_smooths").expect("temp dir");
    let data_dir = tmp.path().join("data");
    synthetic::generate(&data_dir, &GenerateOptions::small(48, 4), &mut |_, _| {})
        .expect("generate");
    let data = Dataset::open(&data_dir, DatasetOptions::default()).expect("open");
    let mut trainer = Trainer::new(&data, config("deform", FilterKind::Mip3d)).expect("trainer");
    trainer.set_filter(Box::new(StaticWithoutMip));
    for _ in 0..12 {
        trainer.step();
    }
    assert!(matches!(
        trainer.state.filter,
        maaf_filter::FilterState::Mip3d { .. }
    ));
    let dir = tmp.path().join("model");
    save_checkpoint(&trainer, &dir).expect("checkpoint");
    // The state alone says "a 3D filter", which used to mean the 2D Mip filter too;
    // the checkpoint records that this filter did not smooth.
    let scene = TrainedScene::from_checkpoint(&dir, &ModelRegistry::builtin(), None).expect("load");
    assert!(!scene.smooths);
    assert_eq!(
        scene.render_settings().filter2d,
        trainer.render_settings(trainer.iteration).filter2d
    );
    let camera = data.camera(Split::Test, 0, 0.5).expect("test camera");
    assert_eq!(
        bits(&scene.render(&camera, 0.5)),
        bits(&trainer_render(&trainer, &camera, 0.5))
    );
    // A checkpoint from before the record: the built-in filter its config names says.
    let state_path = dir.join("state.json");
    let mut state: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&state_path).expect("state")).expect("json");
    assert_eq!(state["smooths"], false);
    state.as_object_mut().expect("object").remove("smooths");
    std::fs::write(&state_path, serde_json::to_vec(&state).expect("json")).expect("write");
    let old = TrainedScene::from_checkpoint(&dir, &ModelRegistry::builtin(), None).expect("load");
    assert!(old.smooths, "config names mip3d, which smooths");
}
