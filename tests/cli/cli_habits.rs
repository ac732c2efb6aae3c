//! The command line's habits, as a user meets them: every option's default in
//! `--help`, help that names only the command's own options, `info` printing what it
//! says, a misspelt filter answered with the close name, one `--background` spelling
//! everywhere, `maaf cameras` feeding `render --camera` (at the file's time), `render
//! --size` keeping the camera's aspect, `render-video` along camera paths and refusing a
//! video file name, `report` printing every evaluated scale, and `train` asking for
//! `--out`.

use std::path::Path;
use std::process::{Command, Output};

use maaf::train::data::{Dataset, DatasetOptions, Split};

use super::support::{TempDir, s, tiny_scene};

/// Runs `maaf args`, returning its output whatever the exit status.
fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args(args)
        .output()
        .expect("run maaf")
}

/// Runs `maaf args` and fails the test unless it succeeds; returns stdout.
fn ok(args: &[&str]) -> String {
    let out = run(args);
    assert!(
        out.status.success(),
        "maaf {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs `maaf args`, expects a failure, returns stderr.
fn fails(args: &[&str]) -> String {
    let out = run(args);
    assert!(!out.status.success(), "maaf {args:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Width and height of a PNG.
fn png_size(path: &Path) -> (u32, u32) {
    let img = maaf::train::data::image::decode_rgba(path).expect("png");
    (img.width, img.height)
}

/// Options that take a value but have no default by design: one of a required pair
/// (`--view` / `--camera` of `render` say so in their text; `export-ply --time` /
/// `--frames`), or the mode switches of `train` (`--resume`, `--from`) and the
/// `--out` that `--resume` replaces.
const NO_DEFAULT: [(&str, &str); 5] = [
    ("export-ply", "--time"),
    ("export-ply", "--frames"),
    ("train", "--resume"),
    ("train", "--from"),
    ("train", "--out"),
];

#[test]
fn every_optional_value_shows_its_default_in_help() {
    let commands = [
        "demo",
        "generate",
        "inspect",
        "cameras",
        "train",
        "eval",
        "render",
        "render-video",
        "report",
        "compare",
        "bench",
        "export-ply",
        "render-ply",
        "sweep",
        "bench-suite",
    ];
    let mut missing = Vec::new();
    for cmd in commands {
        let help = ok(&[cmd, "--help"]);
        let usage = help
            .lines()
            .find(|l| l.starts_with("Usage:"))
            .expect("usage line");
        // The blocks of `--help`: an option line, then its indented description.
        let mut blocks: Vec<(String, String)> = Vec::new();
        for line in help.lines() {
            let t = line.trim_start();
            if t.starts_with("--") || (t.starts_with('-') && t.contains(", --")) {
                blocks.push((t.to_string(), String::new()));
            } else if let Some(b) = blocks.last_mut() {
                b.1.push_str(line);
                b.1.push('\n');
            }
        }
        for (head, body) in blocks {
            let name = head
                .split(|c: char| c.is_whitespace() || c == ',')
                .find(|w| w.starts_with("--"))
                .expect("option name")
                .to_string();
            let takes_value = head.contains('<');
            let required = usage.contains(&format!("{name} <"));
            let text = format!("{head}\n{body}");
            if takes_value
                && !required
                && !text.contains("[default:")
                && !NO_DEFAULT.contains(&(cmd, name.as_str()))
            {
                missing.push(format!("maaf {cmd} {name}"));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "options without a default in --help: {missing:?}"
    );
}

#[test]
fn cameras_render_sizes_paths_backgrounds_and_report() {
    let tmp = TempDir::fresh("cli_habits");
    let (data, run_dir) = (tmp.0.join("data"), tmp.0.join("run"));
    tiny_scene(&data);
    // `--out` is asked for by the parser, before any work.
    let err = fails(&["train", "--data", s(&data), "--iters", "1"]);
    assert!(err.contains("--out"), "{err}");
    ok(&[
        "train",
        "--data",
        s(&data),
        "--out",
        s(&run_dir),
        "--train-scale",
        "0.5",
        "--iters",
        "20",
        "--background",
        "1,1,1",
    ]);

    // A split's cameras as files, at the training scale: rendering one through
    // --camera gives the same PNG as the view itself.
    let cams = tmp.0.join("cams");
    ok(&[
        "cameras",
        "--data",
        s(&data),
        "--split",
        "test",
        "--scale",
        "0.5",
        "--out",
        s(&cams),
    ]);
    let ds = Dataset::open(&data, DatasetOptions::default()).expect("data");
    let times = ds.times(Split::Test);
    let listing: serde_json::Value =
        serde_json::from_slice(&std::fs::read(cams.join("cameras.json")).expect("listing"))
            .expect("json");
    let listed = listing["cameras"].as_array().expect("cameras");
    assert_eq!(listed.len(), times.len());
    assert_eq!(listed[1]["file"], "0001.json");
    assert_eq!(listed[1]["time"].as_f64(), Some(times[1]));
    let (by_view, by_file) = (tmp.0.join("view.png"), tmp.0.join("file.png"));
    ok(&[
        "render",
        "--run",
        s(&run_dir),
        "--view",
        "test:1",
        "--out",
        s(&by_view),
    ]);
    // The camera file carries its view's time, which render uses without --time.
    let cam1 = cams.join("0001.json");
    let by_camera = ["render", "--run", s(&run_dir), "--camera", s(&cam1)];
    let said = ok(&[&by_camera[..], &["--out", s(&by_file)]].concat());
    assert!(
        times[1] > 0.0 && said.contains(&format!("t = {}", times[1])),
        "{said}"
    );
    assert_eq!(
        std::fs::read(&by_view).expect("view png"),
        std::fs::read(&by_file).expect("file png")
    );
    let at_t = tmp.0.join("t.png");
    let said = ok(&[&by_camera[..], &["--time", "0.75", "--out", s(&at_t)]].concat());
    assert!(
        said.contains("t = 0.75"),
        "--time overrides the file's time: {said}"
    );

    // --size instead of --scale, on a view and on a camera file (32x32): the camera's
    // aspect, or a refusal naming both sizes rather than a stretched image.
    let sized = tmp.0.join("sized.png");
    for source in [
        ["--view", "test:0"],
        ["--camera", s(&cams.join("0000.json"))],
    ] {
        let args = ["render", "--run", s(&run_dir), source[0], source[1]];
        ok(&[&args[..], &["--size", "40x40", "--out", s(&sized)]].concat());
        assert_eq!(png_size(&sized), (40, 40));
        let err = fails(&[&args[..], &["--size", "40x30", "--out", s(&sized)]].concat());
        assert!(
            err.contains("--size 40x30") && err.contains("32x32") && err.contains("40x40"),
            "{err}"
        );
    }
    let err = fails(&[
        "render",
        "--run",
        s(&run_dir),
        "--view",
        "test:0",
        "--size",
        "40x30",
        "--scale",
        "2",
        "--out",
        s(&sized),
    ]);
    assert!(err.contains("--scale") && err.contains("--size"), "{err}");
    let err = fails(&[
        "render",
        "--run",
        s(&run_dir),
        "--view",
        "test:0",
        "--size",
        "40",
        "--out",
        s(&sized),
    ]);
    assert!(err.contains("WxH"), "{err}");

    // One --background spelling: the run trained on "1,1,1" renders with "white".
    ok(&[
        "render",
        "--run",
        s(&run_dir),
        "--view",
        "test:0",
        "--background",
        "white",
        "--out",
        s(&sized),
    ]);
    let err = fails(&[
        "render",
        "--run",
        s(&run_dir),
        "--view",
        "test:0",
        "--background",
        "grey",
        "--out",
        s(&sized),
    ]);
    assert!(err.contains("white, black or r,g,b"), "{err}");

    // Videos along an orbit, a spiral and the test views.
    for (path, frames, expected) in [
        ("orbit", "3", 3),
        ("spiral", "4", 4),
        ("test", "3", times.len()),
    ] {
        let video = tmp.0.join(format!("video_{path}"));
        ok(&[
            "render-video",
            "--run",
            s(&run_dir),
            "--path",
            path,
            "--frames",
            frames,
            "--out",
            s(&video),
        ]);
        let pngs = std::fs::read_dir(&video)
            .expect("video folder")
            .filter(|e| {
                e.as_ref()
                    .expect("entry")
                    .file_name()
                    .to_string_lossy()
                    .ends_with(".png")
            })
            .count();
        assert_eq!(pngs, expected, "{path}");
        assert!(video.join("video.gif").exists());
    }
    let orbit0 = tmp.0.join("video_orbit").join("frame_0000.png");
    let orbit1 = tmp.0.join("video_orbit").join("frame_0001.png");
    assert_ne!(
        std::fs::read(orbit0).expect("frame 0"),
        std::fs::read(orbit1).expect("frame 1"),
        "an orbit moves the camera"
    );
    let err = fails(&[
        "render-video",
        "--run",
        s(&run_dir),
        "--out",
        s(&tmp.0.join("video_fixed")),
    ]);
    assert!(err.contains("--view"), "{err}");
    // A video file name is refused before any work, naming the folder to give instead.
    let err = fails(&[
        "render-video",
        "--run",
        s(&run_dir),
        "--path",
        "orbit",
        "--out",
        s(&tmp.0.join("v.mp4")),
    ]);
    assert!(
        err.contains("v.mp4") && err.contains("not a .mp4 file"),
        "{err}"
    );
    assert!(!tmp.0.join("v.mp4").exists(), "nothing written");

    // `report` prints every evaluated scale, zoom-out included.
    ok(&[
        "eval",
        "--run",
        s(&run_dir),
        "--scales",
        "0.5,1,2",
        "--max-views",
        "1",
        "--no-images",
    ]);
    let printed = ok(&[
        "report",
        "--runs",
        s(&run_dir),
        "--out",
        s(&tmp.0.join("report")),
    ]);
    for col in ["PSNR 1/2x", "PSNR 1x", "PSNR 2x"] {
        assert!(printed.contains(col), "{col}: {printed}");
    }
}

/// `maaf info | head -0`: a closed standard output ends the process by SIGPIPE, as
/// other command-line tools end, not by a panic and its backtrace.
#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_the_command_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    let out = Command::new(env!("CARGO_BIN_EXE_maaf"))
        .arg("info")
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .expect("run maaf");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.signal(),
        Some(libc::SIGPIPE),
        "{:?}: {err}",
        out.status
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// Every `--option` a command's `--help` mentions is one of its own (or a global one),
/// unless the text names the command it belongs to (`maaf eval --scales`).
#[test]
fn help_mentions_only_the_commands_own_options() {
    let mut strays = Vec::new();
    for cmd in [
        "render",
        "render-video",
        "sweep",
        "train",
        "eval",
        "export-ply",
        "render-ply",
    ] {
        let help = ok(&[cmd, "--help"]);
        let own: Vec<&str> = help
            .lines()
            .map(str::trim_start)
            .filter(|l| l.starts_with("--") || (l.starts_with('-') && l.contains(", --")))
            .filter_map(|l| {
                l.split(|c: char| c.is_whitespace() || c == ',')
                    .find(|w| w.starts_with("--"))
            })
            .collect();
        for line in help.lines() {
            let mut rest = line;
            while let Some(i) = rest.find("--") {
                let before = &rest[..i];
                let word: String = rest[i..]
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                    .collect();
                rest = &rest[i + word.len().max(2)..];
                let other_command = before.contains("maaf ") || before.contains("`maaf");
                if word.len() > 2 && !own.contains(&word.as_str()) && !other_command {
                    strays.push(format!(
                        "maaf {cmd} --help mentions {word}: {}",
                        line.trim()
                    ));
                }
            }
        }
    }
    assert!(strays.is_empty(), "{strays:#?}");
}

#[test]
fn info_prints_the_float_types_and_threads_and_inspect_names_its_layouts() {
    let info = ok(&["info"]);
    assert!(
        info.contains("f32") && info.contains("f64") && info.contains("threads:"),
        "{info}"
    );
    let help = ok(&["inspect", "--help"]);
    for layout in ["D-NeRF", "Plenoptic Video", "Dynamic 3D Gaussians"] {
        assert!(help.contains(layout), "{layout}: {help}");
    }
}

/// A misspelt filter gets the close name, before any data is read or folder made; a
/// name far from every filter gets the list and how to register one.
#[test]
fn a_misspelt_filter_is_answered_with_the_close_name() {
    let tmp = TempDir::fresh("cli_did_you_mean");
    let run_dir = tmp.0.join("run");
    let args = [
        "train",
        "--data",
        "/nonexistent/data",
        "--out",
        s(&run_dir),
        "--filter",
    ];
    let err = fails(&[&args[..], &["mip"]].concat());
    assert!(
        err.contains("filter `mip` is not registered: did you mean `mip3d`?"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!run_dir.exists());
    let err = fails(&[&args[..], &["gaussian_blur"]].concat());
    assert!(
        !err.contains("did you mean") && err.contains("none, mip3d, motion, window_max"),
        "{err}"
    );
}
