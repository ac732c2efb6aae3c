//! A run with a background layer, per-camera colour correction and the foreground
//! focus, on a multi-view video the generator writes in the Dynamic 3D Gaussians
//! layout (every camera with exact masks): the layer is trained into
//! `RUN/backdrop` on background pixels and left alone by a resume; the loaded
//! scene draws the model over the layer exactly as `C + (1 - alpha) B` computed
//! pixel by pixel from separate renders; a window on the tile grid renders that
//! rectangle of the whole view; the colour correction is learned and saved; a
//! `val_meta.json` gives a validation split.

use std::path::Path;

use maaf_autodiff::{Tape, Tensor};
use maaf_io::TempDir;
use maaf_scene::forward::forward;
use maaf_scene::{LossRegion, ModelRegistry, TrainConfig, TrainedScene};
use maaf_splat::{RenderSettings, Window};
use maaf_train::data::synthetic::{MultiviewOptions, generate_dynamic3dgs};
use maaf_train::data::{Dataset, DatasetOptions, Split};
use maaf_train::trainer::region::crop;
use maaf_train::trainer::train_run;

/// The `approach` scene, 5 cameras (4 train, 1 test) x 4 frames at 64 x 48.
fn generated(dir: &Path) {
    let opts = MultiviewOptions {
        scene: "approach".into(),
        width: 64,
        height: 48,
        cameras: 5,
        frames: 4,
        samples: 1,
        seed: 3,
        force: false,
    };
    generate_dynamic3dgs(dir, &opts, &mut |_, _| {}).expect("generates");
}

fn layered_config(iterations: usize) -> TrainConfig {
    let mut c = TrainConfig {
        iterations,
        train_scale: 1.0,
        init_points: 200,
        hull_fraction: 1.0,
        seed: 2,
        val_every: 0,
        loss_region: LossRegion::Foreground,
        focus_margin: 2,
        ..TrainConfig::default()
    };
    c.camera_colour.enabled = true;
    c.camera_colour.lr = 0.01;
    c.backdrop.iterations = 15;
    c.backdrop.init_points = 300;
    c.backdrop.densify_until = 10;
    c.densify.from = 5;
    c.densify.every = 5;
    c.densify.until = 10;
    c
}

#[test]
fn a_layered_run_trains_its_layer_first_and_renders_over_it() {
    let t = TempDir::new("layers").expect("temp dir");
    let (root, run) = (t.path().join("scene"), t.path().join("run"));
    generated(&root);
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    train_run(&data, layered_config(12), &run, false).expect("trains");

    let layer = run.join("backdrop");
    let layer_config: TrainConfig = serde_json::from_slice(
        &std::fs::read(layer.join("config.json")).expect("the layer's config"),
    )
    .expect("parses");
    assert_eq!(layer_config.loss_region, LossRegion::Background);
    assert_eq!(layer_config.iterations, 15);
    assert!(!layer_config.backdrop.enabled());
    let summary = std::fs::read(layer.join("summary.json")).expect("layer summary");

    // A resume to a larger budget (the run's own config, as `maaf train --resume`
    // reads it) continues the model and leaves the finished layer.
    let mut resumed: TrainConfig =
        serde_json::from_slice(&std::fs::read(run.join("config.json")).expect("config"))
            .expect("parses");
    resumed.iterations = 20;
    train_run(&data, resumed, &run, true).expect("resumes");
    assert_eq!(
        std::fs::read(layer.join("summary.json")).expect("layer summary"),
        summary
    );

    let registry = ModelRegistry::builtin();
    let scene = TrainedScene::load(&run, &registry).expect("loads without data");
    let back = scene.backdrop.as_deref().expect("the layer is loaded");
    assert_eq!(scene.iteration, 20);
    let view = data.view(Split::Test, 2, 1.0).expect("a test view");
    let settings = scene.render_settings();
    let got = scene.render(&view.camera, view.time);

    // Independently: the model alone on black, the layer alone on the background.
    let tape = Tape::new();
    let params = scene.model.params().bind_constants(&tape);
    let black = RenderSettings {
        background: [0.0; 3],
        ..settings.clone()
    };
    let fg = forward(
        scene.model.as_ref(),
        &params,
        &scene.filter,
        &view.camera,
        view.time,
        &black,
    );
    let (image, alpha) = (fg.render.image.value(), fg.render.alpha.value());
    let behind = back.render(&view.camera, view.time);
    for p in 0..alpha.len() {
        for c in 0..3 {
            let i = 3 * p + c;
            let want = image.data()[i] + (1.0 - alpha.data()[p]) * behind.data()[i];
            assert!(
                (got.data()[i] - want).abs() < 1e-6,
                "pixel {p} channel {c}: {} against {want}",
                got.data()[i]
            );
        }
    }
    // Both layers' Gaussians are exported: the model's rows first.
    let [means, ..] = scene.gaussians_at(view.time);
    assert_eq!(
        means.rows(),
        scene.num_gaussians() + back.num_gaussians(),
        "model + layer rows"
    );

    // A window on the tile grid renders exactly that rectangle of the whole view.
    let window = Window {
        x0: 16,
        y0: 16,
        width: 32,
        height: 21,
    };
    let whole = back.render(&view.camera, view.time);
    let windowed = RenderSettings {
        window: Some(window),
        ..back.render_settings()
    };
    let part = back.render_with(&view.camera, view.time, &windowed);
    assert_eq!(crop(&whole, &window).data(), part.data());

    // The colour correction was learned and saved with the model.
    let tensors = std::fs::read(run.join("model/tensors.safetensors")).expect("tensors");
    let st = safetensors::SafeTensors::deserialize(&tensors).expect("parses");
    let gain = st
        .tensor("param/camera_colour/log_gain")
        .expect("saved with the model");
    assert_eq!(gain.shape(), [4, 3], "one row per training camera");
    let moved = gain
        .data()
        .chunks_exact(4)
        .any(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) != 0.0);
    assert!(moved, "the corrections moved from the identity");
}

#[test]
fn a_val_meta_file_gives_a_validation_split() {
    let t = TempDir::new("layers-val").expect("temp dir");
    let root = t.path().join("scene");
    generated(&root);
    std::fs::copy(root.join("test_meta.json"), root.join("val_meta.json")).expect("copies");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    assert_eq!(data.len(Split::Val), data.len(Split::Test));
    let a = data.view(Split::Val, 1, 1.0).expect("val view");
    let b = data.view(Split::Test, 1, 1.0).expect("test view");
    assert_eq!(a.camera, b.camera);
    assert_eq!(a.time, b.time);
    let _: Tensor<f32> = a.image.to_tensor();
}

#[test]
fn loss_regions_need_training_masks() {
    let t = TempDir::new("layers-masks").expect("temp dir");
    let root = t.path().join("scene");
    generated(&root);
    std::fs::remove_dir_all(root.join("seg")).expect("drops the masks");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    let config = TrainConfig {
        loss_region: LossRegion::Background,
        ..layered_config(5)
    };
    let err = match train_run(&data, config, &t.path().join("run"), false) {
        Ok(_) => panic!("trained without masks"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("no foreground mask"), "{err}");
}
