//! A tiny run of the built-in scene end to end: an exported PLY frame renders exactly
//! as the run does at that time, a sequence folder has every frame with its time in
//! its header, the zip version holds the same files byte for byte, and `eval
//! --temporal` fills the temporal fields with exact and model flow.

use std::io::Read;
use std::path::Path;

use maaf_data::synthetic::{self, GenerateOptions};
use maaf_data::{Dataset, DatasetOptions, Split};
use maaf_eval::export::{export_frame, export_sequence, export_sequence_zip};
use maaf_eval::{EvalOptions, EvalReport, evaluate_scene};
use maaf_filter::FilterKind;
use maaf_io::TempDir;
use maaf_scene::TrainConfig;
use maaf_scene::{ModelRegistry, TrainedScene};
use maaf_splat::{read_ply, render_gaussians};
use maaf_train::trainer::train_run;

fn tiny_config() -> TrainConfig {
    let mut c = TrainConfig {
        iterations: 40,
        train_scale: 0.5,
        init_points: 400,
        seed: 3,
        ..TrainConfig::default()
    };
    c.filter.kind = FilterKind::Motion;
    c.filter.refresh.start = 10;
    c.filter.refresh.every = 10;
    c.densify.from = 10;
    c.densify.every = 20;
    c.densify.opacity_reset_every = 0;
    c.sh_degree_every = 10;
    *c.model.warm_up_mut().expect("a built-in model") = 10;
    c
}

/// `name -> bytes` of every entry of the zip archive `path`, in archive order.
fn zip_entries(path: &Path) -> Vec<(String, Vec<u8>)> {
    let file = std::fs::File::open(path).expect("open zip");
    let mut archive = zip::ZipArchive::new(file).expect("a zip archive");
    (0..archive.len())
        .map(|i| {
            let mut entry = archive.by_index(i).expect("entry");
            let name = entry.name().expect("entry name").into_owned();
            let mut bytes = Vec::new();
            entry.read_to_end(&mut bytes).expect("entry bytes");
            (name, bytes)
        })
        .collect()
}

/// A 20-frame sequence as a folder and as a zip: the archive holds exactly the
/// folder's files (the frames in order) with identical bytes, is the
/// same file when written again (fixed timestamps), and replaces an earlier zip; a
/// non-zip file or a folder at the `.zip` path and a folder with foreign files are
/// refused naming the path.
fn zip_holds_the_folder_version(scene: &TrainedScene, tmp: &Path) {
    let (dir, zip) = (tmp.join("seq20"), tmp.join("seq20.zip"));
    export_sequence(scene, (0.0, 1.0), 20, &dir).expect("folder");
    let bytes = export_sequence_zip(scene, (0.0, 1.0), 20, &zip).expect("zip");
    assert_eq!(bytes, std::fs::metadata(&zip).expect("zip size").len());
    let mut want: Vec<String> = std::fs::read_dir(&dir)
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    want.sort();
    let entries = zip_entries(&zip);
    let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names.len(),
        20,
        "only the PLY frames, which viewers play: {names:?}"
    );
    assert_eq!(names[19], "frame_0019.ply");
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(sorted, want, "the zip holds exactly the folder's files");
    for (name, content) in &entries {
        let on_disk = std::fs::read(dir.join(name)).expect("folder file");
        assert!(on_disk == *content, "{name} differs between zip and folder");
    }
    let folder_bytes: u64 = want
        .iter()
        .map(|n| std::fs::metadata(dir.join(n)).expect("size").len())
        .sum();
    eprintln!(
        "20 frames of {} Gaussians: folder {folder_bytes} bytes, zip {bytes} bytes",
        scene.num_gaussians()
    );
    // Written again over the earlier archive: the same bytes, and no temporary left.
    let first = std::fs::read(&zip).expect("zip");
    export_sequence_zip(scene, (0.0, 1.0), 20, &zip).expect("zip again");
    assert!(
        std::fs::read(&zip).expect("zip") == first,
        "zip not reproducible"
    );
    let temps = std::fs::read_dir(tmp)
        .expect("ls")
        .filter(|e| {
            let name = e.as_ref().expect("entry").file_name();
            name.to_string_lossy().contains(maaf_io::TEMP_MARK)
        })
        .count();
    assert_eq!(temps, 0, "a temporary was left behind");

    // Refusals: one line naming the path, and the file left as it was.
    let not_zip = tmp.join("notes.zip");
    std::fs::write(&not_zip, b"my notes").expect("write");
    let err = export_sequence_zip(scene, (0.0, 1.0), 2, &not_zip).expect_err("refused");
    let msg = err.to_string();
    assert!(msg.contains(&*not_zip.to_string_lossy()) && msg.contains("not a zip"));
    assert!(!msg.contains('\n'), "one line: {msg}");
    assert_eq!(std::fs::read(&not_zip).expect("read"), b"my notes");
    let folder = tmp.join("folder.zip");
    std::fs::create_dir_all(&folder).expect("mkdir");
    let err = export_sequence_zip(scene, (0.0, 1.0), 2, &folder).expect_err("a folder");
    assert!(err.to_string().contains("is a folder"), "{err}");
    let plain = tmp.join("plain");
    std::fs::write(&plain, b"mine").expect("write");
    let err = export_sequence(scene, (0.0, 1.0), 2, &plain).expect_err("a file");
    assert!(err.to_string().contains("not a folder"), "{err}");
    std::fs::write(dir.join("keep.txt"), b"mine").expect("write");
    let err = export_sequence(scene, (0.0, 1.0), 2, &dir).expect_err("foreign file");
    assert!(err.to_string().contains("keep.txt"), "{err}");
}

