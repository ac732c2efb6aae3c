//! Folder replacement that keeps a complete version readable at every instant.
//!
//! On Linux [`replace_dir`] swaps the new folder and the target with one
//! `renameat2(RENAME_EXCHANGE)`: the target's name points at the old complete folder
//! until the kernel points it at the new one. Where the exchange is unsupported (other
//! systems, some file systems) the old folder is parked under `.NAME.old.maaf-tmp-PID`
//! for the instant between two renames; readers go through [`readable_dir`], which
//! finds it there, and [`recover_dir`] puts it back on the next start.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use crate::fault::{self, Step};
use crate::{TEMP_MARK, parent_of, sync_dir, sync_tree};

/// Moves the complete folder `new` (a [`crate::temp_sibling`] of `target`) into place
/// as `target`, durably (every file and folder fsynced first, the parent after). An
/// existing `target` stays readable throughout (see the module doc) and is removed
/// once the new version is in place.
pub fn replace_dir(new: &Path, target: &Path) -> io::Result<()> {
    sync_tree(new)?;
    let parent = parent_of(target);
    if !target.exists() {
        fault::step(Step::Meta, "rename folder")?;
        fs::rename(new, target)?;
        fault::step(Step::Meta, "fsync folder")?;
        return sync_dir(parent);
    }
    fault::step(Step::Meta, "exchange folders")?;
    if !fault::exchange_disabled() && exchange(new, target)? {
        // `new` now names the old version: a hidden temporary, swept if the process dies here.
        fault::step(Step::Meta, "fsync folder")?;
        sync_dir(parent)?;
        fault::step(Step::Meta, "remove old folder")?;
        return fs::remove_dir_all(new);
    }
    let old = old_sibling(target);
    if old.exists() {
        fs::remove_dir_all(&old)?;
    }
    fault::step(Step::Meta, "park old folder")?;
    fs::rename(target, &old)?;
    fault::step(Step::Meta, "rename folder")?;
    fs::rename(new, target)?;
    fault::step(Step::Meta, "fsync folder")?;
    sync_dir(parent)?;
    fault::step(Step::Meta, "remove old folder")?;
    fs::remove_dir_all(&old)
}

/// Writes the folder `out` whole or not at all: what killed writers of `out` left
/// beside it goes first ([`crate::remove_dead_temps`]), `fill` writes the content into
/// a fresh [`crate::temp_sibling`], which [`replace_dir`] then swaps in for `out`
/// (replacing an existing one). On any failure the temporary is removed and `out` is
/// left as it was. `io_err` turns an I/O error at a path into the caller's error.
pub fn write_dir<E>(
    out: &Path,
    io_err: impl Fn(&Path, io::Error) -> E,
    fill: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    crate::remove_dead_temps(out).map_err(|e| io_err(out, e))?;
    let tmp = crate::temp_sibling(out);
    if tmp.exists() {
        fs::remove_dir_all(&tmp).map_err(|e| io_err(&tmp, e))?;
    }
    fs::create_dir_all(&tmp).map_err(|e| io_err(&tmp, e))?;
    let result = fill(&tmp).and_then(|()| replace_dir(&tmp, out).map_err(|e| io_err(out, e)));
    if result.is_err() {
        let _ = fs::remove_dir_all(&tmp);
    }
    result
}

/// Copies the folder tree `from` into `to` (created if needed), file by file; not
/// atomic by itself: wrap it in [`write_dir`] for a folder that must appear whole.
pub fn copy_tree(from: &Path, to: &Path) -> io::Result<()> {
    fs::create_dir_all(to)?;
    for entry in fs::read_dir(from)? {
        let entry = entry?;
        let target = to.join(entry.file_name());
        if entry.file_type()?.is_dir() {
            copy_tree(&entry.path(), &target)?;
        } else {
            fs::copy(entry.path(), &target)?;
        }
    }
    Ok(())
}

/// Atomically exchanges the names `a` and `b`; `Ok(false)` where the system or file
/// system cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> io::Result<bool> {
    use rustix::fs::{CWD, RenameFlags, renameat_with};
    use rustix::io::Errno;
    match renameat_with(CWD, a, CWD, b, RenameFlags::EXCHANGE) {
        Ok(()) => Ok(true),
        Err(Errno::INVAL | Errno::NOSYS | Errno::OPNOTSUPP) => Ok(false),
        Err(e) => Err(e.into()),
    }
}

/// Atomically exchanges the names `a` and `b`; `Ok(false)` where the system or file
/// system cannot.
#[cfg(not(target_os = "linux"))]
fn exchange(_a: &Path, _b: &Path) -> io::Result<bool> {
    Ok(false)
}

/// Where the fallback of [`replace_dir`] parks the old version of `target`.
fn old_sibling(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    parent_of(target).join(format!(".{name}.old{TEMP_MARK}{}", std::process::id()))
}

/// The marker between a parked folder's target name and the parking process id.
fn parked_marker() -> String {
    format!(".old{TEMP_MARK}")
}

