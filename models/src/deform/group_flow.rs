//! GroupFlow (SpeeDe3DGS, Tu et al. 2025, Sec. 3.3; code tuallen/speede3dgs
//! `utils/rigid_utils.py`, its default `GroupFlowModel_v2`): after a warm-up with the
//! deformation MLP, the Gaussians are clustered into groups that move rigidly, and
//! each group gets one rotation and translation per time knot in place of the
//! per-Gaussian MLP query.
//!
//! Fitting, from the trajectories `p_i(t_k)` the MLP gives at K knot times:
//! - G nodes by farthest-point sampling of the knot-0 positions;
//! - each Gaussian joins the node whose trajectory is nearest in
//!   `0.5 std_k |p_i - p_n| + 0.5 mean_k |p_i - p_n|` over 8 knots spread over the
//!   sequence (rigidly co-moving points keep a constant distance: std 0);
//! - per group g and knot k, the centroid `c_gk` of its members, the translation
//!   `T_gk = c_gk - c_g0`, and the least-squares rotation `R_gk` from the members'
//!   knot-0 positions to their knot-k positions ([`super::rigid_fit`]);
//!   `R_g0 = I`, `T_g0 = 0`.
//!
//! Motion at time t between knots k and k+1 (ratio r): `R = slerp(R_gk, R_g(k+1), r)`
//! (the reference's `R_k exp(r log(R_k^T R_k+1))`), `T = lerp`; a point at `x_0`
//! (its knot-0 position) moves to `R (x_0 - n_g) + n_g + T` around the group's node
//! `n_g = c_g0`.
//!
//! maaf's, not the reference's: knots are uniform in t (`k / (K-1)`, K = the number of
//! training frames capped at `max_knots`) instead of the training frames' own time
//! stamps; every member enters the rotation fit (the reference samples 100);
//! farthest-point sampling starts at Gaussian 0 (the reference at a random one).

use glam::{DQuat, DVec3};
use rayon::prelude::*;

use super::rigid_fit::best_rotation;

/// Knots used to compare trajectories when assigning Gaussians to nodes (the
/// reference's `nframes=8`).
const ASSIGN_KNOTS: usize = 8;

/// Fitted groups: per-Gaussian labels and per-group motion at each knot.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupFlow {
    /// Group of each Gaussian \[N].
    pub labels: Vec<usize>,
    /// Each group's node `n_g` (its centroid at knot 0) \[G].
    pub nodes: Vec<DVec3>,
    /// Rotation of group g at knot k, at `g * knots + k` \[G * K].
    pub rotations: Vec<DQuat>,
    /// Translation of group g at knot k, at `g * knots + k` \[G * K].
    pub translations: Vec<DVec3>,
    /// Number of knots K (>= 2), at times `k / (K - 1)`.
    pub knots: usize,
}

