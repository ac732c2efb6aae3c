//! A trained run without its data set: the data folder moved away, `maaf
//! render` (camera file), `render-video` (fixed camera and an orbit around the
//! training cameras the run saved) and `export-ply` work from the run alone and render
//! what they rendered before the move; `maaf eval` refuses in one line naming the
//! missing folder and suggesting --data, and with `--data NEW` writes the numbers it
//! wrote before the move.

use super::support::{fixture, maaf, refused, s, succeeded};

#[test]
fn a_run_renders_exports_and_evaluates_after_its_data_folder_moved() {
    let fx = fixture("moved_data");
    let run = fx.trained("run");
    let cams = fx.root.join("cams");
    let t1 = {
        let data = maaf::train::data::Dataset::open(&fx.data, Default::default()).expect("data");
        data.times(maaf::train::data::Split::Test)[1].to_string()
    };
    succeeded(maaf(&[
        "cameras",
        "--data",
        s(&fx.data),
        "--split",
        "test",
        "--scale",
        "0.5",
        "--out",
        s(&cams),
    ]));
    let before = fx.root.join("before.png");
    succeeded(maaf(&[
        "render",
        "--run",
        s(&run),
        "--view",
        "test:1",
        "--out",
        s(&before),
    ]));
    let eval = ["--max-views", "2", "--scales", "0.5,1", "--no-images"];
    succeeded(maaf(&[&["eval", "--run", s(&run)][..], &eval].concat()));
    let scales_of = |run: &std::path::Path| -> serde_json::Value {
        let text = std::fs::read(run.join("eval.json")).expect("eval.json");
        serde_json::from_slice::<serde_json::Value>(&text).expect("json")["scales"].clone()
    };
    let scored = scales_of(&run);

    let recorded = maaf::scene::run_data::recorded_data(&run)
        .expect("data.json")
        .expect("recorded")
        .root;
    let moved = fx.root.join("moved");
    std::fs::rename(&fx.data, &moved).expect("move the data away");

    // Rendering and export need no data set.
    let after = fx.root.join("after.png");
    succeeded(maaf(&[
        "render",
        "--run",
        s(&run),
        "--camera",
        s(&cams.join("0001.json")),
        "--time",
        &t1,
        "--out",
        s(&after),
    ]));
    assert_eq!(
        std::fs::read(&before).expect("before"),
        std::fs::read(&after).expect("after"),
        "the camera file renders what the view rendered before the move"
    );
    for path in ["fixed", "orbit"] {
        let video = fx.root.join(format!("video_{path}"));
        succeeded(maaf(&[
            "render-video",
            "--run",
            s(&run),
            "--camera",
            s(&cams.join("0000.json")),
            "--path",
            path,
            "--frames",
            "3",
            "--out",
            s(&video),
        ]));
        assert!(video.join("frame_0002.png").is_file(), "{path}");
    }
    let ply = fx.root.join("frame.ply");
    succeeded(maaf(&[
        "export-ply",
        "--run",
        s(&run),
        "--time",
        "0.5",
        "--out",
        s(&ply),
    ]));
    assert!(ply.is_file());
    let seq = fx.root.join("seq");
    succeeded(maaf(&[
        "export-ply",
        "--run",
        s(&run),
        "--frames",
        "2",
        "--out",
        s(&seq),
    ]));
    assert!(seq.join("frame_0001.ply").is_file());

    // What needs the data set says where it was and how to point at its new place.
    let gone = format!("{} is gone", recorded.display());
    refused(
        maaf(&[&["eval", "--run", s(&run)][..], &eval].concat()),
        &[&gone, "--data"],
    );
    refused(
        maaf(&[
            "render",
            "--run",
            s(&run),
            "--view",
            "test:0",
            "--out",
            s(&fx.root.join("x.png")),
        ]),
        &[&gone, "--data"],
    );
    std::fs::remove_file(run.join("eval.json")).expect("remove eval.json");
    succeeded(maaf(
        &[&["eval", "--run", s(&run), "--data", s(&moved)][..], &eval].concat(),
    ));
    assert_eq!(scales_of(&run), scored, "eval on the moved data set");
}
