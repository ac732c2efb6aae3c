//! `maaf eval` on a run trained at 1/16 scale, where the default zoom-out scales ask
//! for ground truth the source images cannot give (a downsampling factor of 64 or 32
//! that does not divide 176, as 800 at 1/4x): it evaluates the scales it can, says
//! which it skipped and why (on stderr and in eval.json), and fails only when it can
//! evaluate none.

use super::support::{TempDir, maaf, refused, s, succeeded};

#[test]
fn eval_on_a_sixteenth_scale_run_skips_the_scales_it_cannot_make() {
    let tmp = TempDir::fresh("cli_eval_scales");
    let (data, run) = (tmp.0.join("data"), tmp.0.join("run"));
    succeeded(maaf(&[
        "generate",
        "--out",
        s(&data),
        "--size",
        "176",
        "--frames",
        "4",
        "--samples",
        "1",
    ]));
    let trained = succeeded(maaf(&[
        "train",
        "--data",
        s(&data),
        "--out",
        s(&run),
        "--train-scale",
        "0.0625",
        "--iters",
        "2",
    ]));
    // The 2-iteration run is far shorter than the default schedule, and is told so.
    assert!(
        trained.contains("warning") && trained.contains("densify.from"),
        "{trained}"
    );

    let out = maaf(&["eval", "--run", s(&run), "--max-views", "1", "--no-images"]);
    let err = succeeded(out);
    for scale in ["0.25x", "0.5x"] {
        assert!(
            err.contains(&format!("scale {scale} skipped")) && err.contains("does not divide"),
            "{scale}: {err}"
        );
    }
    let eval: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("eval.json")).expect("eval.json"))
            .expect("json");
    let scales: Vec<f64> = eval["scales"]
        .as_array()
        .expect("scales")
        .iter()
        .map(|c| c["scale"].as_f64().expect("scale"))
        .collect();
    assert_eq!(scales, [1.0, 2.0, 4.0]);
    let skipped = eval["skipped_scales"].as_array().expect("skipped_scales");
    assert_eq!(skipped.len(), 2, "{eval}");
    assert_eq!(skipped[0]["scale"], 0.25);
    assert!(
        skipped[0]["reason"]
            .as_str()
            .expect("reason")
            .contains("factor 64 does not divide the image size 176x176"),
        "{eval}"
    );

    // Nothing to evaluate: one line naming every scale and its reason, exit 1.
    refused(
        maaf(&[
            "eval",
            "--run",
            s(&run),
            "--scales",
            "0.25,0.5",
            "--no-images",
        ]),
        &["none of the scales can be evaluated", "0.25x", "0.5x"],
    );
}