impl GroupFlow {
    /// Fits `groups` groups to `trajectories[k][i]`, the position of Gaussian i at knot
    /// k (K >= 2 knots, N >= 1 Gaussians); fewer Gaussians than groups give one group
    /// per Gaussian.
    pub fn fit(trajectories: &[Vec<DVec3>], groups: usize) -> Self {
        let knots = trajectories.len();
        assert!(knots >= 2, "GroupFlow::fit: at least two knots");
        let n = trajectories[0].len();
        assert!(
            n >= 1 && groups >= 1,
            "GroupFlow::fit: no Gaussians or groups"
        );
        let seeds = farthest_points(&trajectories[0], groups.min(n));
        let assign: Vec<usize> = (0..ASSIGN_KNOTS.min(knots))
            .map(|j| j * (knots - 1) / (ASSIGN_KNOTS.min(knots) - 1))
            .collect();
        let labels: Vec<usize> = (0..n)
            .into_par_iter()
            .map(|i| {
                // One distance buffer per Gaussian, reused for every seed.
                let mut d = vec![0.0; assign.len()];
                let mut cost = |s: usize| {
                    for (dj, &k) in d.iter_mut().zip(&assign) {
                        *dj = trajectories[k][i].distance(trajectories[k][s]);
                    }
                    0.5 * std_unbiased(&d) + 0.5 * mean(&d)
                };
                let costs: Vec<f64> = seeds.iter().map(|&s| cost(s)).collect();
                (0..seeds.len())
                    .min_by(|&a, &b| costs[a].total_cmp(&costs[b]))
                    .unwrap_or(0)
            })
            .collect();
        let g_count = seeds.len();
        let mut members = vec![Vec::new(); g_count];
        for (i, &g) in labels.iter().enumerate() {
            members[g].push(i);
        }
        // A seed is its own nearest trajectory, so no group is empty; guard anyway
        // (coincident seeds tie).
        for (m, &seed) in members.iter_mut().zip(&seeds) {
            if m.is_empty() {
                m.push(seed);
            }
        }
        let per_group: Vec<(DVec3, Vec<DQuat>, Vec<DVec3>)> = members
            .par_iter()
            .map(|m| {
                let at =
                    |k: usize| -> Vec<DVec3> { m.iter().map(|&i| trajectories[k][i]).collect() };
                let centroid = |p: &[DVec3]| p.iter().copied().sum::<DVec3>() / p.len() as f64;
                let start = at(0);
                let c0 = centroid(&start);
                let mut rot = vec![DQuat::IDENTITY];
                let mut trans = vec![DVec3::ZERO];
                for k in 1..knots {
                    let now = at(k);
                    rot.push(best_rotation(&start, &now));
                    trans.push(centroid(&now) - c0);
                }
                (c0, rot, trans)
            })
            .collect();
        let mut flow = GroupFlow {
            labels,
            nodes: Vec::with_capacity(g_count),
            rotations: Vec::with_capacity(g_count * knots),
            translations: Vec::with_capacity(g_count * knots),
            knots,
        };
        for (c0, rot, trans) in per_group {
            flow.nodes.push(c0);
            flow.rotations.extend(rot);
            flow.translations.extend(trans);
        }
        flow
    }

    /// Number of groups G.
    pub fn groups(&self) -> usize {
        self.nodes.len()
    }

    /// Rotation and translation of group `g` at `time` (clamped to \[0, 1]):
    /// slerp and lerp between the two knots around it.
    pub fn motion(&self, g: usize, time: f64) -> (DQuat, DVec3) {
        let s = time.clamp(0.0, 1.0) * (self.knots - 1) as f64;
        let k = (s.floor() as usize).min(self.knots - 2);
        let r = s - k as f64;
        let at = g * self.knots + k;
        if r == 0.0 {
            // Exactly on a knot (slerp's endpoint is off by an ulp).
            return (self.rotations[at], self.translations[at]);
        }
        let q = self.rotations[at].slerp(self.rotations[at + 1], r);
        let t = self.translations[at].lerp(self.translations[at + 1], r);
        (q, t)
    }

    /// Keeps `labels[index[0]], labels[index[1]], ...` (densification and pruning
    /// move rows; a clone joins its parent's group).
    pub fn select_rows(&mut self, index: &[usize]) {
        self.labels = index.iter().map(|&i| self.labels[i]).collect();
    }
}

