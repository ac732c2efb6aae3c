//! The tracking representation trained end to end on a generated multi-view video
//! (`glide`: two movers gliding at constant velocity, 10 frames): its Gaussians follow
//! the movers' true displacement and the static ones stay; each iteration trains on
//! its frame's views, every camera once per pass; a run resumed from a checkpoint
//! (at a frame's last iteration and inside a frame) ends bit for bit as the
//! uninterrupted one, and a checkpoint loads without the data set and renders as its
//! trainer.

use std::path::Path;

use glam::DVec3;
use maaf_filter::FilterKind;
use maaf_io::TempDir;
use maaf_scene::{ModelRegistry, TrainConfig, TrainedScene};
use maaf_train::data::synthetic::scene::Shape;
use maaf_train::data::synthetic::{MultiviewOptions, build_scene, generate_multiview};
use maaf_train::data::{Dataset, DatasetOptions};
use maaf_train::models::{ModelConfig, TrackConfig};
use maaf_train::trainer::{Trainer, load_checkpoint, save_checkpoint};

const FRAMES: usize = 10;

/// `glide` from 7 cameras (6 training) x 10 frames at 96 x 64, times `j / 10`.
fn glide(dir: &Path) -> Dataset {
    let opts = MultiviewOptions {
        scene: "glide".into(),
        width: 96,
        height: 64,
        cameras: 7,
        frames: FRAMES,
        samples: 1,
        seed: 3,
        force: false,
    };
    generate_multiview(dir, &opts, &mut |_, _| {}).expect("generates");
    Dataset::open(dir, DatasetOptions::default()).expect("opens")
}

/// `iterations` of the tracking model, `share` of them on frame 0 (densified in its
/// first half), with the neighbour weights and the centres' learning rate scaled to
/// the scene: about 0.1 units between initial points (weight 0.6 there), 0.06 units of
/// motion a frame (reached in a few tens of iterations at 1e-3 x the extent).
fn config(iterations: usize, share: f64, filter: FilterKind) -> TrainConfig {
    let mut track = TrackConfig {
        first_frame_iterations: share,
        neighbour_falloff: 50.0,
        ..TrackConfig::default()
    };
    track.lr.position = 1e-3;
    let first = track.first_frame_end(iterations);
    let mut c = TrainConfig {
        model: ModelConfig::Track(track),
        iterations,
        train_scale: 1.0,
        init_points: 20_000,
        seed: 1,
        val_every: 0,
        ..TrainConfig::default()
    };
    c.filter.kind = filter;
    c.densify.from = first / 5;
    c.densify.every = (first / 5).max(1);
    c.densify.until = first / 2;
    c.densify.opacity_reset_every = 0;
    c.densify.max_gaussians = 20_000;
    c
}

#[test]
fn each_iteration_trains_on_its_frame_and_meets_every_camera_once_a_pass() {
    let t = TempDir::new("track-views").expect("temp dir");
    let data = glide(&t.path().join("glide"));
    let trainer = Trainer::new(&data, config(200, 0.1, FilterKind::None)).expect("trainer");
    // Frame 0 takes 20 iterations, each later frame 20.
    let times = data.times(maaf_train::data::Split::Train);
    for frame in [0, 1, 9] {
        let start = 1 + 20 * frame;
        let views: Vec<usize> = (start..start + 12)
            .flat_map(|it| trainer.views_at(it))
            .collect();
        assert!(
            views.iter().all(|&v| times[v] == frame as f64 / 10.0),
            "frame {frame}"
        );
        for pass in views.chunks(6) {
            let mut cams = pass.to_vec();
            cams.sort_unstable();
            cams.dedup();
            assert_eq!(cams.len(), 6, "frame {frame}: {pass:?}");
        }
    }
}

/// The mean of `f` over `rows`, or `None` without rows.
fn mean(rows: &[usize], f: impl Fn(usize) -> DVec3) -> Option<DVec3> {
    (!rows.is_empty()).then(|| rows.iter().map(|&i| f(i)).sum::<DVec3>() / rows.len() as f64)
}

