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

use std::collections::HashMap;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// Name of the lock file inside a run folder.
pub const LOCK_FILE: &str = "run.lock";

/// The locks this process holds: lock-file path -> (open file, exclusive, holders).
type Held = HashMap<PathBuf, (File, bool, usize)>;

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
                "{}: is being {holder}; wait for it to finish (or use another run folder)",
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
        std::fs::create_dir_all(run).map_err(|source| LockError::Io {
            path: run.to_path_buf(),
            source,
        })?;
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
        let key = std::fs::canonicalize(run)
            .map(|r| r.join(LOCK_FILE))
            .unwrap_or_else(|_| path.clone());
        let mut registry = held();
        let map = registry.get_or_insert_with(HashMap::new);
        if let Some((_, is_exclusive, count)) = map.get_mut(&key) {
            // Already held by this process: an exclusive holder may read and write;
            // a shared holder cannot become the writer without letting go first.
            if exclusive && !*is_exclusive {
                return Err(LockError::Busy {
                    run: run.to_path_buf(),
                    holder: String::new(),
                });
            }
            *count += 1;
            return Ok(RunLock { path: key });
        }
        let io_err = |source| LockError::Io {
            path: path.clone(),
            source,
        };
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io_err)?;
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
        map.insert(key.clone(), (file, exclusive, 1));
        Ok(RunLock { path: key })
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let mut registry = held();
        let Some(map) = registry.as_mut() else {
            return;
        };
        let last = match map.get_mut(&self.path) {
            Some((_, _, count)) => {
                *count -= 1;
                *count == 0
            }
            None => false,
        };
        if last && let Some((file, exclusive, _)) = map.remove(&self.path) {
            if exclusive {
                // The label goes with the lock; the file stays (removing it would
                // let a waiting process lock a file nobody else can see).
                let _ = file.set_len(0);
            }
            let _ = file.unlock();
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
}
