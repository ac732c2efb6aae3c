//! `maaf sweep` as a user runs it: a two-axis ablation on a tiny built-in scene becomes
//! one config per point and one shell line per point; two of the lines are run as
//! written (train + eval), and the report script reports exactly the evaluated points.

use std::process::{Command, Output};

use super::support::{TempDir, s};

fn run(cmd: &mut Command) -> Output {
    let out = cmd.output().expect("spawn");
    assert!(
        out.status.success(),
        "{cmd:?} failed: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn maaf() -> Command {
    Command::new(env!("CARGO_BIN_EXE_maaf"))
}

#[test]
fn sweep_writes_configs_and_runnable_job_lines() {
    let tmp = TempDir::fresh("cli_sweep");
    let (data, sweep) = (tmp.0.join("data"), tmp.0.join("sweep"));
    run(maaf()
        .args([
            "generate",
            "--out",
            s(&data),
            "--size",
            "48",
            "--frames",
            "3",
        ])
        .arg("--samples")
        .arg("1"));
    let out = run(maaf().args([
        "sweep",
        "--data",
        s(&data),
        "--out",
        s(&sweep),
        "--iters",
        "12",
        "--train-scale",
        "0.5",
        "--grid",
        "filter.grid_t=25,50,100",
        "--grid",
        "filter.h_x=0.1,0.3",
        "--eval-args",
        "--scales 1 --no-images",
    ]));
    let printed = String::from_utf8_lossy(&out.stdout);
    // base + T in {25, 50} (100 is the default) + h_x = 0.1 (0.3 is the default).
    assert!(printed.contains("sweep: 4 points"), "{printed}");
    let jobs = std::fs::read_to_string(sweep.join("jobs.txt")).expect("jobs.txt");
    let lines: Vec<&str> = jobs.lines().collect();
    assert_eq!(lines.len(), 4, "{jobs}");
    let t25: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(sweep.join("configs/filter.grid_t=25.json")).expect("config"),
    )
    .expect("json");
    assert_eq!(t25["filter"]["grid_t"], 25);
    assert_eq!(t25["iterations"], 12);

    // The report script refuses while nothing is evaluated.
    let none = Command::new("sh")
        .arg(sweep.join("report.sh"))
        .output()
        .expect("sh");
    assert!(!none.status.success());
    assert!(String::from_utf8_lossy(&none.stderr).contains("no evaluated point"));

    // Two job lines exactly as written, from another working folder.
    for line in &lines[..2] {
        run(Command::new("sh").arg("-c").arg(line).current_dir(&tmp.0));
    }
    for name in ["base", "filter.grid_t=25"] {
        assert!(
            sweep.join(name).join("eval.json").is_file(),
            "{name} not evaluated"
        );
    }
    let report = run(Command::new("sh").arg(sweep.join("report.sh")));
    let table = String::from_utf8_lossy(&report.stdout);
    assert!(table.contains("filter.grid_t=25"), "{table}");
    assert!(
        !table.contains("filter.h_x=0.1"),
        "an unevaluated point was reported: {table}"
    );
}
