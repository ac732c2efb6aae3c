//! One writer per run folder: an OS lock (`flock` on Unix) on `RUN/run.lock`, which
//! the kernel releases when the process ends however it ends (a `kill -9` leaves no
//! stale lock, unlike a PID file). A trainer or an evaluation holds it exclusively
//! for its whole command; readers that write nothing into the run (render, export)
//! hold it shared, so they never read a model a trainer is replacing.
//!
//! The lock is re-entrant within a process: the CLI takes it before it reads the run
//! and the library's run entry points take it again, which only counts up.
//! The holder of an exclusive lock writes what it is doing into the file, so a
//! refused process can say who holds it.
//!
//! A command refused after taking the lock leaves nothing: when the last guard
//! drops and the folder holds nothing but the lock file this process created, the
//! file goes, and the folder too when this process created it (a refused `maaf
//! train --out NEW`). A process that locked a lock file just removed that way (it
//! opened the file before the removal) sees that the file it holds is no longer the
//! one at the path and takes the lock again on the new one.

use std::collections::HashMap;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use crate::parent_of;

/// Name of the lock file inside a run folder.
pub const LOCK_FILE: &str = "run.lock";

/// A lock this process holds.
struct Entry {
    /// The open lock file.
    file: File,
    /// Held exclusively.
    exclusive: bool,
    /// Guards of this process holding it.
    holders: usize,
    /// This process created the lock file.
    created_file: bool,
    /// The run folder, when this process created it.
    created_dir: Option<PathBuf>,
}

/// The locks this process holds, by lock-file path.
type Held = HashMap<PathBuf, Entry>;

static HELD: Mutex<Option<Held>> = Mutex::new(None);

fn held() -> MutexGuard<'static, Option<Held>> {
    // A panic while holding the registry leaves it consistent (every change is one
    // insert or remove), so a poisoned lock is used as is.
    HELD.lock().unwrap_or_else(|p| p.into_inner())
}

/// Why a run lock was not taken.
#[derive(Debug)]
pub enum LockError {
    /// Another process holds the lock; `holder` is what it wrote into the lock file
    /// (e.g. `maaf train, pid 1234`), empty when it wrote nothing (a reader).
    Busy {
        /// The run folder.
        run: PathBuf,
        /// What the holder is doing, as it wrote it.
        holder: String,
    },
    /// The lock file could not be created or locked.
    Io {
        /// The lock file.
        path: PathBuf,
        /// The OS error.
        source: io::Error,
    },
}

impl std::fmt::Display for LockError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LockError::Busy { run, holder } if holder.is_empty() => write!(
                f,
                "{}: is in use by another process (being read); try again when it has finished",
                run.display()
            ),
            LockError::Busy { run, holder } => write!(
                f,
                "{}: is being {holder}; wait for it to finish (or use another folder)",
                run.display()
            ),
            LockError::Io { path, source } => {
                write!(f, "{}: cannot lock the run: {source}", path.display())
            }
        }
    }
}

impl std::error::Error for LockError {}

/// A held run lock; released when the last guard of this process for the run drops.
#[derive(Debug)]
pub struct RunLock {
    path: PathBuf,
}

impl RunLock {
    /// Takes the exclusive lock of the run folder `run` (created if needed) at once or
    /// fails with [`LockError::Busy`]. `doing` says what the holder does, as the past
    /// participle a refused process prints (`"trained (maaf train, pid 1234)"`).
    pub fn exclusive(run: &Path, doing: &str) -> Result<Self, LockError> {
        Self::take(run, true, doing)
    }

