//! Resuming a run: settings a resume cannot honour are refused, and a damaged checkpoint
//! is detected and the previous one used.

use super::*;

#[test]
fn case_6_settings_a_resume_cannot_honour_are_refused() {
    let fx = fixture("integrity_settings");
    let run = fx.trained("run");
    refused(
        maaf(&["train", "--resume", s(&run), "--background", "white"]),
        &[
            "--background white (the run's is black)",
            "a resumed run keeps its settings",
        ],
    );
    refused(
        maaf(&["train", "--resume", s(&run), "--iters", "4"]),
        &["the run has trained 6 iterations, past the budget of 4"],
    );
    let config = std::fs::read_to_string(run.join("config.json")).expect("config");
    assert!(
        config.contains("\"iterations\": 6,"),
        "budget kept: {config}"
    );
    let branch = fx.root.join("branch");
    let ckpt = run.join("checkpoints/iter_000004");
    for iters in ["4", "3"] {
        refused(
            maaf(&[
                "train",
                "--data",
                s(&fx.data),
                "--from",
                s(&ckpt),
                "--out",
                s(&branch),
                "--train-scale",
                "0.5",
                "--iters",
                iters,
            ]),
            &["the checkpoint is at iteration 4, so a branch from it needs a budget above 4"],
        );
    }
    assert!(!branch.join("log.csv").exists());
    // A hand-edited config.json is refused, not silently reverted.
    let edited = config.replace("\"lambda_dssim\": 0.2,", "\"lambda_dssim\": 0.5,");
    assert_ne!(edited, config, "lambda_dssim in {config}");
    std::fs::write(run.join("config.json"), &edited).expect("edit");
    refused(
        maaf(&["train", "--resume", s(&run), "--iters", "8"]),
        &[
            "`lambda_dssim` is 0.5 but the checkpoint",
            "was trained with 0.2",
        ],
    );
    assert_eq!(
        std::fs::read_to_string(run.join("config.json")).expect("config"),
        edited
    );
}

#[test]
fn case_7_a_damaged_checkpoint_is_detected_and_the_previous_one_used() {
    let fx = fixture("integrity_checksum");
    let run = fx.trained("run");
    let tensors = run.join("model/tensors.safetensors");
    let mut bytes = std::fs::read(&tensors).expect("tensors");
    let n = bytes.len();
    assert!(n > 10_000, "{n} bytes");
    bytes[n - 5000..].fill(0);
    std::fs::write(&tensors, &bytes).expect("damage");
    refused(
        maaf(&["eval", "--run", s(&run), "--max-views", "1"]),
        &["tensors.safetensors: damaged: its CRC-32 is"],
    );
    let err = succeeded(maaf(&["train", "--resume", s(&run), "--iters", "8"]));
    assert!(
        err.contains("warning: skipping a checkpoint that does not load")
            && err.contains("damaged"),
        "{err}"
    );
    assert!(
        err.contains("resuming from") && err.contains("iter_000004"),
        "{err}"
    );
    succeeded(maaf(&[
        "eval",
        "--run",
        s(&run),
        "--max-views",
        "1",
        "--scales",
        "1",
        "--no-images",
    ]));
}
