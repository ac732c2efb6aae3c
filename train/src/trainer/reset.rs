//! The periodic opacity reset and what it can leave behind: the per-Gaussian caps of
//! [`OpacityReset`], and [`Liveness`], which counts the Gaussians that have received
//! no gradient since the last reset (drawn too faint to matter, they are never pruned
//! or densified again).

use maaf_autodiff::{PerGaussian, Tensor};
use maaf_filter::FilterState;

use super::{OpacityReset, TrainState};

/// The cap on the base opacity `sigmoid(o)` of each Gaussian at a reset to `max`
/// (3DGS and Mip-Splatting use 0.01):
///
/// - `Raw`: `max` for every Gaussian.
/// - `Filtered`: `max / k_i` with the filter's compensation
///   `k_i = prod_a sqrt(s_ia^2 / (s_ia^2 + var_i))` on the canonical activated
///   scales `scales` \[N,3] and the widest variance the filter gives the Gaussian at
///   any time, `var_i = max_t var_i(t)` ([`FilterState::max_variance`]). Capping
///   `sigmoid(o)` at `max / k` caps the drawn opacity `sigmoid(o) k` at `max`, as
///   Mip-Splatting's `reset_opacity` does with `get_opacity_with_3D_filter`.
///
/// Why the widest variance for the motion filter, whose `nu(t)` changes with time:
/// it gives the smallest `k`, hence the largest cap, so the drawn opacity after a
/// reset is `max` at the Gaussian's least visible time and `max` or more at every
/// other time (`max k(t) / k_min >= max`). Any other choice would leave it below
/// `max` (possibly below 1/255, with no gradient) at some times. The deformation's
/// change of the scales and SaRO's temporal opacity factor are not included: like
/// 3DGS's reset, it acts on the canonical parameters.
///
/// A cap of 1 or more leaves the Gaussian unchanged.
pub fn opacity_caps(
    mode: OpacityReset,
    filter: &FilterState,
    scales: &Tensor<f32>,
    max: f64,
) -> Vec<f64> {
    match mode {
        OpacityReset::Raw => vec![max; scales.rows()],
        OpacityReset::Filtered => filter
            .max_variance()
            .iter()
            .zip(scales.data().chunks_exact(3))
            .map(|(&var, s)| {
                let var = f64::from(var);
                let k: f64 = s
                    .iter()
                    .map(|&s| {
                        let s2 = f64::from(s) * f64::from(s);
                        (s2 / (s2 + var)).sqrt()
                    })
                    .product();
                max / k
            })
            .collect(),
    }
}

/// Per Gaussian, the last iteration its opacity received a nonzero gradient, and
/// whether the last opacity reset lowered it. Rows travel with their Gaussian
/// through densification (a clone or split half inherits its parent's), and the
/// checkpoint carries both (as `liveness/last_grad`, u32, and `liveness/lowered`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Liveness {
    /// Iteration (1-based) of the last step whose opacity gradient was nonzero for
    /// the row; 0 = none yet.
    pub last_grad: Vec<u32>,
    /// Whether the last reset lowered the row's opacity.
    pub lowered: Vec<bool>,
}

impl Liveness {
    /// `n` Gaussians, none with a gradient yet, none lowered.
    pub fn new(n: usize) -> Self {
        Liveness {
            last_grad: vec![0; n],
            lowered: vec![false; n],
        }
    }

    /// `n` Gaussians counted as alive at `iteration` (what a checkpoint written
    /// before this record existed loads as: nothing is known, so nothing is dead).
    pub fn alive_at(n: usize, iteration: usize) -> Self {
        Liveness {
            last_grad: vec![iteration as u32; n],
            lowered: vec![false; n],
        }
    }

    /// Records the opacity gradient `grad` \[N] of `iteration`: rows with a nonzero
    /// entry get `last_grad = iteration`.
    pub fn record(&mut self, grad: &[f32], iteration: usize) {
        for (last, &g) in self.last_grad.iter_mut().zip(grad) {
            if g != 0.0 {
                *last = iteration as u32;
            }
        }
    }

    /// Records which rows a reset lowered (`lowered[i]`: the logit changed).
    pub fn reset(&mut self, lowered: Vec<bool>) {
        self.lowered = lowered;
    }

    /// Dead Gaussians: rows with no gradient after the reset at `last_reset`,
    /// `last_grad <= last_reset` (without a reset yet: rows never given one).
    pub fn dead(&self, last_reset: Option<usize>) -> usize {
        let since = last_reset.unwrap_or(0);
        self.last_grad
            .iter()
            .filter(|&&g| g as usize <= since)
            .count()
    }

