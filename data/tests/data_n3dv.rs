//! Plenoptic Video loader: a `poses_bounds.npy` written by hand in LLFF's convention
//! gives the expected camera centres, viewing directions, focal (half-size frames) and
//! times; every bad input gets one line naming the file and field.

use std::path::Path;

use glam::DVec3;
use maaf_data::{DataError, Dataset, DatasetOptions, Format, Split};
use maaf_io::TempDir;
use npyz::WriterBuilder;

/// A hand-made camera: centre and LLFF axes (down, right, back) in world coordinates.
struct HandCam {
    centre: [f64; 3],
    down: [f64; 3],
    right: [f64; 3],
    back: [f64; 3],
}

/// Three cameras, world z up. cam00 looks along (cos 30, sin 30, 0) with down = -z;
/// cam01 looks along +x with down = -z (so right = -y); cam02 looks down -z from above
/// with down = +y (so right = -x).
fn hand_cams() -> Vec<HandCam> {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    vec![
        HandCam {
            centre: [-1.0, 0.5, 1.5],
            down: [0.0, 0.0, -1.0],
            right: [s, -c, 0.0],
            back: [-c, -s, 0.0],
        },
        HandCam {
            centre: [1.0, 2.0, 3.0],
            down: [0.0, 0.0, -1.0],
            right: [0.0, -1.0, 0.0],
            back: [-1.0, 0.0, 0.0],
        },
        HandCam {
            centre: [0.0, 0.0, 5.0],
            down: [0.0, 1.0, 0.0],
            right: [-1.0, 0.0, 0.0],
            back: [0.0, 0.0, 1.0],
        },
    ]
}

/// `[H, W, focal]` of the "original videos": 40 x 64 with focal 100; frames are written
/// at half that size, 32 x 20, so the expected focal is 50.
const HWF: [f64; 3] = [40.0, 64.0, 100.0];
const FRAME_W: u32 = 32;
const FRAME_H: u32 = 20;

/// The 17 values of one row: `[down right back centre hwf]` row by row, then near, far.
fn row(cam: &HandCam) -> Vec<f64> {
    let mut v = Vec::new();
    for (r, hwf) in HWF.iter().enumerate() {
        v.extend([cam.down[r], cam.right[r], cam.back[r], cam.centre[r], *hwf]);
    }
    v.extend([0.5, 20.0]);
    v
}

fn write_npy_f64(path: &Path, rows: &[Vec<f64>], cols: u64) {
    let mut out = Vec::new();
    let mut w = npyz::WriteOptions::<f64>::new()
        .default_dtype()
        .shape(&[rows.len() as u64, cols])
        .writer(&mut out)
        .begin_nd()
        .expect("npy header");
    w.extend(rows.iter().flatten().copied()).expect("npy data");
    w.finish().expect("npy finish");
    std::fs::write(path, out).expect("write npy");
}

/// Frame `j` of camera `c` is a flat colour `(c / 10, j / 10, 0.5)`.
fn frame_colour(c: usize, j: usize) -> [u8; 3] {
    [(c * 25) as u8, (j * 25) as u8, 128]
}

fn write_frames(root: &Path, c: usize, n: usize, w: u32, h: u32) {
    let dir = root.join(format!("cam{c:02}/images"));
    std::fs::create_dir_all(&dir).expect("mkdir");
    for j in 0..n {
        let img = image::RgbImage::from_pixel(w, h, image::Rgb(frame_colour(c, j)));
        img.save(dir.join(format!("{j:04}.png"))).expect("png");
    }
}

fn hand_scene(tag: &str) -> TempDir {
    let t = TempDir::new(tag).expect("temp dir");
    let cams = hand_cams();
    let rows: Vec<Vec<f64>> = cams.iter().map(row).collect();
    write_npy_f64(&t.path().join("poses_bounds.npy"), &rows, 17);
    for c in 0..cams.len() {
        write_frames(t.path(), c, 3, FRAME_W, FRAME_H);
    }
    t
}

