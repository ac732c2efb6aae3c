//! Crash-safe output (one implementation for every crate of maaf).
//!
//! Every file maaf writes goes through [`write_atomic`]: the bytes are written to a
//! temporary sibling, flushed to disk (`fsync`), renamed over the target, and the
//! folder itself is synced so the rename survives a power cut. A reader therefore
//! sees, at every instant, either the complete old file or the complete new one. A
//! failed write (full disk, read-only folder) removes its temporary file, so nothing
//! is left behind to keep the disk full.
//!
//! Folders (checkpoints, evaluation outputs, generated data sets) are built under a
//! temporary name ([`temp_sibling`]) and swapped in by [`replace_dir`]. Leftover
//! temporaries of a killed process start with `.` and contain [`TEMP_MARK`];
//! [`remove_stale_temps`] sweeps them on the next start.

use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

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
/// rename over `path`, `fsync` of the folder. On error the temporary is removed and
/// `path` is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = temp_sibling(path);
    let result = (|| {
        let mut f = File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)?;
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
            File::open(&path)?.sync_all()?;
        }
    }
    sync_dir(dir)
}

/// Moves the complete folder `new` (a [`temp_sibling`] of `target`) into place as
/// `target`. An existing `target` stays readable until the new one is in place: it is
/// renamed aside to `.NAME.old.maaf-tmp-PID` first and removed only after the swap.
/// Between the two renames a reader finds the old version under that name, which
/// [`recover_dir`] restores if the process dies there.
pub fn replace_dir(new: &Path, target: &Path) -> io::Result<()> {
    sync_tree(new)?;
    let parent = parent_of(target);
    if target.exists() {
        let old = old_sibling(target);
        if old.exists() {
            fs::remove_dir_all(&old)?;
        }
        fs::rename(target, &old)?;
        fs::rename(new, target)?;
        sync_dir(parent)?;
        fs::remove_dir_all(&old)?;
    } else {
        fs::rename(new, target)?;
        sync_dir(parent)?;
    }
    Ok(())
}

/// Where [`replace_dir`] parks the old version of `target` during the swap.
fn old_sibling(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    parent_of(target).join(format!(".{name}.old{TEMP_MARK}{}", std::process::id()))
}

/// If `target` is missing because a process died between the two renames of
/// [`replace_dir`], puts the parked old version back. Returns whether it did.
pub fn recover_dir(target: &Path) -> io::Result<bool> {
    if target.exists() {
        return Ok(false);
    }
    let Some(name) = target.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return Ok(false);
    };
    let prefix = format!(".{name}.old{TEMP_MARK}");
    let parent = parent_of(target);
    let Ok(entries) = fs::read_dir(parent) else {
        return Ok(false);
    };
    for entry in entries.flatten() {
        if entry.file_name().to_string_lossy().starts_with(&prefix) {
            fs::rename(entry.path(), target)?;
            sync_dir(parent)?;
            return Ok(true);
        }
    }
    Ok(false)
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
            let path = entry.path();
            if entry.file_type()?.is_dir() {
                fs::remove_dir_all(&path)?;
            } else {
                fs::remove_file(&path)?;
            }
            removed += 1;
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
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
    fn replace_dir_swaps_and_recover_restores_a_parked_folder() {
        let dir = scratch("dir");
        let target = dir.join("model");
        for version in ["v1", "v2"] {
            let tmp = temp_sibling(&target);
            fs::create_dir_all(&tmp).expect("mkdir");
            fs::write(tmp.join("f"), version).expect("write");
            replace_dir(&tmp, &target).expect("replace");
            assert_eq!(fs::read_to_string(target.join("f")).expect("read"), version);
        }
        assert_eq!(fs::read_dir(&dir).expect("ls").count(), 1);
        // A death between the two renames: the old version is parked, no target.
        let parked = old_sibling(&target);
        fs::rename(&target, &parked).expect("park");
        assert!(recover_dir(&target).expect("recover"));
        assert_eq!(fs::read_to_string(target.join("f")).expect("read"), "v2");
        assert!(!recover_dir(&target).expect("nothing to do"));
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
