//! Continuing a run from whatever stopped it: the next start first repairs the run
//! folder (a folder swap cut short is put back, temporaries are swept), then restores
//! the newest complete checkpoint (`checkpoints/iter_N` or `model/`), and cuts
//! `log.csv` back to that checkpoint's iteration so no row is logged twice.

use std::path::{Path, PathBuf};

use super::TrainConfig;
use crate::{Error, write_atomic};

/// The complete checkpoint folders `checkpoints/iter_N` (temporaries excluded).
fn checkpoint_dirs(checkpoints: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(checkpoints) else {
        return Vec::new();
    };
    entries
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with("iter_"))
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect()
}

/// Every checkpoint of the run in `out` whose `state.json` reads, newest first (by
/// iteration; `model/` before a checkpoint of the same iteration), with its iteration.
pub fn checkpoints_newest_first(out: &Path) -> Vec<(PathBuf, usize)> {
    let model = maaf_io::readable_dir(&out.join("model")).map(|d| (d, true));
    let checkpoints = checkpoint_dirs(&out.join("checkpoints")).into_iter();
    let mut read: Vec<(PathBuf, usize, bool)> = model
        .into_iter()
        .chain(checkpoints.map(|d| (d, false)))
        .filter_map(|(dir, is_model)| match super::checkpoint_iteration(&dir) {
            Ok(it) => Some((dir, it, is_model)),
            Err(e) => {
                log::warn!("skipping an unreadable checkpoint: {e}");
                None
            }
        })
        .collect();
    read.sort_by_key(|e| std::cmp::Reverse((e.1, e.2)));
    read.into_iter().map(|(d, it, _)| (d, it)).collect()
}

/// Loads, with `load`, the newest checkpoint of `out` that loads, falling back to
/// older ones when a newer one fails (a damaged file, a failed checksum; each
/// reported on one warning line). Returns what `load`
/// gave and the folder used, or `None` when the run has no checkpoint yet (it then
/// starts over).
pub fn load_newest<T>(
    out: &Path,
    mut load: impl FnMut(&Path) -> Result<T, Error>,
) -> Option<(T, PathBuf)> {
    for (dir, _) in checkpoints_newest_first(out) {
        match load(&dir) {
            Ok(t) => return Some((t, dir)),
            Err(e) => log::warn!(
                "skipping a checkpoint that does not load, falling back to an older one: {e}"
            ),
        }
    }
    None
}

/// Rewrites `log.csv` (atomically) as its header plus its rows up to `iteration`:
/// rows a killed process logged after its last checkpoint and a torn last line go.
/// `headers` are the layouts the run may have been logged in, the current one first;
/// returns the index of the one the log has (0 for a log not written yet, which is
/// started with `headers[0]`). Refuses a log whose header is none of them (a
/// different objective).
pub fn truncate_log(
    path: &Path,
    headers: &[Vec<String>],
    iteration: usize,
) -> Result<usize, Error> {
    let bytes = match std::fs::read(path) {
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(Error::io(path, e)),
    };
    let bad = |e: csv::Error| Error::Input(format!("{}: {e}", path.display()));
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(bytes.as_slice());
    let mut records = reader.records();
    let found = match records.next() {
        None => 0,
        Some(first) => {
            let first = first.map_err(bad)?;
            headers
                .iter()
                .position(|h| first.iter().eq(h.iter().map(String::as_str)))
                .ok_or_else(|| {
                    Error::Input(format!(
                        "{}: its columns `{}` differ from this run's objective `{}` (on resume, add the same custom terms as when the run started)",
                        path.display(),
                        first.iter().collect::<Vec<_>>().join(","),
                        headers.first().map_or(String::new(), |h| h.join(","))
                    ))
                })?
        }
    };
    let rows: Vec<csv::StringRecord> = records.collect::<Result<_, _>>().map_err(bad)?;
    // A last row without its newline was torn by a kill: only complete rows count.
    let complete = rows.len() - usize::from(!bytes.ends_with(b"\n") && !rows.is_empty());
    let mut kept = csv::Writer::from_writer(Vec::new());
    kept.write_record(headers.get(found).map_or(&[][..], Vec::as_slice))
        .map_err(bad)?;
    for row in rows[..complete].iter().take_while(|r| {
        let it = r.get(0).and_then(|v| v.parse::<usize>().ok());
        it.is_some_and(|it| it <= iteration)
    }) {
        kept.write_record(row).map_err(bad)?;
    }
    let kept = kept
        .into_inner()
        .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
    write_atomic(path, &kept)?;
    Ok(found)
}