fn check_hand_cameras(data: &Dataset) {
    let cams = hand_cams();
    let v = |a: [f64; 3]| DVec3::from_array(a);
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-6;
    // Train: cam01 frames 0..3 then cam02 frames 0..3; test: cam00.
    let expect = [
        (Split::Test, 0, 0),
        (Split::Train, 0, 1),
        (Split::Train, 3, 2),
    ];
    for (split, index, c) in expect {
        let cam = data.camera(split, index, 1.0).expect("camera");
        let h = &cams[c];
        assert!(
            close(cam.center(), v(h.centre)),
            "cam{c} centre {:?}",
            cam.center()
        );
        // OpenCV: camera +z is the viewing direction = -back, +y = down, +x = right.
        let r_t = cam.rotation().transpose();
        assert!(close(r_t * DVec3::Z, -v(h.back)), "cam{c} view dir");
        assert!(close(r_t * DVec3::Y, v(h.down)), "cam{c} down");
        assert!(close(r_t * DVec3::X, v(h.right)), "cam{c} right");
        assert!((cam.fx - 50.0).abs() < 1e-6 && (cam.fy - 50.0).abs() < 1e-6);
        assert_eq!((cam.cx, cam.cy), (16.0, 10.0));
        assert_eq!((cam.width, cam.height), (FRAME_W, FRAME_H));
        // A point 2 units along the viewing direction projects to the centre pixel; one
        // also 0.2 to the camera's right and 0.1 down lands at (16 + 5, 10 + 2.5).
        let p = v(h.centre) - 2.0 * v(h.back);
        let (u, w, z) = cam.project(p).expect("in front");
        assert!((u - 16.0).abs() < 1e-6 && (w - 10.0).abs() < 1e-6 && (z - 2.0).abs() < 1e-6);
        let q = p + 0.2 * v(h.right) + 0.1 * v(h.down);
        let (u, w, _) = cam.project(q).expect("in front");
        assert!(
            (u - 21.0).abs() < 1e-6 && (w - 12.5).abs() < 1e-6,
            "({u}, {w})"
        );
    }
}

#[test]
fn hand_written_poses_bounds_gives_centres_directions_focal_and_times() {
    let t = hand_scene("hand");
    let data = Dataset::open(t.path(), DatasetOptions::default()).expect("opens");
    assert_eq!(data.format(), Format::Plenoptic);
    assert_eq!(data.len(Split::Train), 6);
    assert_eq!(data.len(Split::Test), 3);
    assert_eq!(data.len(Split::Video), 0);
    check_hand_cameras(&data);
    // t = frame / frames, per camera.
    let third = [0.0, 1.0 / 3.0, 2.0 / 3.0];
    assert_eq!(data.times(Split::Test), third.to_vec());
    assert_eq!(data.times(Split::Train), [third, third].concat());
    // Views keep the camera-major order and the frame order of the files.
    for (split, index, c, j) in [(Split::Test, 2, 0, 2), (Split::Train, 4, 2, 1)] {
        let view = data.view(split, index, 1.0).expect("view");
        let want = frame_colour(c, j).map(|b| b as f32 / 255.0);
        assert_eq!(view.image.pixel(3, 4), &want[..], "{split}[{index}]");
    }
    assert!(data.moving_mask(0, 1.0).expect("no error").is_none());
}

#[test]
fn float32_and_fortran_order_tables_read_the_same() {
    let t = hand_scene("f32");
    let rows: Vec<Vec<f64>> = hand_cams().iter().map(row).collect();
    let mut out = Vec::new();
    let mut w = npyz::WriteOptions::<f32>::new()
        .default_dtype()
        .shape(&[3, 17])
        .writer(&mut out)
        .begin_nd()
        .expect("header");
    w.extend(rows.iter().flatten().map(|&x| x as f32))
        .expect("data");
    w.finish().expect("finish");
    std::fs::write(t.path().join("poses_bounds.npy"), out).expect("write");
    check_hand_cameras(&Dataset::open(t.path(), DatasetOptions::default()).expect("f32 opens"));

    // Fortran order: column by column.
    let mut out = Vec::new();
    let mut w = npyz::WriteOptions::<f64>::new()
        .default_dtype()
        .order(npyz::Order::Fortran)
        .shape(&[3, 17])
        .writer(&mut out)
        .begin_nd()
        .expect("header");
    w.extend((0..17).flat_map(|c| rows.iter().map(move |r| r[c])))
        .expect("data");
    w.finish().expect("finish");
    std::fs::write(t.path().join("poses_bounds.npy"), out).expect("write");
    check_hand_cameras(&Dataset::open(t.path(), DatasetOptions::default()).expect("fortran opens"));
}

#[test]
fn capped_open_keeps_evenly_spread_times() {
    let t = TempDir::new("cap").expect("temp dir");
    let cams = hand_cams();
    write_npy_f64(
        &t.path().join("poses_bounds.npy"),
        &cams.iter().map(row).collect::<Vec<_>>(),
        17,
    );
    for c in 0..3 {
        write_frames(t.path(), c, 5, FRAME_W, FRAME_H);
    }
    let data = Dataset::open_capped(t.path(), DatasetOptions::default(), Some(3)).expect("opens");
    // 5 frames: t = 0, .2, .4, .6, .8; keep indices 0, 2, 4 for both training cameras.
    assert_eq!(data.times(Split::Train), vec![0.0, 0.4, 0.8, 0.0, 0.4, 0.8]);
    assert_eq!(data.len(Split::Test), 5, "only train is capped");
    let all = Dataset::open_capped(t.path(), DatasetOptions::default(), None).expect("opens");
    assert_eq!(all.len(Split::Train), 10);
}

