//! Adaptive density control (3DGS `densify_and_prune`, as configured by SaRO-GS):
//! statistics of the screen-space positional gradient, clone / split / prune as one
//! row-index list applied to every per-Gaussian container.

use maaf_autodiff::{PerGaussian, Tensor};
use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::DensifyConfig;
use crate::models::Representation;

/// One view's part of [`DensifyStats::record_views`]: the cotangent of its screen
/// means (None when nothing reached them), its radii and its image size.
pub struct ViewGrad<'a> {
    /// `dL/d means2d` `[N, 2]` in pixels.
    pub grad: Option<&'a Tensor<f32>>,
    /// The sums of absolute per-pixel gradients `[N, 2]` (AbsGS), present when the
    /// run densifies on them (`densify.gradient` `abs`); the statistics then use them
    /// in place of `grad`.
    pub abs_grad: Option<&'a Tensor<f32>>,
    /// Screen radii (0 = not drawn).
    pub radii: &'a [u32],
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// Per-Gaussian statistics between densifications: accumulated screen-space gradient
/// norm, number of views in which the Gaussian was visible, and its largest radius.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DensifyStats {
    /// Sum over iterations of `|dL/d mean2d|` in NDC units (averaged over the views of
    /// an iteration that drew the Gaussian).
    pub grad_accum: Vec<f32>,
    /// Iterations in which the Gaussian was drawn by at least one view.
    pub denom: Vec<f32>,
    /// Largest screen radius seen (pixels).
    pub max_radii: Vec<f32>,
}

impl DensifyStats {
    /// Zeroed statistics for `n` Gaussians.
    pub fn new(n: usize) -> Self {
        DensifyStats {
            grad_accum: vec![0.0; n],
            denom: vec![0.0; n],
            max_radii: vec![0.0; n],
        }
    }

    /// Adds one iteration's views. Per view, `grad` is `dL/d means2d` `[N,2]` in
    /// pixels of the iteration's objective (or `abs_grad` when present), which
    /// `loss_scale` turns into that view's own objective; 3DGS thresholds the
    /// gradient with respect to NDC coordinates,
    /// `d/d ndc_x = (W/2) d/d px`, so the norm is taken of `(gx W/2, gy H/2)`. A
    /// Gaussian's entry is the mean of its norms over the views where its radius is
    /// positive, and counts once (SaRO-GS `train.py` with `batch`: the summed norms
    /// divided by the visibility count, then `add_densification_stats_grad`); with one
    /// view this is 3DGS's `add_densification_stats`.
    pub fn record_views(&mut self, views: &[ViewGrad<'_>], loss_scale: f32) {
        let n = self.denom.len();
        let mut sum = vec![0.0f32; n];
        let mut seen = vec![0u32; n];
        for v in views {
            let (hw, hh) = (v.width as f32 * 0.5, v.height as f32 * 0.5);
            for (i, &r) in v.radii.iter().enumerate() {
                if r == 0 {
                    continue;
                }
                if let Some(g) = v.abs_grad.or(v.grad) {
                    let (gx, gy) = (g.data()[2 * i] * hw, g.data()[2 * i + 1] * hh);
                    sum[i] += (gx * gx + gy * gy).sqrt() * loss_scale;
                }
                seen[i] += 1;
                self.max_radii[i] = self.max_radii[i].max(r as f32);
            }
        }
        for i in 0..n {
            if seen[i] > 0 {
                self.grad_accum[i] += sum[i] / seen[i] as f32;
                self.denom[i] += 1.0;
            }
        }
    }

    /// Mean gradient norm per Gaussian (0 where never visible).
    pub fn mean_grad(&self) -> Vec<f32> {
        self.grad_accum
            .iter()
            .zip(&self.denom)
            .map(|(&g, &d)| if d > 0.0 { g / d } else { 0.0 })
            .collect()
    }
}

impl PerGaussian for DensifyStats {
    fn rows(&self) -> usize {
        self.denom.len()
    }
    fn select_rows(&mut self, index: &[usize]) {
        self.grad_accum.select_rows(index);
        self.denom.select_rows(index);
        self.max_radii.select_rows(index);
    }
}

/// One densification as a row-index list over the old Gaussians plus the new
/// centres and scales of the rows that clones and splits created.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DensifyPlan {
    /// New rows as old row indices (survivors, then clones, then split halves).
    pub index: Vec<usize>,
    /// Rows (in the new numbering) whose centre and scale must be overwritten.
    pub new_rows: Vec<usize>,
    /// Centres of `new_rows`, flat `[len, 3]`.
    pub new_means: Vec<f32>,
    /// Activated scales of `new_rows`, flat `[len, 3]`.
    pub new_scales: Vec<f32>,
    /// Gaussians cloned.
    pub cloned: usize,
    /// Gaussians split (each into two).
    pub split: usize,
    /// Gaussians pruned.
    pub pruned: usize,
}

