//! The clock of a step's phases: wall seconds lap by lap, each charged to the phase
//! of [`Timings`] it belongs to, and the CPU both clocks used over the whole step
//! ([`CpuStamp`]).

use std::time::Instant;

use super::cpu_clock::CpuStamp;
use maaf_scene::Timings;

/// A running clock over one step's phases.
pub(super) struct PhaseClock {
    lap: Instant,
    cpu: CpuStamp,
}

impl PhaseClock {
    /// Starts both clocks now.
    pub(super) fn start() -> Self {
        PhaseClock {
            lap: Instant::now(),
            cpu: CpuStamp::now(),
        }
    }

    /// Wall seconds since the start or the last lap; starts the next lap.
    pub(super) fn lap(&mut self) -> f64 {
        let now = Instant::now();
        let seconds = (now - self.lap).as_secs_f64();
        self.lap = now;
        seconds
    }

    /// Charges the CPU the process and the machine used since the start to `timings`
    /// ([`CpuStamp::charge`]).
    pub(super) fn finish(self, timings: &mut Timings) {
        self.cpu.charge(timings);
    }
}