    /// Takes a shared lock of the run folder `run` at once, or fails with
    /// [`LockError::Busy`] while a process holds it exclusively. A run folder that
    /// cannot hold a lock file (read-only) is read without one: `Ok(None)`.
    pub fn shared(run: &Path) -> Result<Option<Self>, LockError> {
        match Self::take(run, false, "") {
            Ok(lock) => Ok(Some(lock)),
            Err(LockError::Io { source, .. })
                if matches!(
                    source.kind(),
                    io::ErrorKind::PermissionDenied
                        | io::ErrorKind::ReadOnlyFilesystem
                        | io::ErrorKind::NotFound
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    fn take(run: &Path, exclusive: bool, doing: &str) -> Result<Self, LockError> {
        let path = run.join(LOCK_FILE);
        let io_err = |source| LockError::Io {
            path: path.clone(),
            source,
        };
        let mut registry = held();
        let map = registry.get_or_insert_with(HashMap::new);
        // A lock file removed by a refused command between this process's open and
        // its lock is no longer the run's; take the lock again on the new one (a few
        // tries).
        for _ in 0..8 {
            let created_dir = exclusive && !run.exists();
            if exclusive {
                std::fs::create_dir_all(run).map_err(|source| LockError::Io {
                    path: run.to_path_buf(),
                    source,
                })?;
            }
            let key = std::fs::canonicalize(run)
                .map(|r| r.join(LOCK_FILE))
                .unwrap_or_else(|_| path.clone());
            if let Some(entry) = map.get_mut(&key) {
                // Already held by this process: an exclusive holder may read and
                // write; a shared holder cannot become the writer without letting go.
                if exclusive && !entry.exclusive {
                    return Err(LockError::Busy {
                        run: run.to_path_buf(),
                        holder: String::new(),
                    });
                }
                entry.holders += 1;
                return Ok(RunLock { path: key });
            }
            let (file, created_file) = open_lock_file(&path).map_err(io_err)?;
            let taken = if exclusive {
                file.try_lock()
            } else {
                file.try_lock_shared()
            };
            match taken {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let holder = std::fs::read_to_string(&path).unwrap_or_default();
                    return Err(LockError::Busy {
                        run: run.to_path_buf(),
                        holder: holder.trim().to_string(),
                    });
                }
                Err(TryLockError::Error(e)) => return Err(io_err(e)),
            }
            if !same_file(&file, &path) {
                continue;
            }
            if exclusive {
                // Not crash-critical (the lock is the kernel's, the text only a label),
                // so a plain rewrite in place rather than an atomic replace.
                let label = (|| {
                    file.set_len(0)?;
                    (&file).write_all(doing.as_bytes())?;
                    (&file).flush()
                })();
                label.map_err(io_err)?;
            }
            let entry = Entry {
                file,
                exclusive,
                holders: 1,
                created_file,
                created_dir: created_dir.then(|| run.to_path_buf()),
            };
            map.insert(key.clone(), entry);
            return Ok(RunLock { path: key });
        }
        Err(LockError::Busy {
            run: run.to_path_buf(),
            holder: String::new(),
        })
    }
}

/// Opens (creating it if needed) the lock file at `path`; says whether it created it.
fn open_lock_file(path: &Path) -> io::Result<(File, bool)> {
    let mut options = OpenOptions::new();
    options.read(true).write(true);
    match options.clone().create_new(true).open(path) {
        Ok(file) => Ok((file, true)),
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {
            options.open(path).map(|file| (file, false))
        }
        Err(e) => Err(e),
    }
}

/// Whether the open `file` is still the file at `path` (same device and inode).
fn same_file(file: &File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (file.metadata(), std::fs::metadata(path)) {
            (Ok(a), Ok(b)) => (a.dev(), a.ino()) == (b.dev(), b.ino()),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (file, path);
        true
    }
}

/// Whether `dir` holds nothing but its lock file.
fn holds_only_lock(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries
            .flatten()
            .all(|e| e.file_name() == std::ffi::OsStr::new(LOCK_FILE))
    })
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let mut registry = held();
        let Some(map) = registry.as_mut() else {
            return;
        };
        let last = match map.get_mut(&self.path) {
            Some(entry) => {
                entry.holders -= 1;
                entry.holders == 0
            }
            None => false,
        };
        if last && let Some(entry) = map.remove(&self.path) {
            if entry.exclusive {
                // The label goes with the lock; the file stays while the folder
                // holds anything else (another process may be opening it).
                let _ = entry.file.set_len(0);
            }
            // Removed while still locked: a process that opened it meanwhile sees
            // the removal after taking the lock (`same_file`) and starts over.
            let dir = parent_of(&self.path);
            if entry.created_file && holds_only_lock(dir) {
                let _ = std::fs::remove_file(&self.path);
                if let Some(created) = &entry.created_dir {
                    let _ = std::fs::remove_dir(created);
                }
            }
            let _ = entry.file.unlock();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::scratch;

    #[test]
    fn the_lock_is_reentrant_in_a_process_and_released_by_the_last_guard() {
        let run = scratch("lock");
        std::fs::write(run.join("config.json"), b"{}").expect("a run's file");
        let a = RunLock::exclusive(&run, "trained (test)").expect("first");
        let b = RunLock::exclusive(&run, "trained (test)").expect("re-entrant");
        let c = RunLock::shared(&run).expect("shared under exclusive");
        drop(a);
        drop(c);
        // Another open file description of the same file conflicts while `b` holds it.
        let other = File::open(run.join(LOCK_FILE)).expect("open");
        assert!(matches!(
            other.try_lock_shared(),
            Err(TryLockError::WouldBlock)
        ));
        assert_eq!(
            std::fs::read_to_string(run.join(LOCK_FILE)).expect("label"),
            "trained (test)"
        );
        drop(b);
        other.try_lock().expect("released by the last guard");
        let busy = RunLock::shared(&run).expect_err("held by `other`");
        assert!(busy.to_string().contains("is in use"), "{busy}");
        other.unlock().expect("unlock");
        let _ = std::fs::remove_dir_all(&run);
    }

    #[test]
    fn a_refused_command_leaves_no_lock_file_and_no_folder_it_created() {
        let root = scratch("lock_litter");
        let new = root.join("new_run");
        drop(RunLock::exclusive(&new, "trained (test)").expect("lock"));
        assert!(!new.exists(), "the folder it created goes with the lock");
        std::fs::create_dir_all(&new).expect("mkdir");
        drop(RunLock::exclusive(&new, "trained (test)").expect("lock"));
        assert!(new.is_dir(), "a folder it did not create stays");
        assert_eq!(std::fs::read_dir(&new).expect("ls").count(), 0);
        // A second process that opened the file before the first removed it takes
        // the lock on the new file instead of the removed one.
        let first = RunLock::exclusive(&new, "trained (test)").expect("lock");
        let stale = File::open(new.join(LOCK_FILE)).expect("open");
        drop(first);
        stale.try_lock().expect("the removed file is free");
        assert!(!same_file(&stale, &new.join(LOCK_FILE)));
        let _ = std::fs::remove_dir_all(&root);
    }
}