/// A parked old version of `target` left by any process, if there is one.
fn parked(target: &Path) -> Option<PathBuf> {
    let name = target.file_name()?.to_string_lossy().into_owned();
    let prefix = format!(".{name}{}", parked_marker());
    fs::read_dir(parent_of(target))
        .ok()?
        .flatten()
        .find(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .map(|e| e.path())
}

/// The folder a reader of `target` should open: `target` itself, or, if a process
/// died inside the fallback swap of [`replace_dir`], the parked complete old version;
/// `None` if neither exists.
pub fn readable_dir(target: &Path) -> Option<PathBuf> {
    if target.is_dir() {
        return Some(target.to_path_buf());
    }
    parked(target)
}

/// If `target` is missing because a process died inside the fallback swap of
/// [`replace_dir`], puts the parked old version back. Returns whether it did.
pub fn recover_dir(target: &Path) -> io::Result<bool> {
    if target.exists() {
        return Ok(false);
    }
    let Some(old) = parked(target) else {
        return Ok(false);
    };
    fs::rename(old, target)?;
    sync_dir(parent_of(target))?;
    Ok(true)
}

/// [`recover_dir`] for every folder parked directly inside `dir` (whatever its
/// target's name, which the caller may not know while the target is missing);
/// returns how many it put back. Parked copies whose target exists are left for
/// [`crate::remove_stale_temps`].
pub fn recover_parked_in(dir: &Path) -> io::Result<usize> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Ok(0);
    };
    let marker = parked_marker();
    let mut restored = 0;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let target = name
            .strip_prefix('.')
            .and_then(|stem| stem.find(&marker).map(|i| dir.join(&stem[..i])));
        if let Some(target) = target {
            restored += usize::from(recover_dir(&target)?);
        }
    }
    Ok(restored)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temp_sibling;
    use crate::tests::scratch;
    use std::process::Command;

    fn install(target: &Path, version: &str) -> io::Result<()> {
        let tmp = temp_sibling(target);
        fs::create_dir_all(&tmp)?;
        fs::write(tmp.join("a"), version)?;
        fs::write(tmp.join("b"), version)?;
        replace_dir(&tmp, target)
    }

    #[test]
    fn replace_dir_swaps_and_recover_restores_a_parked_folder() {
        let dir = scratch("dir");
        let target = dir.join("model");
        for version in ["v1", "v2"] {
            install(&target, version).expect("replace");
            assert_eq!(fs::read_to_string(target.join("a")).expect("read"), version);
        }
        assert_eq!(fs::read_dir(&dir).expect("ls").count(), 1);
        // A death inside the fallback swap: the old version is parked, no target.
        let parked = old_sibling(&target);
        fs::rename(&target, &parked).expect("park");
        assert_eq!(readable_dir(&target), Some(parked.clone()));
        assert!(recover_dir(&target).expect("recover"));
        assert_eq!(fs::read_to_string(target.join("a")).expect("read"), "v2");
        assert!(!recover_dir(&target).expect("nothing to do"));
        assert_eq!(readable_dir(&dir.join("absent")), None);
        // The same death, recovered without knowing the target's name.
        fs::rename(&target, &parked).expect("park");
        assert_eq!(recover_parked_in(&dir).expect("recover all"), 1);
        assert_eq!(fs::read_to_string(target.join("a")).expect("read"), "v2");
    }

    /// Child half of the kill test below: replaces `MAAF_IO_TARGET` with version v2
    /// under the abort plan the parent set (a plain `cargo test` run does nothing).
    #[test]
    fn child_replaces_target() {
        if let Ok(target) = std::env::var("MAAF_IO_TARGET") {
            install(Path::new(&target), "v2").expect("replace");
        }
    }

    /// The process is killed at every write step of a folder replacement in turn; after
    /// each kill a reader finds one complete version (both files the same version).
    #[test]
    fn a_kill_at_any_step_of_replace_dir_leaves_a_complete_version() {
        let dir = scratch("kill");
        let exe = std::env::current_exe().expect("test binary");
        let mut aborted = 0;
        for (k, no_exchange) in (1..=12).flat_map(|k| [(k, "0"), (k, "1")]) {
            let target = dir.join(format!("model{k}_{no_exchange}"));
            install(&target, "v1").expect("v1");
            let status = Command::new(&exe)
                .args([
                    "--exact",
                    "dir::tests::child_replaces_target",
                    "--nocapture",
                ])
                .env("MAAF_IO_TARGET", &target)
                .env("MAAF_FAULT_ABORT_AT_WRITE", k.to_string())
                .env("MAAF_FAULT_NO_EXCHANGE", no_exchange)
                .output()
                .expect("child")
                .status;
            aborted += usize::from(!status.success());
            let read = readable_dir(&target).expect("a version is readable");
            let a = fs::read_to_string(read.join("a")).expect("a");
            let b = fs::read_to_string(read.join("b")).expect("b");
            assert_eq!(a, b, "step {k}: mixed versions");
            assert!(a == "v1" || a == "v2", "step {k}: {a}");
            if status.success() {
                assert_eq!(a, "v2", "step {k}: finished but old version");
            }
            // The next start restores a parked version and sweeps the rest.
            recover_dir(&target).expect("recover");
            crate::remove_stale_temps(&dir).expect("sweep");
            assert_eq!(fs::read_to_string(target.join("a")).expect("a"), a);
        }
        assert!(aborted >= 8, "only {aborted} kills landed inside the swap");
    }
}