/// `count` indices of `points` by farthest-point sampling from index 0: each next
/// index is the point farthest from those already taken.
fn farthest_points(points: &[DVec3], count: usize) -> Vec<usize> {
    let mut taken = Vec::with_capacity(count);
    let mut dist = vec![f64::INFINITY; points.len()];
    let mut next = 0;
    for _ in 0..count {
        taken.push(next);
        let p = points[next];
        for (d, q) in dist.iter_mut().zip(points) {
            *d = d.min(p.distance_squared(*q));
        }
        next = (0..points.len())
            .max_by(|&a, &b| dist[a].total_cmp(&dist[b]))
            .unwrap_or(0);
    }
    taken
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Sample standard deviation (n - 1 denominator, as `torch.std`); 0 for one value.
fn std_unbiased(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let m = mean(v);
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two rigid bodies far apart, each spinning about its centroid at a constant rate
    /// about a fixed axis while the centroid moves on a straight line: the exact
    /// positions at any time, and at `knots` knots.
    struct Bodies {
        start: Vec<DVec3>,
        body: Vec<usize>,
    }

    impl Bodies {
        fn new() -> Self {
            let mut start = Vec::new();
            let mut body = Vec::new();
            for b in 0..2 {
                for i in 0..12 {
                    let f = i as f64;
                    let local = DVec3::new((f * 1.7).sin(), (f * 0.9).cos(), (f * 2.3).sin() * 0.5);
                    start.push(local + DVec3::new(10.0 * b as f64, 0.0, 0.0));
                    body.push(b);
                }
            }
            Bodies { start, body }
        }

        fn centroid0(&self, b: usize) -> DVec3 {
            let p: Vec<DVec3> = (0..self.start.len())
                .filter(|&i| self.body[i] == b)
                .map(|i| self.start[i])
                .collect();
            p.iter().copied().sum::<DVec3>() / p.len() as f64
        }

        fn at(&self, i: usize, t: f64) -> DVec3 {
            let b = self.body[i];
            let (axis, rate, velocity) = if b == 0 {
                (DVec3::new(0.0, 0.0, 1.0), 2.0, DVec3::new(0.0, 3.0, 0.0))
            } else {
                (
                    DVec3::new(1.0, 1.0, 0.0).normalize(),
                    -1.5,
                    DVec3::new(0.0, 0.0, -2.0),
                )
            };
            let c0 = self.centroid0(b);
            DQuat::from_axis_angle(axis, rate * t) * (self.start[i] - c0) + c0 + velocity * t
        }

        fn trajectories(&self, knots: usize) -> Vec<Vec<DVec3>> {
            (0..knots)
                .map(|k| {
                    let t = k as f64 / (knots - 1) as f64;
                    (0..self.start.len()).map(|i| self.at(i, t)).collect()
                })
                .collect()
        }
    }

    fn moved(flow: &GroupFlow, x0: DVec3, g: usize, t: f64) -> DVec3 {
        let (q, tr) = flow.motion(g, t);
        q * (x0 - flow.nodes[g]) + flow.nodes[g] + tr
    }

    #[test]
    fn rigid_bodies_fall_into_their_own_groups_and_move_exactly() {
        let bodies = Bodies::new();
        let flow = GroupFlow::fit(&bodies.trajectories(9), 2);
        assert_eq!(flow.groups(), 2);
        for i in 0..bodies.start.len() {
            let same_body: Vec<usize> = (0..bodies.start.len())
                .filter(|&j| bodies.body[j] == bodies.body[i])
                .collect();
            assert!(
                same_body.iter().all(|&j| flow.labels[j] == flow.labels[i]),
                "body {} split across groups",
                bodies.body[i]
            );
        }
        assert_ne!(flow.labels[0], flow.labels[bodies.start.len() - 1]);
        // Exact at the knots and, since rotation angle and centroid are linear in t,
        // between them too.
        for t in [0.0, 0.125, 0.3, 0.5, 0.61, 0.875, 1.0] {
            for i in 0..bodies.start.len() {
                let got = moved(&flow, bodies.start[i], flow.labels[i], t);
                let err = got.distance(bodies.at(i, t));
                assert!(err < 1e-9, "Gaussian {i} at t {t}: error {err}");
            }
        }
    }

    #[test]
    fn knot_zero_is_the_rest_pose_and_rows_follow_selection() {
        let bodies = Bodies::new();
        let mut flow = GroupFlow::fit(&bodies.trajectories(5), 3);
        for g in 0..flow.groups() {
            let (q, t) = flow.motion(g, 0.0);
            assert_eq!((q, t), (DQuat::IDENTITY, DVec3::ZERO));
        }
        let before = flow.labels.clone();
        flow.select_rows(&[3, 3, 20]);
        assert_eq!(flow.labels, vec![before[3], before[3], before[20]]);
    }

    #[test]
    fn farthest_point_sampling_spreads_out() {
        let pts: Vec<DVec3> = [0.0, 1.0, 2.0, 10.0, 10.5]
            .iter()
            .map(|&x| DVec3::new(x, 0.0, 0.0))
            .collect();
        assert_eq!(farthest_points(&pts, 3), vec![0, 4, 2]);
    }

    #[test]
    fn std_is_the_sample_deviation() {
        assert!((std_unbiased(&[1.0, 3.0]) - 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(std_unbiased(&[4.0]), 0.0);
    }
}
