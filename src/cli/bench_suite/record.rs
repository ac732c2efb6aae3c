//! `maaf bench-suite --out OUT --record DIR`: the suite's measurements without its
//! checkpoints and models, a few kB per run, so that a suite's report can be rebuilt
//! (`--report-only --out DIR`) after its run folders are gone (another machine, a
//! cleaned disk) and so that runs of one suite done on several machines, or in several
//! suite folders, can be put together into one report.
//!
//! A record is a suite folder: `DIR/suite.json` (marked as a record, its run folders
//! relative to DIR) and, per evaluated run, `runs/SCENE/NAME/` with exactly the files
//! the suite report reads: `eval.json`, `summary.json` and `eval-on-*.json`. Recording
//! into an existing record adds the runs to it (a run recorded again is replaced), as
//! long as configs of one name and the `maaf eval` arguments agree, so that every row
//! of the record was measured the same way.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use maaf_eval::eval_json::OTHER_BACKGROUND_PREFIX;
use maaf_eval::report::suite::SuiteRun;
use maaf_scene::write_atomic;

use super::eval_plan::words;
use super::{SPEC_FILE, SuiteSpec, holds_files, read_spec};

/// What [`record`] did: runs copied, and runs left out because not evaluated yet.
pub(super) struct Recorded {
    /// Run folders copied, relative to the record.
    pub copied: Vec<PathBuf>,
    /// Run folders of the suite without `eval.json`.
    pub not_evaluated: Vec<PathBuf>,
}

/// The run folder of `run` relative to the suite folder `out` (`runs/SCENE/NAME` for a
/// suite written by `maaf bench-suite`; a folder outside `out` keeps its last name).
fn relative_dir(run: &SuiteRun, out: &Path) -> PathBuf {
    match run.dir.strip_prefix(out) {
        Ok(rel) => rel.to_path_buf(),
        Err(_) => Path::new("runs")
            .join(&run.scene)
            .join(run.dir.file_name().unwrap_or(run.dir.as_os_str())),
    }
}

/// The files of a run folder the suite report reads: `eval.json`, `summary.json` (when
/// there) and every `eval-on-*.json`, by name.
fn measured_files(run: &Path) -> anyhow::Result<Vec<String>> {
    let mut names = vec!["eval.json".to_string()];
    if run.join("summary.json").is_file() {
        names.push("summary.json".to_string());
    }
    let entries =
        std::fs::read_dir(run).with_context(|| format!("{}: cannot read", run.display()))?;
    for entry in entries {
        let entry = entry.with_context(|| format!("{}: cannot read", run.display()))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(OTHER_BACKGROUND_PREFIX) && name.ends_with(".json") {
            names.push(name);
        }
    }
    names.sort();
    Ok(names)
}

/// The record already in `dir`, if any; an error when `dir` holds something else.
fn existing_record(dir: &Path) -> anyhow::Result<Option<SuiteSpec>> {
    if dir.join(SPEC_FILE).is_file() {
        let old = read_spec(dir)?;
        if !old.record {
            bail!(
                "{}: a suite folder, not a record; record into a new folder or an earlier record",
                dir.display()
            );
        }
        return Ok(Some(old));
    }
    if holds_files(dir)? {
        bail!(
            "{}: not empty and holds no {SPEC_FILE}; a record is written into a new folder or an earlier record",
            dir.display()
        );
    }
    Ok(None)
}

