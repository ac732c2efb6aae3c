//! `maaf bench-suite --record`: a record keeps a suite's measurements, reports without
//! the run folders and gathers several suites; the repository's published records still
//! report every run.

use super::*;

#[test]
fn a_record_keeps_the_measurements_reports_without_the_runs_and_gathers_suites() {
    let tmp = TempDir::fresh("cli_bench_suite_record");
    let (data, preset, first) = one_scene(&tmp);
    let record = tmp.0.join("record");
    ok(suite(&data, &preset, &first, &["--filters", "none"]));
    let md_of = |dir: &Path| std::fs::read_to_string(dir.join("report.md")).expect("report.md");
    let original = md_of(&first);

    let printed = ok(maaf(&[
        "bench-suite",
        "--out",
        s(&first),
        "--record",
        s(&record),
    ]));
    assert!(printed.contains("recorded 1 of 1 runs"), "{printed}");
    let run = record.join("runs/a/small-none-black");
    let mut files: Vec<String> = std::fs::read_dir(&run)
        .expect("record run")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(
        files,
        ["eval.json", "summary.json"],
        "only what the report reads"
    );
    let spec = std::fs::read_to_string(record.join("suite.json")).expect("suite.json");
    assert!(
        spec.contains(r#""dir": "runs/a/small-none-black""#),
        "{spec}"
    );

    // The suite's folder gone, the record reports the same tables.
    std::fs::remove_dir_all(&first).expect("rm suite");
    ok(maaf(&["bench-suite", "--out", s(&record), "--report-only"]));
    assert_eq!(md_of(&record), original);

    // A second suite folder (as on another machine), one of its two runs evaluated:
    // that run is added to the record, the other named as left out.
    let second = tmp.0.join("second");
    ok(suite(
        &data,
        &preset,
        &second,
        &["--filters", "motion,mip3d", "--jobs-only"],
    ));
    ok(maaf(&["bench-suite", "--out", s(&second), "--job", "1"]));
    let printed = ok(maaf(&[
        "bench-suite",
        "--out",
        s(&second),
        "--record",
        s(&record),
    ]));
    assert!(printed.contains("recorded 1 of 2 runs"), "{printed}");
    assert!(
        printed.contains("left out: ") && printed.contains("small-mip3d-black"),
        "{printed}"
    );
    ok(maaf(&["bench-suite", "--out", s(&record), "--report-only"]));
    let md = md_of(&record);
    for method in ["small / none / black", "small / motion / black"] {
        assert_eq!(count(&md, &format!("| {method} | a | test |")), 3, "{md}");
    }
    assert!(!md.contains("mip3d"), "{md}");

    // A record is not a suite: its runs are not trained, nor other runs planned there.
    refused(
        maaf(&["bench-suite", "--out", s(&record), "--job", "1"]),
        &["suite.json", "a record", "--report-only"],
    );
    refused(
        suite(&data, &preset, &record, &[]),
        &["suite.json", "a record"],
    );
    // Runs evaluated otherwise are not mixed into it; nor is a record written over
    // other files or into its own suite.
    let third = tmp.0.join("third");
    ok(maaf(&[
        "bench-suite",
        "--data",
        s(&data),
        "--preset",
        s(&preset),
        "--out",
        s(&third),
        "--iters",
        "6",
        "--filters",
        "none",
        "--eval-args",
        "--no-images --max-views 1",
    ]));
    refused(
        maaf(&["bench-suite", "--out", s(&third), "--record", s(&record)]),
        &["suite.json", "--max-views 1", "another folder"],
    );
    // Refused before anything is copied: the record still reports its own run.
    ok(maaf(&["bench-suite", "--out", s(&record), "--report-only"]));
    assert_eq!(
        md_of(&record)
            .lines()
            .find(|l| l.contains("| small / none / black | a |")),
        md.lines()
            .find(|l| l.contains("| small / none / black | a |"))
    );
    refused(
        maaf(&["bench-suite", "--out", s(&third), "--record", s(&data)]),
        &["not empty", "suite.json"],
    );
    refused(
        maaf(&["bench-suite", "--out", s(&third), "--record", s(&third)]),
        &["--record", "own folder"],
    );
}

#[test]
fn the_records_of_the_published_tables_still_report_every_run() {
    let records = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/results/suites");
    let tmp = TempDir::fresh("cli_bench_suite_published_records");
    let mut seen = 0;
    for entry in std::fs::read_dir(&records).expect("docs/results/suites") {
        let record = entry.expect("entry").path();
        let copy = tmp.0.join(record.file_name().expect("name"));
        copy_dir(&record, &copy);
        for stale in ["report.md", "report.json", "speed_quality.png"] {
            let _ = std::fs::remove_file(copy.join(stale));
        }
        ok(maaf(&["bench-suite", "--out", s(&copy), "--report-only"]));
        let spec: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(copy.join("suite.json")).expect("suite.json"),
        )
        .expect("suite.json parses");
        assert_eq!(spec["record"], true, "{}", record.display());
        let md = std::fs::read_to_string(copy.join("report.md")).expect("report.md");
        let runs = spec["runs"].as_array().expect("runs");
        assert!(
            md.contains(&format!("{} of {} runs evaluated", runs.len(), runs.len())),
            "{}: {md}",
            record.display()
        );
        for run in runs {
            let scene = run["scene"].as_str().expect("scene");
            assert!(md.contains(&format!(" | {scene} | ")), "{scene}: {md}");
        }
        seen += 1;
    }
    assert!(seen > 0, "no records in {}", records.display());
}
