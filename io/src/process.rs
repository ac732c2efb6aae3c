//! Processes: whether the owner of a leftover temporary is still running, and child
//! processes that end with the process that started them.
//!
//! A parent that spawns long commands (`maaf bench-suite` spawning `maaf train` and
//! `maaf eval`) builds them with [`child_command`], which names the parent in
//! [`PARENT_ENV`]; the child calls [`end_with_parent`] first thing, which asks the
//! kernel (Linux `PR_SET_PDEATHSIG`) to send it `SIGTERM` when the parent ends, however
//! it ends (`kill -9` included), and ends at once when the parent has already gone.
//! The kernel sends the signal when the parent's *thread* that spawned the child
//! ends: the parent must spawn from a thread that lives as long as the child should.
//! Elsewhere than Linux the children are not tied to their parent.

use std::path::Path;
use std::process::Command;

/// The environment variable a parent sets to its process id to ask a child to end
/// with it ([`end_with_parent`]).
pub const PARENT_ENV: &str = "MAAF_END_WITH_PARENT";

/// Whether the process `pid` is running. On Linux a signal 0 is sent (refused for
/// permission still means running); elsewhere every process counts as running, so
/// nothing of another process is ever taken for a dead one's.
pub fn alive(pid: u32) -> bool {
    #[cfg(target_os = "linux")]
    {
        let Some(pid) = i32::try_from(pid)
            .ok()
            .and_then(rustix::process::Pid::from_raw)
        else {
            return false;
        };
        !matches!(
            rustix::process::test_kill_process(pid),
            Err(rustix::io::Errno::SRCH)
        )
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = pid;
        true
    }
}

/// `exe` as a command whose process ends with this one: [`PARENT_ENV`] holds this
/// process's id, which the child's [`end_with_parent`] reads.
pub fn child_command(exe: &Path) -> Command {
    let mut command = Command::new(exe);
    command.env(PARENT_ENV, std::process::id().to_string());
    command
}

/// When [`PARENT_ENV`] names a parent, ties this process to it: the kernel sends
/// `SIGTERM` when the parent ends (Linux), and an error is returned when the parent
/// has ended already (this process was re-parented before it could ask), so the
/// caller exits instead of running on alone. Without the variable, or elsewhere than
/// Linux, nothing happens.
pub fn end_with_parent() -> Result<(), String> {
    let Ok(value) = std::env::var(PARENT_ENV) else {
        return Ok(());
    };
    let Ok(parent) = value.parse::<u32>() else {
        return Err(format!(
            "{PARENT_ENV}={value}: not a process id (the variable is set by a parent maaf process)"
        ));
    };
    #[cfg(target_os = "linux")]
    {
        use rustix::process::{Signal, getppid, set_parent_process_death_signal};
        set_parent_process_death_signal(Some(Signal::TERM))
            .map_err(|e| format!("cannot ask to end with the parent process {parent}: {e}"))?;
        let now = getppid().map_or(0, |p| p.as_raw_nonzero().get().unsigned_abs());
        if now != parent {
            return Err(format!(
                "the parent process {parent} has ended; stopping with it"
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_is_alive_and_an_unused_id_is_not() {
        assert!(alive(std::process::id()));
        if cfg!(target_os = "linux") {
            // Above the kernel's largest process id (pid_max is at most 2^22).
            assert!(!alive(1 << 23));
        }
    }

    #[test]
    fn a_child_names_its_parent() {
        let c = child_command(Path::new("true"));
        let envs: Vec<_> = c.get_envs().collect();
        let own = std::process::id().to_string();
        assert!(
            envs.iter()
                .any(|(k, v)| *k == PARENT_ENV && v.is_some_and(|v| v == own.as_str())),
            "{envs:?}"
        );
    }
}
