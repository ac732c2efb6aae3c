//! `log.csv` holds each term's weighted value under `<weight>*<name>` beside its
//! unweighted value, and a run logged before those columns still resumes, appending
//! in its own layout.

use super::support::{fixture, succeeded};

/// The header and the rows of a `log.csv`, split on commas.
fn read_log(path: &std::path::Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).expect("log");
    let mut lines = text
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect());
    let header = lines.next().expect("header");
    (header, lines.collect())
}

fn column(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

#[test]
fn the_log_has_weighted_terms_and_an_older_log_resumes_in_its_layout() {
    let fx = fixture("log_columns");
    succeeded(fx.train("run", r#""log_every": 1"#));
    let run = fx.root.join("run");
    let (header, rows) = read_log(&run.join("log.csv"));
    assert_eq!(rows.len(), 6, "{rows:?}");
    for (term, weighted, w) in [("l1", "0.8*l1", 0.8), ("dssim", "0.2*dssim", 0.2)] {
        let (a, b) = (column(&header, term), column(&header, weighted));
        for row in &rows {
            let value: f64 = row[a].parse().expect("value");
            let contribution: f64 = row[b].parse().expect("weighted");
            assert!(
                (contribution - w * value).abs() <= 1e-6 * value.abs(),
                "{row:?}"
            );
        }
    }

    // The same run as logged before the weighted columns existed.
    let old_columns: Vec<usize> = (0..header.len())
        .filter(|&i| !header[i].contains('*'))
        .collect();
    let old_text: String = std::iter::once(&header)
        .chain(&rows)
        .map(|r| {
            let cells: Vec<&str> = old_columns.iter().map(|&i| r[i].as_str()).collect();
            cells.join(",") + "\n"
        })
        .collect();
    std::fs::write(run.join("log.csv"), &old_text).expect("old log");
    let err = succeeded(fx.resume(&run, "8"));
    assert!(err.contains("predates the weighted-term columns"), "{err}");
    let (resumed_header, resumed) = read_log(&run.join("log.csv"));
    assert_eq!(
        resumed_header.len(),
        old_columns.len(),
        "{resumed_header:?}"
    );
    assert!(resumed_header.iter().all(|h| !h.contains('*')));
    let iterations: Vec<&str> = resumed.iter().map(|r| r[0].as_str()).collect();
    assert_eq!(iterations, ["1", "2", "3", "4", "5", "6", "7", "8"]);
    assert!(
        resumed.iter().all(|r| r.len() == old_columns.len()),
        "{resumed:?}"
    );
}
