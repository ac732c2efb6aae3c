//! Crash-safe output (one implementation for every crate of maaf).
//!
//! Every file maaf writes goes through [`write_atomic`] (or [`write_atomic_with`],
//! which streams): the bytes are written to a temporary sibling, flushed to disk
//! (`fsync`), renamed over the target, and the folder itself is synced so the rename
//! survives a power cut. A reader therefore sees, at every instant, either the
//! complete old file or the complete new one. A failed write (full disk, read-only
//! folder) removes its temporary file, so nothing is left behind to keep the disk
//! full.
//!
//! Folders (checkpoints, evaluation outputs, generated data sets) are built under a
//! temporary name ([`temp_sibling`]) and swapped in by [`replace_dir`]: on Linux one
//! atomic exchange of the two names, so the target always holds a complete version;
//! elsewhere the old version is parked under a hidden name during the swap, where
//! [`readable_dir`] finds it and [`recover_dir`] restores it. Leftover temporaries of
//! a killed process start with `.` and contain [`TEMP_MARK`]; [`remove_stale_temps`]
//! sweeps them on the next start. [`fault`] injects kills and full disks for tests.
//! A command that writes outside a run folder (an export, a video, a generated data
//! set) sweeps the temporaries of its target that a killed process left
//! ([`remove_dead_temps`]). [`lock`] keeps one writer per run folder; [`memory`]
//! checks a user-sized allocation against the memory available before it is made;
//! [`process`] tells whether a temporary's owner still runs and ties child processes
//! to their parent. [`TempDir`] is the scratch folder the tests of every crate write
//! into.

use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

mod dir;
pub mod fault;
pub mod lock;
pub mod memory;
mod name;
pub mod process;
mod registry;
mod scratch;

pub use dir::{copy_tree, readable_dir, recover_dir, recover_parked_in, replace_dir, write_dir};
use fault::Step;
pub use lock::{LockError, RunLock};
pub use name::{is_plugin_name, unknown_name};
pub use registry::Registry;
pub use scratch::TempDir;

/// Marker every temporary name contains (`.NAME.maaf-tmp-PID`).
pub const TEMP_MARK: &str = ".maaf-tmp-";

/// The folder holding `path` (`.` for a bare file name).
pub fn parent_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// A temporary sibling of `path`: same folder (so a rename is atomic), hidden, and
/// unique to this process: `.NAME.maaf-tmp-PID`.
pub fn temp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    parent_of(path).join(format!(".{name}{TEMP_MARK}{}", std::process::id()))
}

/// Flushes a folder's entries (the renames into it) to disk. Folders cannot be
/// opened for syncing on every platform; where they cannot, this is a no-op.
pub fn sync_dir(dir: &Path) -> io::Result<()> {
    match File::open(dir) {
        Ok(f) => f.sync_all().or(Ok(())),
        Err(_) => Ok(()),
    }
}

/// Writes `bytes` to `path` atomically and durably: temporary sibling, `fsync`,
/// rename over `path`, `fsync` of the folder. On error (a full disk included) the
/// temporary is removed and `path` is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    atomic(path, |f| {
        if let Err(e) = fault::step(Step::Data, "write") {
            // An injected full disk: part of the bytes land, then the write fails.
            f.write_all(&bytes[..bytes.len() / 2])?;
            return Err(e);
        }
        f.write_all(bytes)
    })
}

/// [`write_atomic`] for output too large to hold in memory (an archive of many
/// frames): `fill` streams the content into the temporary sibling, which is then
/// synced, renamed over `path` and its folder synced, exactly as [`write_atomic`]
/// does. An error from `fill` or any later step removes the temporary and leaves
/// `path` untouched.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<()> {
    atomic(path, |f| {
        fault::step(Step::Data, "write")?;
        fill(f)
    })
}

