//! Dynamic 3D Gaussians loader (CMU Panoptic layout) on scenes the generator writes in
//! that layout: per-camera intrinsics with off-centre principal points, camera-major
//! splits, times `j / (F - 1)`, one-line errors for bad meta files; the temporal-median
//! moving masks against the generator's exact masks; the visual hull's points on the
//! movers.

use std::path::Path;

use glam::DVec3;
use maaf_data::dynamic3dgs::{MASKS_DIR, TEST_META, TRAIN_META};
use maaf_data::median_mask::{MEDIAN_THRESHOLD, decode_rgb8};
use maaf_data::synthetic::dynamic3dgs::rig_cameras;
use maaf_data::synthetic::{MultiviewOptions, build_scene, generate_dynamic3dgs};
use maaf_data::{Dataset, DatasetOptions, Format, MaskSource, Split};
use maaf_io::TempDir;
use serde_json::Value;

const W: u32 = 96;
const H: u32 = 64;

/// Writes the `approach` scene with `cameras` cameras x `frames` frames at 96 x 64.
fn generated(dir: &Path, cameras: usize, frames: usize) {
    generated_at(dir, cameras, frames, W, H);
}

/// [`generated`] at `width x height`.
fn generated_at(dir: &Path, cameras: usize, frames: usize, width: u32, height: u32) {
    let opts = MultiviewOptions {
        scene: "approach".into(),
        width,
        height,
        cameras,
        frames,
        samples: 2,
        seed: 3,
        force: false,
    };
    generate_dynamic3dgs(dir, &opts, &mut |_, _| {}).expect("generates");
}

#[test]
fn opens_a_generated_scene_with_its_cameras_times_and_masks() {
    let t = TempDir::new("d3dgs-open").expect("temp dir");
    let root = t.path().join("scene");
    generated(&root, 5, 6);
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    assert_eq!(data.format(), Format::Dynamic3dgs);
    assert_eq!(data.len(Split::Train), 4 * 6);
    assert_eq!(data.len(Split::Test), 6);
    let train = data.split(Split::Train).expect("train");
    assert_eq!((train.width, train.height), (W, H));
    // Camera-major: camera 1's six frames, then camera 2's, ...
    let rig = rig_cameras(5, W, H).expect("cameras");
    for (i, f) in train.frames.iter().enumerate() {
        let (c, j) = (1 + i / 6, i % 6);
        assert_eq!(f.time, j as f64 / 5.0, "view {i}");
        let (got, want) = (&f.camera, &rig[c]);
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12 * (1.0 + b.abs());
        assert!(
            close(got.fx, want.fx)
                && close(got.fy, want.fy)
                && close(got.cx, want.cx)
                && close(got.cy, want.cy),
            "view {i}: {got:?} vs {want:?}"
        );
        let pose = got
            .world_to_camera
            .iter()
            .flatten()
            .zip(want.world_to_camera.iter().flatten());
        assert!(pose.into_iter().all(|(a, b)| close(*a, *b)), "view {i}");
        assert!(
            f.file.ends_with(format!("ims/{c}/{j:06}.png")),
            "{:?}",
            f.file
        );
        assert!(
            data.train_mask(&f.file).is_some(),
            "view {i} has its seg mask"
        );
    }
    // Off-centre principal points and per-camera focal lengths survive, and scale
    // with the images.
    let cams = data.cameras(Split::Train, 1.0).expect("cameras");
    // Views 0, 6, 12 are cameras 1, 2, 3: centred, then moved by +-(0.04 W, -0.03 H).
    let (w, h) = (W as f64, H as f64);
    assert!((cams[0].cx - 0.5 * w).abs() < 1e-9 && (cams[0].cy - 0.5 * h).abs() < 1e-9);
    assert!((cams[6].cx - 0.54 * w).abs() < 1e-9 && (cams[6].cy - 0.47 * h).abs() < 1e-9);
    assert!((cams[12].cx - 0.46 * w).abs() < 1e-9 && (cams[12].cy - 0.53 * h).abs() < 1e-9);
    assert!(cams[12].fx < cams[0].fx && cams[0].fx < cams[6].fx);
    let half = data.camera(Split::Train, 0, 0.5).expect("half");
    assert_eq!((half.width, half.height), (W / 2, H / 2));
    assert!(
        (half.cx - 0.5 * cams[0].cx).abs() < 1e-12 && (half.fy - 0.5 * cams[0].fy).abs() < 1e-12
    );
    let view = data.view(Split::Test, 5, 0.25).expect("decodes");
    assert_eq!((view.image.width, view.image.height), (W / 4, H / 4));
    assert_eq!(view.time, 1.0);
    // The generator writes masks for the test camera too: they are the exact ones.
    assert!(matches!(data.mask_source(), MaskSource::Files(_)));
    let mask = data
        .moving_mask(2, 0.5)
        .expect("reads")
        .expect("has a mask");
    assert_eq!((mask.width, mask.height), (W / 2, H / 2));
}

/// Rewrites one key of `train_meta.json` with `edit` and returns the loader's error.
fn error_after(root: &Path, edit: impl FnOnce(&mut Value)) -> String {
    let path = root.join(TRAIN_META);
    let original = std::fs::read_to_string(&path).expect("reads");
    let mut v: Value = serde_json::from_str(&original).expect("json");
    edit(&mut v);
    std::fs::write(&path, v.to_string()).expect("writes");
    let err = Dataset::open(root, DatasetOptions::default())
        .expect_err("refused")
        .to_string();
    std::fs::write(&path, original).expect("restores");
    err
}

/// A change to a parsed meta file.
type Edit = Box<dyn FnOnce(&mut Value)>;