/// Plans clone / split / prune (3DGS Sec. 5):
/// - candidates have mean NDC gradient `>= grad_threshold`; those whose largest
///   scale is `<= percent_dense * extent` are cloned (a copy at the same place),
///   the others split into two Gaussians sampled from the original
///   (`mu + R (s * n)`, `n ~ N(0, I)`) with scale `s / 1.6`;
/// - pruned: base opacity `< min_opacity`; when `big_screen` is set (after the first
///   opacity reset) largest scale `> max_world_size * extent` and, if enabled, screen
///   radius above `max_screen_size`; and whatever the representation reports as
///   short-lived; a pruned Gaussian is neither cloned nor split;
/// - growth stops at `max_gaussians`, taking the largest gradients first;
/// - the mean gradient is first multiplied by the representation's
///   [`TrainingHooks::densify_grad_scale`](crate::models::TrainingHooks::densify_grad_scale) (SaRO: the adaptive-optimisation scale).
pub fn plan(
    model: &dyn Representation<f32>,
    stats: &DensifyStats,
    cfg: &DensifyConfig,
    extent: f64,
    big_screen: bool,
    seed: u64,
) -> DensifyPlan {
    let canon = model.params().canonical(model.canonical_ids());
    let n = model.rows();
    let hooks = model.hooks();
    let mut grad = stats.mean_grad();
    if let Some(scale) = hooks.and_then(|h| h.densify_grad_scale()) {
        for (g, s) in grad.iter_mut().zip(scale.iter()) {
            *g *= s;
        }
    }
    let mut prune = vec![false; n];
    for i in hooks.map_or_else(Vec::new, |h| h.short_lived()) {
        prune[i] = true;
    }
    let max_scale = |i: usize| {
        canon.scales.data()[3 * i..3 * i + 3]
            .iter()
            .fold(0.0f32, |a, &b| a.max(b)) as f64
    };
    let too_big = |i: usize| {
        let world = cfg.max_world_size > 0.0 && max_scale(i) > cfg.max_world_size * extent;
        let screen = cfg.max_screen_size > 0.0 && stats.max_radii[i] as f64 > cfg.max_screen_size;
        big_screen && (world || screen)
    };
    for (i, p) in prune.iter_mut().enumerate() {
        if (canon.opacity.data()[i] as f64) < cfg.min_opacity || too_big(i) {
            *p = true;
        }
    }
    let mut candidates: Vec<usize> = (0..n)
        .filter(|&i| !prune[i] && grad[i] as f64 >= cfg.grad_threshold)
        .collect();
    candidates.sort_by(|&a, &b| grad[b].total_cmp(&grad[a]).then(a.cmp(&b)));
    let survivors = prune.iter().filter(|&&p| !p).count();
    let mut budget = cfg.max_gaussians.saturating_sub(survivors);
    let (mut clone, mut split) = (Vec::new(), Vec::new());
    for &i in &candidates {
        let is_small = max_scale(i) <= cfg.percent_dense * extent;
        // A clone adds one row; a split replaces one row by two.
        if budget == 0 {
            break;
        }
        budget -= 1;
        if is_small {
            clone.push(i)
        } else {
            split.push(i)
        }
    }
    clone.sort_unstable();
    split.sort_unstable();
    let mut is_split = vec![false; n];
    for &i in &split {
        is_split[i] = true;
    }
    let mut out = DensifyPlan {
        pruned: prune.iter().filter(|&&p| p).count(),
        ..Default::default()
    };
    out.index = (0..n).filter(|&i| !prune[i] && !is_split[i]).collect();
    out.index.extend(&clone);
    out.cloned = clone.len();
    out.split = split.len();
    let mut rng = Pcg64::seed_from_u64(seed);
    for &i in &split {
        let s: [f32; 3] = std::array::from_fn(|a| canon.scales.data()[3 * i + a]);
        let q: [f32; 4] = std::array::from_fn(|a| canon.quats.data()[4 * i + a]);
        let mu: [f32; 3] = std::array::from_fn(|a| canon.means.data()[3 * i + a]);
        for _ in 0..2 {
            let local: [f32; 3] = std::array::from_fn(|a| s[a] * standard_normal(&mut rng));
            let off = rotate(q, local);
            out.new_rows.push(out.index.len());
            out.index.push(i);
            out.new_means.extend((0..3).map(|a| mu[a] + off[a]));
            out.new_scales.extend(s.iter().map(|v| v / 1.6));
        }
    }
    out
}

/// A standard normal sample (Box-Muller).
fn standard_normal(rng: &mut Pcg64) -> f32 {
    use rand::RngExt;
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}