    /// Dead Gaussians the last reset lowered: with no gradient since, Adam has not
    /// moved them, so their opacity is still the cap.
    pub fn at_cap(&self, last_reset: Option<usize>) -> usize {
        let since = last_reset.unwrap_or(0);
        self.last_grad
            .iter()
            .zip(&self.lowered)
            .filter(|&(&g, &low)| low && g as usize <= since)
            .count()
    }
}

impl PerGaussian for Liveness {
    fn rows(&self) -> usize {
        self.last_grad.len()
    }

    fn select_rows(&mut self, index: &[usize]) {
        self.last_grad.select_rows(index);
        self.lowered.select_rows(index);
    }
}

impl TrainState {
    /// The opacity reset of iteration `iteration` to 0.01 ([`opacity_caps`] of `mode`
    /// with the current filter and canonical scales); zeroes the Adam moments of the
    /// parameters it overwrote, records in [`TrainState::liveness`] which Gaussians
    /// it lowered and sets [`TrainState::last_reset`].
    pub fn reset_opacity(&mut self, mode: OpacityReset, iteration: usize) {
        let ids = self.model.canonical_ids();
        let opacity = ids.opacity_logits;
        let before = self.model.params().value(opacity).clone();
        let scales = self.model.params().value(ids.log_scales).map(f32::exp);
        let caps = opacity_caps(mode, &self.filter, &scales, 0.01);
        let store = self.model.params_mut();
        let reset = store.cap_opacity(ids, &caps);
        self.adam.zero_moments(&store.param(reset).name);
        let after = self.model.params().value(opacity);
        let lowered = before.data().iter().zip(after.data()).map(|(a, b)| a != b);
        self.liveness.reset(lowered.collect());
        self.last_reset = Some(iteration);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{DeformConfig, DeformModel, PointCloud, Representation};
    use maaf_autodiff::scalar::sigmoid;
    use maaf_filter::{FilterConfig, MotionCurves, ObservationTable};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    const N: usize = 200;

    /// A model of `N` Gaussians with log-uniform scales in \[1e-4, 0.1] per axis and
    /// opacities from 0.0025 to 0.98.
    fn model() -> DeformModel<f32> {
        let cloud = PointCloud::random_in_box(N, -1.0, 1.0, 5);
        let mut model = DeformModel::<f32>::from_point_cloud(&cloud, DeformConfig::default(), 5);
        let mut rng = Pcg64::seed_from_u64(11);
        let ids = model.canonical_ids();
        let log_scales = (0..3 * N)
            .map(|_| rng.random_range(1e-4f32.ln()..0.1f32.ln()))
            .collect();
        let logits = (0..N).map(|_| rng.random_range(-6.0f32..4.0)).collect();
        let p = model.params_mut();
        *p.value_mut(ids.log_scales) = Tensor::from_vec(log_scales, &[N, 3]);
        *p.value_mut(ids.opacity_logits) = Tensor::from_vec(logits, &[N]);
        model
    }

    /// The opacity each Gaussian of `model` is drawn with at each of `times` under
    /// `filter`: `sigmoid(o) * prod_a sqrt(s_a^2 / (s_a^2 + var(t)))`, in f64.
    fn drawn(model: &DeformModel<f32>, filter: &FilterState, times: &[f32]) -> Vec<Vec<f64>> {
        let c = model.params.canonical(model.canonical_ids());
        let var: Vec<Vec<f32>> = times.iter().map(|&t| filter.variance_at(t)).collect();
        (0..N)
            .map(|i| {
                let o = f64::from(c.opacity.data()[i]);
                var.iter()
                    .map(|v| {
                        let v = f64::from(v[i]);
                        (0..3).fold(o, |acc, a| {
                            let s = f64::from(c.scales.data()[3 * i + a]);
                            acc * (s * s / (s * s + v)).sqrt()
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// Resets a fresh [`model`] under `filter` in `mode`; returns the drawn opacities
    /// at `times` before and after.
    fn reset(
        filter: &FilterState,
        mode: OpacityReset,
        times: &[f32],
    ) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let mut m = model();
        let before = drawn(&m, filter, times);
        let ids = m.canonical_ids();
        let caps = opacity_caps(mode, filter, &m.params().canonical(ids).scales, 0.01);
        m.params_mut().cap_opacity(ids, &caps);
        (before, drawn(&m, filter, times))
    }

    /// After a filtered reset, each Gaussian's drawn opacity at its least visible
    /// time is `min(before, 0.01)` there, and at every time it is no more than before
    /// and at least `min(before, 0.01)`: visible at every time.
    fn assert_filtered_reset(filter: &FilterState, times: &[f32]) {
        let (before, after) = reset(filter, OpacityReset::Filtered, times);
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-5 * b.abs().max(1e-12);
        let mut lowered = 0;
        for (i, (b, a)) in before.iter().zip(&after).enumerate() {
            let want = min(b).min(0.01);
            assert!(close(min(a), want), "row {i}: {} vs {want}", min(a));
            lowered += usize::from(min(b) > 0.01);
            for (&bt, &at) in b.iter().zip(a) {
                assert!(at <= bt * (1.0 + 1e-5), "row {i}: {at} > {bt}");
                assert!(at >= bt.min(0.01) * (1.0 - 1e-5), "row {i}: {at} < {bt}");
            }
        }
        assert!(lowered > 10 && lowered < N - 10, "{lowered} lowered");
    }

    /// The static filter: its compensation does not depend on time.
    #[test]
    fn a_filtered_reset_caps_the_drawn_opacity_with_the_static_filter() {
        let mut rng = Pcg64::seed_from_u64(3);
        let nu = (0..N).map(|_| rng.random_range(20.0f32..400.0)).collect();
        assert_filtered_reset(&FilterState::Mip3d { s3d: 0.2, nu }, &[0.5]);
    }

    /// The motion filter: nu(t) changes with time; the cap holds at the Gaussian's
    /// least visible time of all the curve's bins.
    #[test]
    fn a_filtered_reset_caps_the_drawn_opacity_at_the_least_visible_time() {
        let cfg = FilterConfig::default();
        let times: Vec<f32> = (0..60).map(|f| f as f32 / 59.0).collect();
        let mut table = ObservationTable::new(times, N);
        let mut rng = Pcg64::seed_from_u64(4);
        for n in 0..N {
            let base = rng.random_range(20.0f32..400.0);
            let row = table.row_mut(n);
            for (f, x) in row.iter_mut().enumerate() {
                // f/d from base to 3 x base: the Gaussian approaches its camera.
                *x = base * (1.0 + 2.0 * f as f32 / 59.0) * rng.random_range(0.97f32..1.03);
            }
        }
        let curves = MotionCurves::refresh(&table, &cfg).expect("curves");
        let bins: Vec<f32> = (0..cfg.grid_t).map(|s| curves.bin_time(s)).collect();
        let filter = FilterState::Motion {
            s3d: cfg.s3d,
            curves,
        };
        let moving = (0..N)
            .filter(|&i| {
                let v: Vec<f32> = bins.iter().map(|&t| filter.variance_at(t)[i]).collect();
                v.iter().copied().fold(0.0, f32::max) > 2.0 * v.iter().copied().fold(1.0, f32::min)
            })
            .count();
        assert!(moving > N / 2, "only {moving} curves change over time");
        assert_filtered_reset(&filter, &bins);
    }

    /// The raw reset is 3DGS's: `o = min(o, logit(0.01))` on the stored logits, bit for
    /// bit, whatever the filter.
    #[test]
    fn a_raw_reset_caps_the_stored_opacity() {
        let nu = vec![50.0; N];
        let filter = FilterState::Mip3d { s3d: 0.2, nu };
        let mut m = model();
        let ids = m.canonical_ids();
        let before = m.params().value(ids.opacity_logits).clone();
        let caps = opacity_caps(
            OpacityReset::Raw,
            &filter,
            &m.params().canonical(ids).scales,
            0.01,
        );
        m.params_mut().cap_opacity(ids, &caps);
        // 3DGS `inverse_sigmoid(0.01)`.
        let p = 0.01f32;
        let cap = (p / (1.0 - p)).ln();
        for (&b, &a) in before
            .data()
            .iter()
            .zip(m.params().value(ids.opacity_logits).data())
        {
            assert_eq!(a.to_bits(), b.min(cap).to_bits(), "{b} -> {a}");
            let want = sigmoid(f64::from(b)).min(0.01);
            assert!((sigmoid(f64::from(a)) - want).abs() <= 1e-7, "{b} -> {a}");
        }
    }

    /// Dead and at-cap counts follow the last gradient and the last reset.
    #[test]
    fn dead_rows_are_those_without_a_gradient_since_the_reset() {
        let mut l = Liveness::new(4);
        assert_eq!(l.dead(None), 4);
        l.record(&[0.5, 0.0, -1.0, 0.0], 10);
        assert_eq!(l.dead(None), 2);
        l.reset(vec![true, true, false, false]);
        assert_eq!((l.dead(Some(10)), l.at_cap(Some(10))), (4, 2));
        l.record(&[0.0, 0.0, 2.0, 0.0], 11);
        assert_eq!((l.dead(Some(10)), l.at_cap(Some(10))), (3, 2));
        // Row 0 cloned, row 1 pruned: the copies carry their parent's record.
        l.select_rows(&[0, 2, 3, 0]);
        assert_eq!(l.last_grad, vec![10, 11, 0, 10]);
        assert_eq!(l.lowered, vec![true, false, false, true]);
        assert_eq!((l.dead(Some(10)), l.at_cap(Some(10))), (3, 2));
    }
}
