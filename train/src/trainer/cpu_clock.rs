//! The process's CPU clock (seconds of CPU all its threads have used) and the
//! machine's (seconds of CPU all processes have used).
//!
//! Wall time per phase moves with whatever else runs on the machine; CPU time barely
//! does, so a run's summary carries both (on an idle machine wall ≈ CPU / cores busy),
//! and the machine's clock says how much else ran beside it.

use maaf_scene::Timings;

/// CPU seconds used so far by every thread of this process
/// (`clock_gettime(CLOCK_PROCESS_CPUTIME_ID)`); 0 where the clock is unavailable.
#[cfg(unix)]
#[allow(unsafe_code)]
pub fn process_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec for the call's duration.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if rc == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        0.0
    }
}

/// CPU seconds used so far by this process: unavailable off Unix, always 0.
#[cfg(not(unix))]
pub fn process_cpu_seconds() -> f64 {
    0.0
}

/// Both CPU clocks read at one moment; [`Self::charge`] adds what each advanced since
/// to a run's [`Timings`] (`cpu`, `machine_cpu`), over the same phases as its wall
/// time.
#[derive(Clone, Copy, Debug)]
pub struct CpuStamp {
    process: f64,
    machine: f64,
}

impl CpuStamp {
    /// Reads [`process_cpu_seconds`] and [`machine_cpu_seconds`].
    pub fn now() -> Self {
        CpuStamp {
            process: process_cpu_seconds(),
            machine: machine_cpu_seconds(),
        }
    }

    /// Adds the CPU seconds of this process and of the machine since the stamp.
    pub fn charge(self, timings: &mut Timings) {
        let now = CpuStamp::now();
        timings.cpu += now.process - self.process;
        timings.machine_cpu += now.machine - self.machine;
    }
}

/// CPU seconds the whole machine has used since boot, every process and the kernel
/// (Linux: the first line of `/proc/stat`, user + nice + system + irq + softirq +
/// steal ticks over `sysconf(_SC_CLK_TCK)`; steal is the time a virtual machine's
/// host ran something else, a load on the training too); 0 where that file is
/// unavailable.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn machine_cpu_seconds() -> f64 {
    // SAFETY: sysconf only reads a configuration value.
    let ticks_per_second = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    match std::fs::read_to_string("/proc/stat") {
        Ok(stat) if ticks_per_second > 0 => {
            busy_ticks(&stat).map_or(0.0, |t| t as f64 / ticks_per_second as f64)
        }
        _ => 0.0,
    }
}

/// CPU seconds the whole machine has used: unavailable off Linux, always 0.
#[cfg(not(target_os = "linux"))]
pub fn machine_cpu_seconds() -> f64 {
    0.0
}

/// The busy ticks of all CPUs from `/proc/stat`'s first line, `cpu  user nice system
/// idle iowait irq softirq steal ...`: every column but idle and iowait (guest time is
/// already inside user and nice). `None` when the line is not there.
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
fn busy_ticks(stat: &str) -> Option<u64> {
    let line = stat.lines().next()?;
    let mut fields = line.split_whitespace();
    (fields.next()? == "cpu").then_some(())?;
    let ticks: Vec<u64> = fields
        .take(8)
        .map(|f| f.parse().ok())
        .collect::<Option<_>>()?;
    (ticks.len() == 8).then(|| ticks[0] + ticks[1] + ticks[2] + ticks[5] + ticks[6] + ticks[7])
}

#[cfg(test)]
mod parse_tests {
    use super::busy_ticks;

    #[test]
    fn busy_ticks_sum_every_column_but_idle_and_iowait() {
        let stat = "cpu  100 20 30 5000 40 6 7 8 9 10\ncpu0 50 10 15 2500 20 3 3 4 4 5\n";
        assert_eq!(busy_ticks(stat), Some(100 + 20 + 30 + 6 + 7 + 8));
        assert_eq!(busy_ticks("cpu0 1 2 3 4 5 6 7 8\n"), None);
        assert_eq!(busy_ticks("cpu  1 2 3 4\n"), None);
        assert_eq!(busy_ticks("cpu  1 2 x 4 5 6 7 8\n"), None);
        assert_eq!(busy_ticks(""), None);
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::process_cpu_seconds;

    #[test]
    fn the_clock_advances_with_work_and_not_with_sleep() {
        let t0 = process_cpu_seconds();
        assert!(t0 > 0.0, "a running process has used some CPU: {t0}");
        let mut x = 0u64;
        for i in 0..50_000_000u64 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(i));
        }
        std::hint::black_box(x);
        let t1 = process_cpu_seconds();
        assert!(t1 > t0 + 1e-3, "busy work shows on the clock: {t0} -> {t1}");
        // The clock is the whole process's, and the other tests of this binary run on
        // other threads meanwhile: a sleep must cost (almost) no CPU at least once in
        // five tries (a clock that counted wall time would show 0.3 s every time).
        let costs: Vec<f64> = (0..5)
            .map(|_| {
                let before = process_cpu_seconds();
                std::thread::sleep(std::time::Duration::from_millis(300));
                process_cpu_seconds() - before
            })
            .collect();
        assert!(
            costs.iter().any(|&c| c < 0.15),
            "sleeping 0.3 s costs (almost) no CPU: {costs:?} s"
        );
    }
}

#[cfg(all(test, target_os = "linux"))]
mod machine_tests {
    use super::{machine_cpu_seconds, process_cpu_seconds};

    #[test]
    fn the_machine_clock_counts_this_process_work() {
        let (m0, p0) = (machine_cpu_seconds(), process_cpu_seconds());
        assert!(m0 > 0.0, "the machine has used some CPU since boot: {m0}");
        let mut x = 0u64;
        for i in 0..200_000_000u64 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(i));
        }
        std::hint::black_box(x);
        let (m1, p1) = (machine_cpu_seconds(), process_cpu_seconds());
        // The machine's clock includes this process's time, give or take one 10 ms
        // tick per CPU; a clock that missed it (or read the idle column) would not.
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        assert!(
            m1 - m0 >= (p1 - p0) - 0.02 * cpus - 0.02,
            "machine {m0} -> {m1} s, this process {p0} -> {p1} s"
        );
    }
}