/// Rotates `v` by the (normalised) quaternion `q = (w, x, y, z)`.
fn rotate(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    let norm = (q.iter().map(|a| a * a).sum::<f32>()).sqrt().max(1e-12);
    let (w, x, y, z) = (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm);
    let r = [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ];
    std::array::from_fn(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_by_a_quarter_turn_about_z() {
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let v = rotate([h, 0.0, 0.0, h], [1.0, 0.0, 0.0]);
        assert!((v[0]).abs() < 1e-6 && (v[1] - 1.0).abs() < 1e-6 && v[2].abs() < 1e-6);
    }

    #[test]
    fn stats_use_ndc_units_and_skip_culled() {
        let mut s = DensifyStats::new(2);
        let g = Tensor::from_vec(vec![1.0, 0.0, 5.0, 5.0], &[2, 2]);
        let view = ViewGrad {
            grad: Some(&g),
            abs_grad: None,
            radii: &[3, 0],
            width: 10,
            height: 20,
        };
        s.record_views(&[view], 1.0);
        assert_eq!(s.grad_accum, vec![5.0, 0.0]);
        assert_eq!(s.denom, vec![1.0, 0.0]);
        assert_eq!(s.max_radii, vec![3.0, 0.0]);
        assert_eq!(s.mean_grad(), vec![5.0, 0.0]);
    }

    /// A batch: each Gaussian gets the mean over the views that drew it of its own
    /// objective's gradient norm (the mean objective's times the batch size), counted
    /// once per iteration; the largest radius over the views.
    #[test]
    fn batch_stats_average_over_the_views_that_drew_each_gaussian() {
        let mut s = DensifyStats::new(3);
        // NDC norms: view a (10 x 20): row 0 |(0.2*5, 0)| = 1, row 1 |(0, 0.1*10)| = 1;
        // view b (10 x 20): row 0 |(0.6*5, 0.4*10)| = 5, row 1 not drawn.
        let ga = Tensor::from_vec(vec![0.2, 0.0, 0.0, 0.1, 9.0, 9.0], &[3, 2]);
        let gb = Tensor::from_vec(vec![0.6, 0.4, 7.0, 7.0, 9.0, 9.0], &[3, 2]);
        let views = [
            ViewGrad {
                grad: Some(&ga),
                abs_grad: None,
                radii: &[2, 4, 0],
                width: 10,
                height: 20,
            },
            ViewGrad {
                grad: Some(&gb),
                abs_grad: None,
                radii: &[6, 0, 0],
                width: 10,
                height: 20,
            },
        ];
        s.record_views(&views, 2.0);
        // Row 0: 2 * (1 + 5) / 2 = 6; row 1: 2 * 1 / 1 = 2; row 2 never drawn.
        assert_eq!(s.grad_accum, vec![6.0, 2.0, 0.0]);
        assert_eq!(s.denom, vec![1.0, 1.0, 0.0]);
        assert_eq!(s.max_radii, vec![6.0, 4.0, 0.0]);
    }
    /// After the first reset, a Gaussian larger than 0.1 x the extent in the world is
    /// pruned (3DGS `big_points_ws`) and one large on screen only when the screen
    /// test is switched on; before it, neither.
    #[test]
    fn big_gaussians_are_pruned_by_world_size_and_screen_size_only_on_request() {
        use crate::models::{DeformConfig, DeformModel, PointCloud};
        let cloud = PointCloud::random_in_box(3, -1.0, 1.0, 4);
        let mut model = DeformModel::<f32>::from_point_cloud(&cloud, DeformConfig::default(), 4);
        let ids = model.canonical_ids();
        // Row 0: 0.5 wide (extent 4: 0.125 x extent); rows 1-2: 0.05 wide.
        let scales = [0.5f32, 0.05, 0.05]
            .iter()
            .flat_map(|&s| [s.ln(); 3])
            .collect();
        *model.params_mut().value_mut(ids.log_scales) = Tensor::from_vec(scales, &[3, 3]);
        *model.params_mut().value_mut(ids.opacity_logits) = Tensor::from_vec(vec![2.0; 3], &[3]);
        let mut stats = DensifyStats::new(3);
        stats.max_radii = vec![1.0, 30.0, 1.0];
        let cfg = DensifyConfig::default();
        let pruned = |cfg: &DensifyConfig, after_reset| {
            let p = plan(&model, &stats, cfg, 4.0, after_reset, 0);
            (0..3).filter(|i| !p.index.contains(i)).collect::<Vec<_>>()
        };
        assert_eq!(pruned(&cfg, false), Vec::<usize>::new());
        assert_eq!(pruned(&cfg, true), vec![0]);
        let screen = DensifyConfig {
            max_screen_size: 20.0,
            ..cfg.clone()
        };
        assert_eq!(pruned(&screen, true), vec![0, 1]);
        let neither = DensifyConfig {
            max_world_size: 0.0,
            ..cfg
        };
        assert_eq!(pruned(&neither, true), Vec::<usize>::new());
    }
}