#[test]
fn export_matches_render_and_temporal_eval_fills_the_fields() {
    let tmp = TempDir::new("export").expect("temp dir");
    let data_dir = tmp.path().join("data");
    let opts = GenerateOptions {
        video_frames: 5,
        seed: 2,
        ..GenerateOptions::small(128, 6)
    };
    synthetic::generate(&data_dir, &opts, &mut |_, _| {}).expect("generate");
    let data = Dataset::open(&data_dir, DatasetOptions::default()).expect("open");
    let run = tmp.path().join("run");
    train_run(&data, tiny_config(), &run, false).expect("train");
    let scene = TrainedScene::load(&run, &ModelRegistry::builtin()).expect("load");

    // One frame: render-ply of the export equals the run's own render at that time.
    let t = 0.37;
    let ply = tmp.path().join("frame.ply");
    export_frame(&scene, t, &ply).expect("export");
    let g = read_ply(&ply).expect("read back");
    // Every Gaussian but those the renderer culls at t (opacity at most 1/255).
    let opacity = &scene.gaussians_at(t)[3];
    let drawn = opacity
        .data()
        .iter()
        .filter(|&&o| f64::from(o) > maaf_splat::compositing::ALPHA_MIN)
        .count();
    assert_eq!(g.len(), drawn);
    let cam = data.camera(Split::Test, 0, 0.5).expect("camera");
    let settings = scene.render_settings();
    assert!(
        settings.sh_degree >= 1,
        "the run should render with view-dependent SH"
    );
    assert_eq!(g.sh_degree, settings.sh_degree);
    let want = scene.render_with(&cam, t, &settings);
    let got = render_gaussians(&g, &cam, &settings).image;
    let worst = want
        .data()
        .iter()
        .zip(got.data())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(
        worst < 1e-4,
        "exported frame differs from the render by {worst}"
    );
    // Negative control: another time of the same run renders visibly differently.
    let other = scene.render_with(&cam, 0.9, &settings);
    let moved = other
        .data()
        .iter()
        .zip(got.data())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(moved > 1e-2, "t = 0.9 looks like t = 0.37 ({moved})");

    // A sequence: every frame, times evenly spaced over the data set's range.
    let seq = tmp.path().join("seq");
    let paths = export_sequence(&scene, (0.0, 1.0), 3, &seq).expect("sequence");
    assert_eq!(paths.len(), 3);
    assert_eq!(paths[1], seq.join("frame_0001.ply"));
    let head = std::fs::read(&paths[1]).expect("frame 1 bytes");
    let head = String::from_utf8_lossy(&head[..200]);
    assert!(head.contains("\ncomment maaf time 0.5\n"), "{head}");
    let mid = read_ply(&paths[1]).expect("frame 1");
    let direct = maaf_eval::export::frame_gaussians(&scene, 0.5);
    assert_eq!(mid.means, direct.means);
    zip_holds_the_folder_version(&scene, tmp.path());

    // Temporal evaluation: exact flow from the video split first, model flow second.
    let options = EvalOptions {
        scales: vec![1.0, 2.0],
        max_views: Some(1),
        save_images: false,
        temporal: true,
        ..EvalOptions::default()
    };
    let report = evaluate_scene(&scene, &run, &data, &options).expect("eval");
    let written = EvalReport::read(&run).expect("eval.json");
    for (a, b) in report.scales.iter().zip(&written.scales) {
        assert_eq!(a.flow, b.flow);
        assert_eq!(a.temporal.len(), b.temporal.len());
        let close = |x: Option<f64>, y: Option<f64>| match (x, y) {
            (Some(x), Some(y)) => (x - y).abs() <= 1e-12 * x.abs().max(1.0),
            (x, y) => x == y,
        };
        assert!(close(a.warp_error, b.warp_error) && close(a.w_ssim, b.w_ssim));
        assert!(close(a.w_lpips, b.w_lpips) && close(a.lpips, b.lpips));
    }
    for s in &report.scales {
        let flows: Vec<&str> = s.temporal.iter().map(|t| t.flow.as_str()).collect();
        assert_eq!(flows, ["exact", "model"], "scale {}", s.scale);
        assert_eq!(s.flow.as_deref(), Some("exact"));
        for t in &s.temporal {
            assert_eq!(t.camera, "video 0");
            assert_eq!(t.times.len(), 5);
            assert_eq!(t.per_step.len(), 4);
            let sum: f64 = t.per_step.iter().sum();
            assert!((sum - t.warp_error).abs() < 1e-12);
            assert!(t.warp_error > 0.0 && (0.0..=1.0).contains(&t.w_ssim));
        }
        assert_eq!(s.warp_error, Some(s.temporal[0].warp_error));
        assert_eq!(s.w_ssim, Some(s.temporal[0].w_ssim));
        // LPIPS needs 31 px: the 64 px 1x video has it whenever the test views have it.
        assert_eq!(s.w_lpips.is_some(), s.lpips.is_some(), "scale {}", s.scale);
    }
}