fn open_err(dir: &Path) -> String {
    let err: DataError = Dataset::open(dir, DatasetOptions::default()).expect_err("must fail");
    let msg = err.to_string();
    assert!(!msg.contains('\n'), "error must be one line: {msg}");
    msg
}

fn with_rows(tag: &str, edit: impl Fn(&mut Vec<Vec<f64>>)) -> TempDir {
    let t = hand_scene(tag);
    let mut rows: Vec<Vec<f64>> = hand_cams().iter().map(row).collect();
    edit(&mut rows);
    let cols = rows[0].len() as u64;
    write_npy_f64(&t.path().join("poses_bounds.npy"), &rows, cols);
    t
}

fn assert_all(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "{msg:?} should contain {p:?}");
    }
}

#[test]
fn bad_tables_name_the_file_and_field() {
    let t = with_rows("shape", |rows| rows.iter_mut().for_each(|r| r.truncate(16)));
    assert_all(
        &open_err(t.path()),
        &["poses_bounds.npy", "`shape`", "(N, 17)", "16"],
    );

    let t = with_rows("rigid", |rows| rows[1][0] = 2.0);
    assert_all(
        &open_err(t.path()),
        &["poses_bounds.npy", "`rows[1].c2w`", "not a rotation"],
    );

    let t = with_rows("hwf", |rows| rows[2][14] = -3.0);
    assert_all(
        &open_err(t.path()),
        &["poses_bounds.npy", "`rows[2].hwf`", "must all be positive"],
    );

    let t = with_rows("nan", |rows| rows[0][3] = f64::NAN);
    assert_all(&open_err(t.path()), &["`rows[0][3]`", "not finite"]);

    let t = with_rows("rows", |rows| {
        rows.pop();
    });
    assert_all(
        &open_err(t.path()),
        &["poses_bounds.npy", "2 rows but", "3 camera folders"],
    );

    let t = hand_scene("garbage");
    std::fs::write(t.path().join("poses_bounds.npy"), b"not numpy").expect("write");
    assert_all(
        &open_err(t.path()),
        &["poses_bounds.npy", "not a readable .npy array"],
    );

    let t = hand_scene("dtype");
    let mut out = Vec::new();
    let mut w = npyz::WriteOptions::<i32>::new()
        .default_dtype()
        .shape(&[3, 17])
        .writer(&mut out)
        .begin_nd()
        .expect("header");
    w.extend(std::iter::repeat_n(1, 51)).expect("data");
    w.finish().expect("finish");
    std::fs::write(t.path().join("poses_bounds.npy"), out).expect("write");
    assert_all(
        &open_err(t.path()),
        &["`dtype`", "float64 or float32", "i4"],
    );
}

#[test]
fn bad_frame_folders_name_the_folder_or_file() {
    // Frames whose aspect does not match [H, W] (32 x 32 against 40 x 64).
    let t = hand_scene("aspect");
    for c in 0..3 {
        write_frames(t.path(), c, 3, 32, 32);
    }
    assert_all(
        &open_err(t.path()),
        &["poses_bounds.npy", "`rows[0].hwf`", "aspect"],
    );

    let t = hand_scene("noimages");
    std::fs::remove_dir_all(t.path().join("cam01/images")).expect("rm");
    assert_all(&open_err(t.path()), &["cam01/images", "cannot list frames"]);

    let t = hand_scene("count");
    std::fs::remove_file(t.path().join("cam02/images/0002.png")).expect("rm");
    assert_all(
        &open_err(t.path()),
        &["cam02/images", "has 2 frames but", "has 3"],
    );

    let t = hand_scene("size");
    image::RgbImage::new(16, 10)
        .save(t.path().join("cam01/images/0001.png"))
        .expect("png");
    assert_all(
        &open_err(t.path()),
        &["cam01/images/0001.png", "16x10", "one size"],
    );

    let t = hand_scene("decode");
    std::fs::write(t.path().join("cam02/images/0000.png"), b"\x89PNG broken").expect("write");
    assert_all(
        &open_err(t.path()),
        &["cam02/images/0000.png", "does not decode"],
    );

    let t = hand_scene("nocams");
    for c in 0..3 {
        std::fs::remove_dir_all(t.path().join(format!("cam{c:02}"))).expect("rm");
    }
    assert_all(
        &open_err(t.path()),
        &["no camera folders", "cam00/images/0000.png"],
    );

    let t = hand_scene("onecam");
    write_npy_f64(
        &t.path().join("poses_bounds.npy"),
        &[row(&hand_cams()[0])],
        17,
    );
    for c in 1..3 {
        std::fs::remove_dir_all(t.path().join(format!("cam{c:02}"))).expect("rm");
    }
    assert_all(
        &open_err(t.path()),
        &["poses_bounds.npy", "only one camera"],
    );

    let t = TempDir::new("empty").expect("temp dir");
    assert_all(
        &open_err(t.path()),
        &["neither transforms_train.json", "poses_bounds.npy"],
    );
}
