//! The process's CPU clock: seconds of CPU all its threads have used.
//!
//! Wall time per phase moves with whatever else runs on the machine; CPU time barely
//! does, so a run's summary carries both (on an idle machine wall ≈ CPU / cores busy).

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
