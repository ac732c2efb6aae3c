//! Input that used to be accepted silently is refused in one line naming the file and
//! field: a camera file whose rotation block is not a rotation or whose last row is
//! not `[0, 0, 0, 1]`, a principal point so far off that pixels look sideways, and
//! Panoptic data whose
//! cameras all face away or whose masks are all background (the visual hull would be
//! empty); a bad focal length is named as the intrinsics' field; and an archive
//! export cut short by a full disk reports the one error, no writer's debug line.

use std::path::Path;
use std::process::Command;

use super::support::{copy_dir, fixture, maaf, panoptic, refused, s, stderr, succeeded};

/// A camera file looking down the z axis from 4 units out, with `w2c` edited.
fn camera_file(path: &Path, cx: f64, edit: impl Fn(&mut [[f64; 4]; 4])) {
    let mut w2c = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 4.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    edit(&mut w2c);
    let json = serde_json::json!({
        "width": 32, "height": 32, "fx": 40.0, "fy": 40.0, "cx": cx, "cy": 16.0,
        "world_to_camera": w2c,
    });
    std::fs::write(path, json.to_string()).expect("camera");
}

#[test]
fn camera_files_must_hold_a_rigid_pose_and_a_principal_point_in_view() {
    let fx = fixture("silent_camera");
    let run = fx.trained("run");
    let cam = fx.root.join("cam.json");
    let png = fx.root.join("out.png");
    let render = || {
        maaf(&[
            "render",
            "--run",
            s(&run),
            "--camera",
            s(&cam),
            "--out",
            s(&png),
        ])
    };
    camera_file(&cam, 16.0, |_| {});
    succeeded(render());
    camera_file(&cam, 16.0, |m| {
        for row in m.iter_mut().take(3) {
            for v in row.iter_mut().take(3) {
                *v *= 3.0;
            }
        }
    });
    refused(
        render(),
        &[
            "cam.json",
            "world_to_camera",
            "rotation block is not a rotation",
        ],
    );
    camera_file(&cam, 16.0, |m| m[3] = [0.0, 0.0, 0.5, 1.0]);
    refused(render(), &["world_to_camera", "last row"]);
    camera_file(&cam, 1e12, |_| {});
    refused(render(), &["field `cx`", "degrees off the optical axis"]);
}

/// `train_meta.json` of `dir` with `edit` applied to every entry's `k` and `w2c`.
fn edit_train_meta(dir: &Path, edit: impl Fn(&mut serde_json::Value, &mut serde_json::Value)) {
    let path = dir.join("train_meta.json");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
    let frames = meta["k"].as_array().expect("k").len();
    for j in 0..frames {
        let n = meta["k"][j].as_array().expect("k[j]").len();
        for i in 0..n {
            let mut k = meta["k"][j][i].take();
            let mut w2c = meta["w2c"][j][i].take();
            edit(&mut k, &mut w2c);
            meta["k"][j][i] = k;
            meta["w2c"][j][i] = w2c;
        }
    }
    std::fs::write(&path, meta.to_string()).expect("write");
}

/// `maaf train` of a few iterations on `data` into `out`.
fn train(data: &Path, out: &Path) -> std::process::Output {
    maaf(&[
        "train",
        "--data",
        s(data),
        "--out",
        s(out),
        "--iters",
        "2",
        "--train-scale",
        "0.5",
    ])
}

#[test]
fn panoptic_data_that_would_train_on_nothing_is_refused() {
    let fx = fixture("silent_panoptic");
    let data = fx.root.join("pan");
    panoptic(&data, "64", "48", "6", "4");
    // Every camera turned to face away, its centre kept: R' = diag(-1, 1, -1) R.
    let away = fx.root.join("away");
    copy_dir(&data, &away);
    edit_train_meta(&away, |_, w2c| {
        for r in [0, 2] {
            for c in 0..4 {
                let v = w2c[r][c].as_f64().expect("number");
                w2c[r][c] = serde_json::json!(-v);
            }
        }
    });
    refused(
        train(&away, &fx.root.join("r_away")),
        &["faces away from the middle of the cameras", "w2c"],
    );
    // Every foreground mask all background.
    let black = fx.root.join("black");
    copy_dir(&data, &black);
    let mut stack = vec![black.join("seg")];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).expect("ls").flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let empty = maaf::train::data::Image::filled(64, 48, 4, 0.0);
                maaf::train::data::image::encode_rgba_png(&empty, &p).expect("mask");
            }
        }
    }
    refused(
        train(&black, &fx.root.join("r_black")),
        &["visual hull", "all background"],
    );
    // A focal length too short for a pinhole camera is named as the k entry.
    let wide = fx.root.join("wide");
    copy_dir(&data, &wide);
    edit_train_meta(&wide, |k, _| k[0][0] = serde_json::json!(0.01));
    refused(
        maaf(&["inspect", "--data", s(&wide)]),
        &["train_meta.json", "field `k[0][0]`", "fx"],
    );
    // A principal point at 10^12 px.
    let far = fx.root.join("far");
    copy_dir(&data, &far);
    edit_train_meta(&far, |k, _| k[0][2] = serde_json::json!(1e12));
    refused(
        maaf(&["inspect", "--data", s(&far)]),
        &["field `k[0][0]`", "cx", "degrees off the optical axis"],
    );
}

#[test]
fn a_zip_export_on_a_full_disk_reports_one_line() {
    let fx = fixture("silent_zip");
    let run = fx.trained("run");
    let zip = fx.root.join("frames.zip");
    // Files over 4 kB cannot be written (as on a full disk); the signal such a write
    // raises is ignored, so the write fails with an error instead.
    let out = Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 8; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_maaf"))
        .args([
            "export-ply",
            "--run",
            s(&run),
            "--frames",
            "3",
            "--out",
            s(&zip),
        ])
        .output()
        .expect("run");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("maaf: error: ") && !err.contains("ZipWriter"),
        "one line, no writer's debug line: {err}"
    );
    assert!(err.contains("frames.zip"), "{err}");
    assert!(!zip.exists());
}