/// Refuses a resume whose settings (`wanted`, from `RUN/config.json`) differ from the
/// checkpoint's (`saved`) anywhere but the iteration budget: a resumed run continues
/// with the checkpoint's settings, so an edited `config.json` would otherwise be
/// silently put back. Names the first differing field and both values.
pub(super) fn same_settings(
    saved: &TrainConfig,
    wanted: &TrainConfig,
    dir: &Path,
    out: &Path,
) -> Result<(), Error> {
    let value = |c: &TrainConfig| {
        let mut c = c.clone();
        c.iterations = 0;
        serde_json::to_value(&c).map_err(|e| Error::Input(format!("config: {e}")))
    };
    if let Some((field, ours, theirs)) = first_difference(&value(wanted)?, &value(saved)?, "") {
        return Err(Error::Input(format!(
            "{}: `{field}` is {ours} but the checkpoint {} was trained with {theirs}; a resumed run keeps its settings (put it back, or start a new run from the checkpoint with --from)",
            out.join("config.json").display(),
            dir.display()
        )));
    }
    Ok(())
}

/// The first path (`a.b.c`) where two JSON values differ, with both values.
fn first_difference(
    a: &serde_json::Value,
    b: &serde_json::Value,
    path: &str,
) -> Option<(String, String, String)> {
    use serde_json::Value;
    if let (Value::Object(x), Value::Object(y)) = (a, b) {
        let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
        keys.sort_unstable();
        keys.dedup();
        return keys.into_iter().find_map(|k| {
            let sub = if path.is_empty() {
                k.clone()
            } else {
                format!("{path}.{k}")
            };
            match (x.get(k), y.get(k)) {
                (Some(u), Some(v)) => first_difference(u, v, &sub),
                (u, v) => {
                    let show = |w: Option<&Value>| w.map_or("absent".into(), Value::to_string);
                    Some((sub, show(u), show(v)))
                }
            }
        });
    }
    (a != b).then(|| (path.to_string(), a.to_string(), b.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_is_cut_back_to_the_checkpoint_and_a_torn_row_dropped() {
        let dir = std::env::temp_dir().join(format!("maaf-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let log = dir.join("log.csv");
        let fields = |line: &str| line.split(',').map(String::from).collect::<Vec<_>>();
        let header = [fields("iteration,l1,total")];
        std::fs::write(
            &log,
            "iteration,l1,total\n1,0.5,0.5\n2,0.4,0.4\n3,0.3,0.3\n4,0.2",
        )
        .expect("w");
        truncate_log(&log, &header, 2).expect("truncate");
        assert_eq!(
            std::fs::read_to_string(&log).expect("r"),
            "iteration,l1,total\n1,0.5,0.5\n2,0.4,0.4\n"
        );
        std::fs::write(&log, "iteration,l1,total\n1,0.5,0.5\n2,0.4").expect("w");
        assert_eq!(truncate_log(&log, &header, 9).expect("truncate"), 0);
        assert_eq!(
            std::fs::read_to_string(&log).expect("r"),
            "iteration,l1,total\n1,0.5,0.5\n"
        );
        let both = [fields("iteration,l1,0.8*l1,total"), header[0].clone()];
        assert_eq!(truncate_log(&log, &both, 9).expect("older layout"), 1);
        assert_eq!(
            std::fs::read_to_string(&log).expect("r"),
            "iteration,l1,total\n1,0.5,0.5\n"
        );
        let other = [fields("iteration,l1,mine,total")];
        let err = truncate_log(&log, &other, 9).expect_err("other objective");
        assert!(
            err.to_string().contains("differ from this run's objective"),
            "{err}"
        );
        std::fs::remove_file(&log).expect("rm");
        truncate_log(&log, &header, 0).expect("no log yet");
        assert_eq!(
            std::fs::read_to_string(&log).expect("r"),
            "iteration,l1,total\n"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
