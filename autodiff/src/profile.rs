//! Wall time per op name, recorded by a tape in profile mode ([`crate::Tape::set_profile`]).
//!
//! A profile answers "which ops does this step spend its time in" without an external
//! profiler: each op's forward (in [`crate::Tape::apply`]) and backward (in the reverse
//! sweep) is timed and summed under the op's [`crate::Op::name`].

use std::collections::BTreeMap;

/// Summed wall time of one op name.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OpTime {
    /// Forward calls recorded.
    pub calls: usize,
    /// Seconds in forward.
    pub forward: f64,
    /// Seconds in backward.
    pub backward: f64,
}

/// Wall time per op name (sorted by name).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OpProfile {
    /// Times by op name.
    pub ops: BTreeMap<String, OpTime>,
}

impl OpProfile {
    /// Adds one forward call of `name` taking `seconds`.
    pub fn add_forward(&mut self, name: String, seconds: f64) {
        let t = self.ops.entry(name).or_default();
        t.calls += 1;
        t.forward += seconds;
    }

    /// Adds one backward of `name` taking `seconds`.
    pub fn add_backward(&mut self, name: String, seconds: f64) {
        self.ops.entry(name).or_default().backward += seconds;
    }

    /// Adds every entry of `other` into this profile.
    pub fn merge(&mut self, other: &OpProfile) {
        for (name, t) in &other.ops {
            let e = self.ops.entry(name.clone()).or_default();
            e.calls += t.calls;
            e.forward += t.forward;
            e.backward += t.backward;
        }
    }

    /// Sum of forward and backward seconds over the ops whose name satisfies `pick`.
    pub fn seconds_where(&self, pick: impl Fn(&str) -> bool) -> (f64, f64) {
        self.ops
            .iter()
            .filter(|(name, _)| pick(name))
            .fold((0.0, 0.0), |(f, b), (_, t)| (f + t.forward, b + t.backward))
    }

    /// Op names ordered by total (forward + backward) seconds, largest first.
    pub fn by_total(&self) -> Vec<(&str, OpTime)> {
        let mut v: Vec<(&str, OpTime)> = self.ops.iter().map(|(n, t)| (n.as_str(), *t)).collect();
        v.sort_by(|a, b| (b.1.forward + b.1.backward).total_cmp(&(a.1.forward + a.1.backward)));
        v
    }
}
