//! The multi-view video generator: the Plenoptic Video loader round-trips what it writes
//! (cameras, focal, times, images, flow, moving masks), the masks agree with ray casting
//! at pixel centres, the movers' distance to the cameras changes several-fold, and the
//! folder is written atomically.

use maaf_data::downsample::{composite_premultiplied, premultiply};
use maaf_data::synthetic::render::{forward_flow, render_layers, trace_pixel};
use maaf_data::synthetic::rig::{arc_positions, camera_wh};
use maaf_data::synthetic::write::image_salt;
use maaf_data::synthetic::{MultiviewOptions, build_scene, generate_multiview, scene_bounds};
use maaf_data::{Dataset, DatasetOptions, Format, Split};
use maaf_io::TempDir;

fn tiny() -> MultiviewOptions {
    MultiviewOptions {
        width: 64,
        height: 48,
        cameras: 3,
        frames: 4,
        samples: 2,
        seed: 5,
        ..MultiviewOptions::default()
    }
}

#[test]
fn loader_round_trips_the_generated_scene() {
    let t = TempDir::new("rt").expect("temp dir");
    let out = t.path().join("scene");
    let opts = tiny();
    let summary = generate_multiview(&out, &opts, &mut |_, _| {}).expect("generates");
    assert_eq!(summary.counts, [8, 0, 4, 4]);
    let data = Dataset::open(&out, DatasetOptions::default()).expect("opens");
    assert_eq!(data.format(), Format::Plenoptic);
    assert_eq!((data.len(Split::Train), data.len(Split::Test)), (8, 4));

    let scene = build_scene("approach").expect("scene");
    let want_bounds = scene_bounds(&scene);
    let b = data.scene_bounds();
    assert!(
        (b.min - want_bounds.min).length() < 1e-12 && (b.max - want_bounds.max).length() < 1e-12
    );
    let cams: Vec<_> = arc_positions(3)
        .into_iter()
        .map(|p| camera_wh(p, 64, 48).expect("camera"))
        .collect();
    let times = [0.0, 0.25, 0.5, 0.75];
    assert_eq!(data.times(Split::Test), times.to_vec());
    assert_eq!(data.times(Split::Train), [times, times].concat());

    // Cameras: train is cam01 then cam02, frame by frame; test is cam00.
    let slots = (0..4)
        .map(|j| (Split::Test, j, 0, j))
        .chain((1..3).flat_map(|c| (0..4).map(move |j| (Split::Train, (c - 1) * 4 + j, c, j))));
    for (split, index, c, j) in slots {
        let got = data.camera(split, index, 1.0).expect("camera");
        let want = &cams[c];
        assert!((got.fx - want.fx).abs() < 1e-9 && (got.fy - want.fy).abs() < 1e-9);
        assert_eq!(
            (got.cx, got.cy, got.width, got.height),
            (32.0, 24.0, 64, 48)
        );
        for r in 0..4 {
            for k in 0..4 {
                let d = got.world_to_camera[r][k] - want.world_to_camera[r][k];
                assert!(d.abs() < 1e-12, "{split}[{index}] w2c[{r}][{k}] off by {d}");
            }
        }
        // Images: the loader's view is the render, composited, to 8-bit rounding.
        if j == 1 || j == 3 {
            let (mut rgba, mask) = render_layers(
                &scene,
                want,
                times[j],
                opts.samples,
                image_salt(opts.seed, c, j),
            );
            premultiply(&mut rgba.data);
            let want_rgb = composite_premultiplied(&rgba.data, data.background());
            let view = data.view(split, index, 1.0).expect("view");
            let err = view
                .image
                .data
                .iter()
                .zip(&want_rgb)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(
                err <= 1.0 / 255.0 + 1e-6,
                "{split}[{index}] image off by {err}"
            );
            if c == 0 {
                let got = data.moving_mask(j, 1.0).expect("mask").expect("present");
                let err = got
                    .data
                    .iter()
                    .zip(&mask.data)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f32, f32::max);
                assert!(err <= 0.5 / 255.0 + 1e-6, "mask {j} off by {err}");
            }
        }
    }

    // Flow of cam00 (the video split) is the exact flow to 1/128 px; none after the end.
    for j in 0..3 {
        let got = data.flow(j, 1.0).expect("flow").expect("present");
        let want = forward_flow(&scene, &cams[0], times[j], times[j + 1]);
        for (g, w) in got.data.chunks_exact(3).zip(want.data.chunks_exact(3)) {
            assert_eq!(g[2], w[2]);
            if w[2] > 0.5 {
                assert!((g[0] - w[0]).abs() <= 1.0 / 128.0 + 1e-4);
                assert!((g[1] - w[1]).abs() <= 1.0 / 128.0 + 1e-4);
            }
        }
    }
    assert!(data.flow(3, 1.0).expect("ok").is_none());

    // Half-scale mask is the 2 x 2 mean of the full one.
    let full = data.moving_mask(2, 1.0).expect("ok").expect("present");
    let half = data.moving_mask(2, 0.5).expect("ok").expect("present");
    assert_eq!((half.width, half.height), (32, 24));
    let (x, y) = (10, 7);
    let mean = (full.pixel(2 * x, 2 * y)[0]
        + full.pixel(2 * x + 1, 2 * y)[0]
        + full.pixel(2 * x, 2 * y + 1)[0]
        + full.pixel(2 * x + 1, 2 * y + 1)[0])
        / 4.0;
    assert!((half.pixel(x, y)[0] - mean).abs() < 1e-6);

    // The shipped initial points: seen by the training cameras (not cam00) at the
    // frame times, inside the scene bounds.
    let cloud = data
        .point_cloud()
        .expect("reads")
        .expect("ships points3d.ply");
    let bounds = scene_bounds(&scene);
    let point_times = cloud.times.as_ref().expect("times");
    assert!(cloud.len() > 100, "{} points", cloud.len());
    for (p, t) in cloud.points.iter().zip(point_times) {
        assert!(times.iter().any(|f| (f - t).abs() < 1e-6), "time {t}");
        let p = glam::DVec3::from_array(*p);
        assert!(bounds.contains(p), "{p:?} outside the scene bounds");
    }
}