/// The steps shared by [`write_atomic`] and [`write_atomic_with`]: create the
/// temporary sibling, `fill` it, fsync, rename, fsync the folder; the temporary is
/// removed on any error.
fn atomic(path: &Path, fill: impl FnOnce(&mut File) -> io::Result<()>) -> io::Result<()> {
    let tmp = temp_sibling(path);
    let result = (|| {
        fault::step(Step::Meta, "create")?;
        let mut f = File::create(&tmp)?;
        fill(&mut f)?;
        fault::step(Step::Meta, "fsync")?;
        f.sync_all()?;
        drop(f);
        fault::step(Step::Meta, "rename")?;
        fs::rename(&tmp, path)?;
        fault::step(Step::Meta, "fsync folder")?;
        sync_dir(parent_of(path))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Syncs every file below `dir` (recursively) and the folders themselves, so a
/// folder built under a temporary name is complete on disk before it is renamed.
pub fn sync_tree(dir: &Path) -> io::Result<()> {
    for entry in fs::read_dir(dir)? {
        let entry = entry?;
        let path = entry.path();
        if entry.file_type()?.is_dir() {
            sync_tree(&path)?;
        } else {
            fault::step(Step::Meta, "fsync")?;
            File::open(&path)?.sync_all()?;
        }
    }
    sync_dir(dir)
}

/// Removes every leftover temporary (a name starting with `.` and containing
/// [`TEMP_MARK`]) directly inside `dir`, files and folders; returns how many. Call
/// it when a run starts, after [`recover_dir`] for the folders it swaps.
pub fn remove_stale_temps(dir: &Path) -> io::Result<usize> {
    let mut removed = 0;
    let Ok(entries) = fs::read_dir(dir) else {
        return Ok(0);
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.contains(TEMP_MARK) {
            remove_entry(&entry)?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// Removes the temporaries of `path` that a process which has ended left beside it
/// (`.NAME.maaf-tmp-PID`, [`temp_sibling`], files or folders; `PID` no longer
/// running, [`process::alive`]); returns how many. A temporary of a running process
/// (another command writing the same target) is kept, and so is the parked old
/// version of a folder swap cut short (`.NAME.old.maaf-tmp-PID`), which
/// [`recover_dir`] restores. Outputs that no lock guards (an export, a video, a
/// generated data set) call it before writing, so a killed command's 30-50 MB
/// leftover does not stay for good.
pub fn remove_dead_temps(path: &Path) -> io::Result<usize> {
    let Some(name) = path.file_name() else {
        return Ok(0);
    };
    let prefix = format!(".{}{TEMP_MARK}", name.to_string_lossy());
    let Ok(entries) = fs::read_dir(parent_of(path)) else {
        return Ok(0);
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = file_name
            .strip_prefix(&prefix)
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if process::alive(pid) {
            continue;
        }
        remove_entry(&entry)?;
        removed += 1;
    }
    Ok(removed)
}

/// Removes a folder entry, a file or a whole folder.
fn remove_entry(entry: &fs::DirEntry) -> io::Result<()> {
    if entry.file_type()?.is_dir() {
        fs::remove_dir_all(entry.path())
    } else {
        fs::remove_file(entry.path())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A fresh, empty scratch folder for one test (named by test and process).
    pub(crate) fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("maaf-io-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    #[test]
    fn write_atomic_replaces_and_leaves_no_temp() {
        let dir = scratch("write");
        let f = dir.join("a.json");
        write_atomic(&f, b"one").expect("write");
        write_atomic(&f, b"two").expect("overwrite");
        assert_eq!(fs::read(&f).expect("read"), b"two");
        let names: Vec<_> = fs::read_dir(&dir).expect("ls").flatten().collect();
        assert_eq!(names.len(), 1, "only the target remains");
    }

    #[test]
    fn failed_write_removes_its_temp_and_keeps_the_old_file() {
        let dir = scratch("fail");
        let f = dir.join("x");
        write_atomic(&f, b"old").expect("write");
        // Renaming a file over a non-empty folder fails after the temp was written.
        let blocked = dir.join("blocked");
        fs::create_dir_all(blocked.join("inner")).expect("mkdir");
        assert!(write_atomic(&blocked, b"new").is_err());
        assert_eq!(fs::read(&f).expect("read"), b"old");
        assert_eq!(remove_stale_temps(&dir).expect("sweep"), 0, "no temp left");
    }

    #[test]
    fn write_atomic_with_streams_and_a_failing_fill_keeps_the_old_file() {
        let dir = scratch("with");
        let f = dir.join("a.zip");
        write_atomic_with(&f, |w| {
            w.write_all(b"one ")?;
            w.write_all(b"two")
        })
        .expect("write");
        assert_eq!(fs::read(&f).expect("read"), b"one two");
        let err = write_atomic_with(&f, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("fill failed"))
        })
        .expect_err("fill error");
        assert_eq!(err.to_string(), "fill failed");
        assert_eq!(fs::read(&f).expect("read"), b"one two", "old file kept");
        assert_eq!(fs::read_dir(&dir).expect("ls").count(), 1, "no temp left");
    }

    /// Child half of the full-disk test: writes `MAAF_IO_TARGET` under the parent's plan.
    #[test]
    fn child_writes_target() {
        if let Ok(target) = std::env::var("MAAF_IO_TARGET") {
            let err = write_atomic(Path::new(&target), &[7u8; 4096]).expect_err("full disk");
            assert_eq!(err.kind(), io::ErrorKind::StorageFull);
        }
    }

    #[test]
    fn a_full_disk_keeps_the_old_file_and_leaves_no_partial_temp() {
        let dir = scratch("enospc");
        let f = dir.join("tensors");
        write_atomic(&f, b"old").expect("write");
        let status = std::process::Command::new(std::env::current_exe().expect("exe"))
            .args(["--exact", "tests::child_writes_target"])
            .env("MAAF_IO_TARGET", &f)
            .env("MAAF_FAULT_ENOSPC_AT_WRITE", "1")
            .status()
            .expect("child");
        assert!(status.success());
        assert_eq!(fs::read(&f).expect("read"), b"old");
        assert_eq!(fs::read_dir(&dir).expect("ls").count(), 1, "no temp left");
    }

    #[test]
    fn the_dead_temps_of_a_target_go_and_a_running_process_keeps_its_own() {
        let dir = scratch("dead");
        let out = dir.join("video");
        let dead = dir.join(format!(".video{TEMP_MARK}{}", 1 << 23));
        fs::create_dir_all(dead.join("inner")).expect("mkdir");
        let running = temp_sibling(&out);
        fs::write(&running, b"being written").expect("write");
        let parked = dir.join(format!(".video.old{TEMP_MARK}{}", 1 << 23));
        fs::create_dir_all(&parked).expect("mkdir");
        let other = dir.join(format!(".frames{TEMP_MARK}{}", 1 << 23));
        fs::write(&other, b"another target's").expect("write");
        let expected = usize::from(cfg!(target_os = "linux"));
        assert_eq!(remove_dead_temps(&out).expect("sweep"), expected);
        assert_eq!(dead.exists(), expected == 0);
        assert!(running.exists() && parked.exists() && other.exists());
    }

    #[test]
    fn stale_temps_are_swept_and_other_files_kept() {
        let dir = scratch("sweep");
        fs::write(dir.join(format!(".log.csv{TEMP_MARK}123")), b"x").expect("write");
        fs::create_dir_all(dir.join(format!(".iter_5{TEMP_MARK}9"))).expect("mkdir");
        fs::write(dir.join(".hidden"), b"keep").expect("write");
        fs::write(dir.join("data.json"), b"keep").expect("write");
        assert_eq!(remove_stale_temps(&dir).expect("sweep"), 2);
        assert_eq!(fs::read_dir(&dir).expect("ls").count(), 2);
    }
}
