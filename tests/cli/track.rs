//! The tracking model from the command line: `maaf train --model track` refuses a
//! densification past frame 0 in one line, trains a generated multi-view video with a
//! config that ends it there, and `maaf export-ply` writes its Gaussians between two
//! frames.

use crate::support::{TempDir, maaf, refused, s, succeeded};

#[test]
fn train_a_generated_video_frame_by_frame_and_export_it() {
    let t = TempDir::fresh("track_cli");
    let (data, run) = (t.0.join("glide"), t.0.join("run"));
    succeeded(maaf(&[
        "generate",
        "--rig",
        "multiview",
        "--scene",
        "glide",
        "--out",
        s(&data),
        "--size",
        "64",
        "--height",
        "48",
        "--cameras",
        "4",
        "--frames",
        "3",
        "--samples",
        "1",
    ]));
    let train = |extra: &[&str]| {
        let mut args = vec![
            "train",
            "--data",
            s(&data),
            "--out",
            s(&run),
            "--model",
            "track",
        ];
        args.extend_from_slice(extra);
        maaf(&args)
    };
    refused(
        train(&["--iters", "30"]),
        &["densify.until = 15000", "frame 0"],
    );
    let config = t.0.join("track.json");
    let text = r#"{"iterations": 30, "train_scale": 1.0, "val_every": 0,
        "model": {"kind": "track", "first_frame_iterations": 0.5},
        "densify": {"from": 5, "every": 5, "until": 15, "opacity_reset_every": 0}}"#;
    std::fs::write(&config, text).expect("config");
    succeeded(train(&["--config", s(&config)]));
    let written = std::fs::read_to_string(run.join("config.json")).expect("config.json");
    assert!(
        written.contains("\"first_frame_iterations\": 0.5"),
        "{written}"
    );
    let ply = t.0.join("between.ply");
    let out = maaf(&[
        "export-ply",
        "--run",
        s(&run),
        "--time",
        "0.5",
        "--out",
        s(&ply),
    ]);
    succeeded(out);
    let bytes = std::fs::read(&ply).expect("ply");
    let header = String::from_utf8_lossy(&bytes[..bytes.len().min(200)]).into_owned();
    assert!(
        header.contains("comment maaf time 0.5\n") && header.contains("\nelement vertex "),
        "{header}"
    );
}