#[test]
fn bad_meta_files_get_one_line_naming_the_file_and_entry() {
    let t = TempDir::new("d3dgs-bad").expect("temp dir");
    let root = t.path().join("scene");
    generated(&root, 3, 3);
    let cases: Vec<(Edit, &[&str])> = vec![
        (
            Box::new(|v| v["k"][1][0][0][0] = Value::from(-2.0)),
            &["train_meta.json", "k[1][0]", "fx = -2"],
        ),
        (
            Box::new(|v| v["k"][0][1][0][1] = Value::from(3.0)),
            &["k[0][1]", "no skew"],
        ),
        (
            Box::new(|v| v["w2c"][2][0][0][0] = Value::from(2.0)),
            &["w2c[2][0]"],
        ),
        (
            Box::new(|v| {
                v["cam_id"].as_array_mut().expect("list").pop();
            }),
            &["cam_id", "2 frames but fn has 3"],
        ),
        (
            Box::new(|v| {
                v["fn"][1].as_array_mut().expect("list").pop();
            }),
            &["k[1]", "2 entries but fn[1] has 1"],
        ),
        (
            Box::new(|v| v["fn"][0][1] = Value::from("9/000000.png")),
            &["ims/9/000000.png", "cannot open"],
        ),
        (
            Box::new(|v| v["w"] = Value::from(80)),
            &["is 96x64", "80x64"],
        ),
        (
            Box::new(|v| {
                v.as_object_mut().expect("object").remove("w2c");
            }),
            &["train_meta.json", "w2c"],
        ),
    ];
    for (edit, words) in cases {
        let err = error_after(&root, edit);
        assert_eq!(err.lines().count(), 1, "{err}");
        for w in words {
            assert!(err.contains(w), "{err:?} lacks {w:?}");
        }
    }
    std::fs::remove_file(root.join(TEST_META)).expect("removes");
    let err = Dataset::open(&root, DatasetOptions::default())
        .expect_err("refused")
        .to_string();
    assert!(err.contains("test_meta.json"), "{err}");
}

#[test]
fn temporal_median_masks_agree_with_the_exact_masks() {
    let t = TempDir::new("d3dgs-median").expect("temp dir");
    let root = t.path().join("scene");
    generated(&root, 2, 24);
    // Keep the exact masks aside; without them the loader subtracts the median.
    let exact_dir = t.path().join("exact");
    std::fs::rename(root.join(MASKS_DIR).join("0"), &exact_dir).expect("moves");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    assert!(matches!(
        data.mask_source(),
        MaskSource::TemporalMedian { .. }
    ));
    let (mut both, mut either, mut exact_px, mut missed, mut extra) = (0, 0, 0, 0, 0);
    for j in 0..24 {
        let found = data.moving_mask(j, 1.0).expect("computes").expect("mask");
        let exact = decode_rgb8(&exact_dir.join(format!("{j:06}.png"))).expect("exact");
        for (m, e) in found.data.iter().zip(exact.data.chunks_exact(3)) {
            let (m, e) = (*m > 0.5, e[0] > 127);
            both += usize::from(m && e);
            either += usize::from(m || e);
            exact_px += usize::from(e);
            missed += usize::from(e && !m);
            extra += usize::from(m && !e);
        }
    }
    let iou = both as f64 / either as f64;
    eprintln!(
        "median masks vs exact (threshold {MEDIAN_THRESHOLD}): IoU {iou:.3}, {exact_px} moving pixels, {missed} missed, {extra} extra"
    );
    assert!(exact_px > 500, "the movers cover pixels ({exact_px})");
    assert!(iou > 0.6, "IoU {iou:.3}");
    // A threshold of 255 finds nothing: the comparison measures the masks.
    let frame = decode_rgb8(&root.join("ims/0/000005.png")).expect("frame");
    let none = maaf_data::median_mask::moving_mask(&frame, &frame, 0).expect("same size");
    assert!(none.iter().all(|&v| v == 0.0));
}

#[test]
fn visual_hull_points_lie_on_the_movers() {
    let t = TempDir::new("d3dgs-hull").expect("temp dir");
    let root = t.path().join("scene");
    generated_at(&root, 12, 4, 192, 128);
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    let init = data
        .initial_cloud(4000, 0.5, false, false, 1)
        .expect("carves")
        .expect("has masks");
    let (cloud, line, dynamic) = (init.cloud, init.description, init.hull_points);
    assert!(line.contains("visual hull"), "{line}");
    let times = cloud.times.clone().expect("timed");
    let scene = build_scene("approach").expect("scene");
    let movers: Vec<usize> = (0..scene.objects.len())
        .filter(|&i| !scene.objects[i].motion.is_static())
        .collect();
    let near_mover = |p: [f64; 3], t: f64| {
        let posed = scene.at(t);
        movers.iter().any(|&i| {
            let (c, r) = posed.bounding_sphere(i);
            (DVec3::from_array(p) - c).length() <= r * 1.25 + 0.05
        })
    };
    assert!(dynamic > 100, "{line}");
    let on = (0..dynamic)
        .filter(|&k| near_mover(cloud.points[k], times[k]))
        .count();
    let rest = cloud.len() - dynamic;
    let random_on = (dynamic..cloud.len())
        .filter(|&k| near_mover(cloud.points[k], times[k]))
        .count();
    let (hull, random) = (on as f64 / dynamic as f64, random_on as f64 / rest as f64);
    eprintln!("hull points on movers: {hull:.3}; random points: {random:.3}");
    assert!(hull > 0.8, "{hull:.3} of the hull points lie on movers");
    assert!(random < 0.2, "random static points: {random:.3}");
}
