//! Test-only fault injection for the crash-safety tests: every step of a write
//! ([`crate::write_atomic`], [`crate::replace_dir`]) passes through [`step`], which
//! does nothing unless one of two environment variables is set:
//!
//! - `MAAF_FAULT_ABORT_AT_WRITE=k`: the process aborts (like a `kill -9` or a power
//!   cut) at the k-th write step it performs (1-based, counted over the process);
//! - `MAAF_FAULT_ENOSPC_AT_WRITE=k`: the k-th data write (bytes into a file) writes
//!   half its bytes and then fails with "No space left on device";
//! - `MAAF_FAULT_NO_EXCHANGE=1`: [`crate::replace_dir`] uses its two-rename fallback
//!   instead of the atomic exchange, so tests cover both paths.

use std::io;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

/// What a write step does, for the counters of [`step`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Bytes into a file (counted by both variables).
    Data,
    /// Create, fsync, rename or remove (counted by the abort variable only).
    Meta,
}

struct Plan {
    abort_at: Option<usize>,
    enospc_at: Option<usize>,
    no_exchange: bool,
}

static PLAN: OnceLock<Plan> = OnceLock::new();
static STEPS: AtomicUsize = AtomicUsize::new(0);
static DATA_STEPS: AtomicUsize = AtomicUsize::new(0);

fn plan() -> &'static Plan {
    PLAN.get_or_init(|| {
        let read = |name: &str| std::env::var(name).ok().and_then(|v| v.parse().ok());
        Plan {
            abort_at: read("MAAF_FAULT_ABORT_AT_WRITE"),
            enospc_at: read("MAAF_FAULT_ENOSPC_AT_WRITE"),
            no_exchange: read("MAAF_FAULT_NO_EXCHANGE") == Some(1),
        }
    })
}

/// Counts one write step named `what` and applies the injected fault when due:
/// aborts the process, or returns a "no space left" error for a [`Step::Data`] step
/// (the caller then writes a partial file, as a full disk would, before failing).
pub fn step(kind: Step, what: &str) -> io::Result<()> {
    let plan = plan();
    if plan.abort_at.is_none() && plan.enospc_at.is_none() {
        return Ok(());
    }
    let n = STEPS.fetch_add(1, Ordering::SeqCst) + 1;
    if plan.abort_at == Some(n) {
        eprintln!("maaf: fault injection: abort at write step {n} ({what})");
        std::process::abort();
    }
    if kind == Step::Data {
        let d = DATA_STEPS.fetch_add(1, Ordering::SeqCst) + 1;
        if plan.enospc_at == Some(d) {
            return Err(io::Error::new(
                io::ErrorKind::StorageFull,
                "No space left on device (injected)",
            ));
        }
    }
    Ok(())
}

/// Whether `MAAF_FAULT_NO_EXCHANGE=1` asks for the two-rename fallback of folder swaps.
pub fn exchange_disabled() -> bool {
    plan().no_exchange
}