#[test]
fn masks_agree_with_ray_casting_and_cover_the_movers() {
    let scene = build_scene("approach").expect("scene");
    let cam = camera_wh(arc_positions(1)[0], 96, 64).expect("camera");
    for t in [0.0, 0.5, 0.9] {
        let (_, mask) = render_layers(&scene, &cam, t, 4, 1);
        let (mut moving, mut wholly, mut disagree) = (0, 0, 0);
        for y in 0..64 {
            for x in 0..96 {
                let m = mask.pixel(x, y)[0];
                let centre = trace_pixel(&scene, &cam, t, x, y)
                    .is_some_and(|h| !scene.objects[h.object].motion.is_static());
                // Wholly moving pixels have their centre on a mover, wholly static ones
                // off them, except where a sliver thinner than the sample spacing (the
                // 0.016-wide propeller bars) slips between the 2 x 2 coarse samples.
                disagree += usize::from((m == 1.0 && !centre) || (m == 0.0 && centre));
                wholly += usize::from(m == 1.0);
                moving += usize::from(m > 0.0);
            }
        }
        assert!(
            disagree * 100 <= 96 * 64,
            "t {t}: {disagree} pixels disagree"
        );
        assert!(
            wholly > 20 && moving < 96 * 64 / 2,
            "t {t}: {wholly} moving pixels of {moving}"
        );
    }
}

#[test]
fn movers_change_distance_several_fold_for_every_camera() {
    let scene = build_scene("approach").expect("scene");
    let eyes = arc_positions(16);
    for name in ["flyer", "retreater"] {
        let i = scene
            .objects
            .iter()
            .position(|o| o.name == name)
            .expect("object");
        let motion = scene.objects[i].motion;
        let ratios: Vec<f64> = eyes
            .iter()
            .map(|&e| {
                let d: Vec<f64> = (0..=20)
                    .map(|k| (motion.pose(k as f64 / 20.0).pos - e).length())
                    .collect();
                let (lo, hi) = d
                    .iter()
                    .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
                hi / lo
            })
            .collect();
        let worst = ratios.iter().copied().fold(f64::INFINITY, f64::min);
        println!("{name}: max/min distance per camera {ratios:.2?}");
        // The outermost cameras (45 degrees off the front) see the flyer pass at a slant.
        assert!(
            worst > 1.8,
            "{name}: distance ratio only {worst:.2} for some camera"
        );
        assert!(ratios[0] > 3.0, "{name}: cam00 ratio {:.2}", ratios[0]);
        let most = ratios.iter().filter(|&&r| r > 2.5).count();
        assert!(
            most >= 8,
            "{name}: only {most} of 16 cameras see a 2.5x change"
        );
    }
}

#[test]
fn writes_atomically_and_refuses_bad_options() {
    let t = TempDir::new("atomic").expect("temp dir");
    let out = t.path().join("scene");
    generate_multiview(&out, &tiny(), &mut |_, _| {}).expect("first");
    let err = generate_multiview(&out, &tiny(), &mut |_, _| {}).expect_err("exists");
    assert!(err.to_string().contains("already exists"), "{err}");
    let again = MultiviewOptions {
        force: true,
        frames: 2,
        ..tiny()
    };
    generate_multiview(&out, &again, &mut |_, _| {}).expect("forced");
    let entries: Vec<String> = std::fs::read_dir(t.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().to_string())
        .collect();
    assert_eq!(entries, vec!["scene".to_string()], "no temporaries left");
    let data = Dataset::open(&out, DatasetOptions::default()).expect("opens");
    assert_eq!(
        data.len(Split::Test),
        2,
        "the forced run replaced the old one"
    );

    for (bad, want) in [
        (
            MultiviewOptions {
                width: 40,
                ..tiny()
            },
            "multiple of 16",
        ),
        (
            MultiviewOptions {
                cameras: 1,
                ..tiny()
            },
            "--cameras 1: must be in 2..=100",
        ),
        (
            MultiviewOptions {
                frames: 1,
                ..tiny()
            },
            "--frames 1: must be in 2..=10000",
        ),
        (
            MultiviewOptions {
                samples: 0,
                ..tiny()
            },
            "--samples",
        ),
        (
            MultiviewOptions {
                scene: "nope".into(),
                ..tiny()
            },
            "unknown scene",
        ),
    ] {
        let target = t.path().join("bad");
        let err = generate_multiview(&target, &bad, &mut |_, _| {}).expect_err("refused");
        assert!(err.to_string().contains(want), "{err}");
        assert!(!target.exists());
    }
}
