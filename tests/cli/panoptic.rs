//! The Dynamic 3D Gaussians (CMU Panoptic) layout from the command line: `maaf
//! generate --layout dynamic3dgs`, `maaf inspect` naming its cameras, focal range and
//! masks, `maaf train` starting from the visual hull, and `maaf eval --frame-stride`.

use std::process::{Command, Output};

use crate::support::{TempDir, panoptic, s};

fn maaf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_maaf"))
        .args(args)
        .output()
        .expect("run maaf")
}

fn ok(out: &Output) -> (String, String) {
    let (o, e) = (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    );
    assert!(out.status.success(), "{o}\n{e}");
    (o, e)
}

#[test]
fn generate_inspect_train_and_eval_a_panoptic_layout_scene() {
    let t = TempDir::fresh("panoptic_cli");
    let (data, run) = (t.0.join("scene"), t.0.join("run"));
    let o = panoptic(&data, "64", "48", "6", "4");
    assert!(o.contains("Dynamic 3D Gaussians layout"), "{o}");
    let (o, _) = ok(&maaf(&["inspect", "--data", s(&data)]));
    for words in [
        "train   20 views  5 cameras",
        "20 foreground masks",
        "visual hull",
        "files",
    ] {
        assert!(o.contains(words), "inspect lacks {words:?}:\n{o}");
    }
    // The rig's unequal focal lengths print as a range, `f = lo..hi px`.
    let train_line = o
        .lines()
        .find(|l| l.trim_start().starts_with("train"))
        .expect("train line");
    let focal = train_line
        .split("f = ")
        .nth(1)
        .and_then(|r| r.split(" px").next());
    assert!(focal.is_some_and(|f| f.contains("..")), "{train_line}");
    let train = [
        "train",
        "--data",
        s(&data),
        "--out",
        s(&run),
        "--iters",
        "10",
        "--train-scale",
        "0.5",
        "--filter",
        "motion",
    ];
    let (_, e) = ok(&maaf(&train));
    assert!(e.contains("on the visual hulls"), "{e}");
    let eval = [
        "eval",
        "--run",
        s(&run),
        "--scales",
        "0.5,1,2",
        "--frame-stride",
        "2",
        "--no-images",
    ];
    let (o, e) = ok(&maaf(&eval));
    assert!(o.contains("| 2x | 64x48 |"), "{o}");
    assert!(e.contains("(2 views"), "two of the four frames: {e}");
    let text = std::fs::read_to_string(run.join("eval.json")).expect("eval.json");
    assert!(text.contains("\"frame_stride\": 2"), "{text}");
    // The layout's keys are checked: a missing test_meta.json is one line naming it.
    std::fs::remove_file(data.join("test_meta.json")).expect("removes");
    let out = maaf(&["inspect", "--data", s(&data)]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("test_meta.json") && e.trim().lines().count() == 1,
        "{e}"
    );
}