/// The spec of `old` with `new`'s configs and runs added: a config of the same name must
/// be the same, the `maaf eval` arguments too; a run of the same folder is replaced.
fn merge(old: SuiteSpec, new: SuiteSpec, dir: &Path) -> anyhow::Result<SuiteSpec> {
    if words(&old.eval_args) != words(&new.eval_args) {
        bail!(
            "{}: its runs were evaluated with --eval-args `{}`, these with `{}`; record them into another folder",
            dir.join(SPEC_FILE).display(),
            old.eval_args,
            new.eval_args
        );
    }
    let mut configs = old.configs;
    for (name, config) in new.configs {
        match configs.iter().find(|(n, _)| *n == name) {
            Some((_, c)) if *c != config => bail!(
                "{}: holds another configuration named {name}; record these runs into another folder",
                dir.join(SPEC_FILE).display()
            ),
            Some(_) => {}
            None => configs.push((name, config)),
        }
    }
    let mut runs: Vec<SuiteRun> = old
        .runs
        .into_iter()
        .filter(|r| !new.runs.iter().any(|n| n.dir == r.dir))
        .collect();
    runs.extend(new.runs);
    runs.sort_by(|a, b| a.scene.cmp(&b.scene));
    Ok(SuiteSpec {
        configs,
        runs,
        ..new
    })
}

/// Copies the measurements of every evaluated run of the suite in `out` (its runs'
/// folders resolved) into the record `dir` (module docs). The record is checked before
/// anything is copied; a new record is built in a temporary sibling and moved into
/// place whole, and into an earlier one `suite.json` is written last, so a refused or
/// failed recording (a full disk) leaves the record as it was, or none.
pub(super) fn record(spec: &SuiteSpec, out: &Path, dir: &Path) -> anyhow::Result<Recorded> {
    if dir == out {
        bail!(
            "--record {}: the suite's own folder; record into another one",
            dir.display()
        );
    }
    let (evaluated, not_evaluated): (Vec<&SuiteRun>, Vec<&SuiteRun>) = spec
        .runs
        .iter()
        .partition(|r| r.dir.join("eval.json").is_file());
    let new = SuiteSpec {
        record: true,
        runs: evaluated
            .iter()
            .map(|r| SuiteRun {
                dir: relative_dir(r, out),
                ..(*r).clone()
            })
            .collect(),
        ..spec.clone()
    };
    let copied: Vec<PathBuf> = new.runs.iter().map(|r| r.dir.clone()).collect();
    let recorded = Recorded {
        copied: copied.clone(),
        not_evaluated: not_evaluated.iter().map(|r| r.dir.clone()).collect(),
    };
    let runs: Vec<(&Path, &Path)> = evaluated
        .iter()
        .zip(&copied)
        .map(|(r, rel)| (r.dir.as_path(), rel.as_path()))
        .collect();
    if let Some(old) = existing_record(dir)? {
        write_record(dir, &merge(old, new, dir)?, &runs)?;
        return Ok(recorded);
    }
    maaf_io::remove_dead_temps(dir).with_context(|| format!("{}: cannot clean", dir.display()))?;
    let tmp = maaf_io::temp_sibling(dir);
    let built = write_record(&tmp, &new, &runs).and_then(|()| {
        maaf_io::replace_dir(&tmp, dir).with_context(|| format!("{}: cannot write", dir.display()))
    });
    if built.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    built
        .with_context(|| format!("{}: not recorded, nothing written", dir.display()))
        .map(|()| recorded)
}

/// Copies the measured files of `runs` (each a run folder and its folder relative to
/// the record) into the record `dir`, then writes its `suite.json`.
fn write_record(dir: &Path, spec: &SuiteSpec, runs: &[(&Path, &Path)]) -> anyhow::Result<()> {
    for &(run, rel) in runs {
        let target = dir.join(rel);
        std::fs::create_dir_all(&target)
            .with_context(|| format!("{}: cannot create", target.display()))?;
        let names = measured_files(run)?;
        for name in &names {
            let from = run.join(name);
            let bytes =
                std::fs::read(&from).with_context(|| format!("{}: cannot read", from.display()))?;
            write_atomic(&target.join(name), &bytes)?;
        }
        // A run recorded again: files of its earlier recording it no longer has go.
        for stale in measured_files(&target)?
            .iter()
            .filter(|n| !names.contains(n))
        {
            let path = target.join(stale);
            std::fs::remove_file(&path)
                .with_context(|| format!("{}: cannot remove", path.display()))?;
        }
    }
    let json = serde_json::to_string_pretty(spec)?;
    write_atomic(&dir.join(SPEC_FILE), json.as_bytes())?;
    Ok(())
}