#[test]
fn gaussians_follow_the_movers_and_static_ones_stay() {
    let t = TempDir::new("track-follow").expect("temp dir");
    let data = glide(&t.path().join("glide"));
    let mut trainer = Trainer::new(&data, config(600, 0.4, FilterKind::None)).expect("trainer");
    for _ in 0..600 {
        trainer.step();
    }
    let (first, last) = (0.0, (FRAMES - 1) as f64 / FRAMES as f64);
    let [m0, _, _, opacity, _] = trainer.frame_at(first);
    let [m1, ..] = trainer.frame_at(last);
    let at = |m: &maaf_autodiff::Tensor<f32>, i: usize| {
        DVec3::from_array(std::array::from_fn(|a| f64::from(m.data()[3 * i + a])))
    };
    let visible: Vec<usize> = (0..trainer.num_gaussians())
        .filter(|&i| opacity.data()[i] > 0.2)
        .collect();
    let scene = build_scene("glide").expect("scene");
    for name in ["ball", "crate"] {
        let k = scene
            .objects
            .iter()
            .position(|o| o.name == name)
            .expect("mover");
        let (p0, p1) = (
            scene.objects[k].motion.pose(first),
            scene.objects[k].motion.pose(last),
        );
        // Gaussians within 0.03 of the mover's surface at the first frame.
        let inside = |x: DVec3| {
            let local = p0.rot_t * (x - p0.pos);
            match scene.objects[k].shape {
                Shape::Sphere(r) => local.length() < r + 0.03,
                Shape::Box(half) => (local.abs() - half).max_element() < 0.03,
                _ => unreachable!("glide's movers are a sphere and a box"),
            }
        };
        let on: Vec<usize> = visible
            .iter()
            .copied()
            .filter(|&i| inside(at(&m0, i)))
            .collect();
        let moved = mean(&on, |i| at(&m1, i) - at(&m0, i)).expect("Gaussians on the mover");
        // Where the mover's rigid motion takes each of them.
        let truth = mean(&on, |i| {
            let x = at(&m0, i);
            p1.to_world(p0.rot_t * (x - p0.pos)) - x
        })
        .expect("rows");
        let err = (moved - truth).length() / truth.length();
        eprintln!(
            "{name}: {} Gaussians, moved {moved:.3} ({:.3}), truth {truth:.3} ({:.3}), relative error {err:.3}",
            on.len(),
            moved.length(),
            truth.length()
        );
        assert!(on.len() >= 20, "{name}: {} Gaussians", on.len());
        assert!(err < 0.25, "{name}: moved {moved}, truth {truth}");
    }
    // The floor (the movers stay above z = 0.2), against the ball's 0.7 units.
    let floor: Vec<usize> = visible
        .iter()
        .copied()
        .filter(|&i| at(&m0, i).z.abs() < 0.05)
        .collect();
    let drift: Vec<f64> = floor
        .iter()
        .map(|&i| (at(&m1, i) - at(&m0, i)).length())
        .collect();
    let mean_drift = drift.iter().sum::<f64>() / drift.len() as f64;
    eprintln!(
        "floor: {} Gaussians, mean drift {mean_drift:.4}",
        floor.len()
    );
    assert!(floor.len() >= 100, "{} floor Gaussians", floor.len());
    assert!(mean_drift < 0.07, "the floor drifts by {mean_drift}");
}

fn bits(t: &maaf_autodiff::Tensor<f32>) -> Vec<u32> {
    t.data().iter().map(|v| v.to_bits()).collect()
}

/// Every parameter and buffer of `t`, bit for bit.
fn state(t: &Trainer) -> Vec<(String, Vec<u32>)> {
    let params = t
        .state
        .model
        .params()
        .named_tensors()
        .map(|(n, v)| (n.to_string(), bits(v)));
    let hooks = t.state.model.hooks().expect("track has hooks");
    params
        .chain(hooks.buffers().iter().map(|(n, v)| (n.clone(), bits(v))))
        .collect()
}

#[test]
fn a_resumed_run_is_bit_identical_and_a_loaded_one_renders_as_its_trainer() {
    let t = TempDir::new("track-resume").expect("temp dir");
    let data = glide(&t.path().join("glide"));
    // Frame 0 takes iterations 1..=20, frame 1 21..=23, frame 2 24..=26, frames 3-9 two
    // each; the motion filter observes every frame.
    let cfg = config(40, 0.5, FilterKind::Motion);
    let mut straight = Trainer::new(&data, cfg.clone()).expect("trainer");
    for _ in 0..40 {
        straight.step();
    }
    let want = state(&straight);
    assert!(want.iter().any(|(n, _)| n == "frame_means"));
    // At a frame's last iteration (the next one switches frames) and inside a frame.
    for stop in [23, 25] {
        let mut first = Trainer::new(&data, cfg.clone()).expect("trainer");
        for _ in 0..stop {
            first.step();
        }
        let dir = t.path().join(format!("iter_{stop}"));
        save_checkpoint(&first, &dir).expect("checkpoint");
        let scene = TrainedScene::from_checkpoint(&dir, &ModelRegistry::builtin(), None)
            .expect("loads without the data set");
        // Frame times (the current one last), between frames, and clamped past it.
        let times = [0.0, 0.05, 0.1, 0.15, 0.2, 0.7];
        for time in times {
            let (a, b) = (first.frame_at(time), scene.gaussians_at(time));
            for (x, y) in a.iter().zip(&b) {
                assert!(
                    bits(x) == bits(y),
                    "iteration {stop}: Gaussians at t = {time}"
                );
            }
        }
        let camera = first.cameras()[0].clone();
        let live = first.into_scene();
        for time in times {
            let (a, b) = (live.render(&camera, time), scene.render(&camera, time));
            assert!(
                bits(&a) == bits(&b),
                "iteration {stop}: render at t = {time}"
            );
        }
        let mut resumed = load_checkpoint(&data, &dir).expect("resume");
        for _ in stop..40 {
            resumed.step();
        }
        assert!(
            state(&resumed) == want,
            "resumed at {stop}: not bit-identical"
        );
    }
}
