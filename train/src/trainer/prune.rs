//! Sensitivity pruning: Speedy-Splat's pruning score (Hanson et al. 2025, Sec. 4.2),
//! computed as SpeeDe3DGS does for dynamic scenes (Tu et al. 2025, "temporal
//! sensitivity pruning"): every training view is rendered at its own time, so a
//! Gaussian that matters only while it moves keeps its score; the Gaussians with
//! the lowest scores are removed.

use maaf_autodiff::{Tape, Tensor};
use maaf_filter::FilterState;
use maaf_splat::{Camera, GaussianVars, RenderSettings, SplatFloat};

use super::{DensifyPlan, RefineStep, TrainState};
use maaf_scene::forward::{deformed_at, fold_filter};

/// How much the total intensity of one render depends on each Gaussian: with
/// `S = sum over pixels and channels of the image` and `o_i` the opacity of Gaussian
/// `i` at this time, the entry is `o_i dS/do_i`, the derivative of `S` with respect
/// to a factor `e_i` that scales the Gaussian's alpha (`alpha_i = e_i o_i G_i`) at
/// `e_i = 1`: the first-order change of the image when the Gaussian fades out, signed.
///
/// `deformed` is `[means, scales, quats, opacity, sh]` before the 3D filter (moved onto
/// the tape, not copied); `filter` is folded in at `time` as in training (its opacity compensation is a factor, so
/// the derivative is the same before and after it).
pub fn removal_sensitivity<T: SplatFloat>(
    deformed: [Tensor<T>; 5],
    filter: &FilterState,
    time: f64,
    camera: &Camera,
    settings: &RenderSettings,
) -> Result<Vec<f64>, String> {
    let tape = Tape::new();
    let [means, scales, quats, opacity, sh] = deformed;
    let [means, scales, quats, sh] = [means, scales, quats, sh].map(|t| tape.constant(t));
    let opacity = tape.var(opacity);
    let g = GaussianVars {
        means,
        scales,
        quats,
        opacity,
        sh,
    };
    let filtered = fold_filter(g, filter, time);
    let render = maaf_splat::render(&tape, &filtered, camera, settings);
    let ones = Tensor::full(&render.image.shape(), T::of(1.0));
    let grads = tape
        .backward_from(&[(render.image, ones)])
        .map_err(|e| e.to_string())?;
    let o = opacity.value();
    let o = o.data();
    Ok(match grads.wrt(opacity) {
        Some(d) => o
            .iter()
            .zip(d.data())
            .map(|(&o, &d)| o.to_f64() * d.to_f64())
            .collect(),
        None => vec![0.0; o.len()],
    })
}

/// The rows that stay when the fraction `ratio` of them with the lowest `scores` is
/// removed: `floor(ratio n)` rows go, ties broken towards the lower row index; the
/// survivors are returned in their original order.
pub fn keep_highest(scores: &[f64], ratio: f64) -> Vec<usize> {
    let n = scores.len();
    let remove = ((ratio * n as f64).floor() as usize).min(n);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]).then(a.cmp(&b)));
    let mut keep = order.split_off(remove);
    keep.sort_unstable();
    keep
}

/// The pruning score of every Gaussian of `state` (Speedy-Splat Eq. 10 with the
/// image sum as the objective): the sum over all training views `v` of `step`, each
/// rendered at its own time with the step's settings, of the squared
/// [`removal_sensitivity`]. Squaring per view means a Gaussian that brightens one
/// frame and darkens another does not cancel out.
pub fn sensitivity_scores(state: &TrainState, step: &RefineStep<'_>) -> Result<Vec<f64>, String> {
    let mut scores = vec![0.0; state.rows()];
    for (&time, camera) in step.times.iter().zip(step.cameras) {
        let deformed = deformed_at(state.model.as_ref(), time);
        let s = removal_sensitivity(deformed, &state.filter, time, camera, step.settings)?;
        for (acc, v) in scores.iter_mut().zip(s) {
            *acc += v * v;
        }
    }
    Ok(scores)
}

/// Sensitivity pruning when `config.prune` schedules it at `step.iteration`: the soft
/// ratio before `densify.until`, the hard one from then on. Returns whether
/// Gaussians were removed. The densification statistics of the survivors are kept
/// (3DGS `prune_points`): [`TrainState::apply_plan`] carries them with their rows.
pub(super) fn maybe_prune(state: &mut TrainState, step: &RefineStep<'_>) -> bool {
    let (p, it) = (&step.config.prune, step.iteration);
    if p.every == 0 || it < p.from || it > p.until || !it.is_multiple_of(p.every) {
        return false;
    }
    let ratio = if it < step.config.densify.until {
        p.ratio_densifying
    } else {
        p.ratio_after
    };
    let scores = match sensitivity_scores(state, step) {
        Ok(s) => s,
        Err(e) => {
            log::warn!("iteration {it}: sensitivity pruning skipped: {e}");
            return false;
        }
    };
    let n = scores.len();
    let index = keep_highest(&scores, ratio);
    let pruned = n - index.len();
    if pruned == 0 {
        return false;
    }
    state.apply_plan(&DensifyPlan {
        index,
        pruned,
        ..Default::default()
    });
    log::info!("iteration {it}: sensitivity pruning removed {pruned} of {n} Gaussians");
    true
}

#[cfg(test)]
mod tests {
    use maaf_splat::AlphaCutoff;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    /// 40 Gaussians in front of a 48x40 camera at the origin looking down +z: sizes
    /// from sub-pixel to a quarter of the image, opacities 0.05-0.95, SH degree 1.
    fn scene() -> ([Tensor<f64>; 5], Camera) {
        let n = 40;
        let mut rng = Pcg64::seed_from_u64(7);
        let mut u = |lo: f64, hi: f64| rng.random_range(lo..hi);
        let mut means = Vec::new();
        for _ in 0..n {
            let z = u(2.0, 6.0);
            means.extend([u(-0.6, 0.6) * z, u(-0.5, 0.5) * z, z]);
        }
        let scales = (0..3 * n).map(|_| u(0.01, 0.4)).collect();
        let quats = (0..4 * n).map(|_| u(-1.0, 1.0)).collect();
        let opacity = (0..n).map(|_| u(0.05, 0.95)).collect();
        let sh = (0..n * 4 * 3).map(|_| u(-0.8, 0.8)).collect();
        let eye = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let camera = Camera::new(48, 40, 40.0, 40.0, 24.0, 20.0, eye).expect("camera");
        let g = [
            Tensor::from_vec(means, &[n, 3]),
            Tensor::from_vec(scales, &[n, 3]),
            Tensor::from_vec(quats, &[n, 4]),
            Tensor::from_vec(opacity, &[n]),
            Tensor::from_vec(sh, &[n, 4, 3]),
        ];
        (g, camera)
    }

    /// Sum of every pixel channel of the render with Gaussian `i`'s opacity times `e`
    /// (forward only).
    fn image_sum(
        g: &[Tensor<f64>; 5],
        i: usize,
        e: f64,
        filter: &FilterState,
        s: &RenderSettings,
        cam: &Camera,
    ) -> f64 {
        let mut g = g.clone();
        g[3].data_mut()[i] *= e;
        let tape = Tape::new();
        let [means, scales, quats, opacity, sh] = g.map(|t| tape.constant(t));
        let v = GaussianVars {
            means,
            scales,
            quats,
            opacity,
            sh,
        };
        let r = maaf_splat::render(&tape, &fold_filter(v, filter, 0.5), cam, s);
        let image = r.image.value();
        image.data().iter().sum()
    }

    /// `o_i dS/do_i` equals the central difference of the image sum when Gaussian
    /// `i`'s opacity is scaled by `1 +- h` (f64, the C1 alpha cutoff so that no pixel
    /// jumps across the 1/255 threshold), on a white background, with and without
    /// the static 3D filter (whose opacity compensation differs from 1 per Gaussian:
    /// a derivative taken after the fold and not multiplied back would fail).
    #[test]
    fn removal_sensitivity_matches_finite_differences() {
        let (g, camera) = scene();
        let n = g[3].len();
        let settings = RenderSettings {
            background: [1.0; 3],
            sh_degree: 1,
            alpha_cutoff: AlphaCutoff::Smooth,
            ..RenderSettings::default()
        };
        let filters = [
            FilterState::None { rows: n },
            FilterState::Mip3d {
                s3d: 0.2,
                nu: (0..n).map(|k| 2.0 + k as f32).collect(),
            },
        ];
        let h = 1e-6;
        for filter in &filters {
            let s =
                removal_sensitivity(g.clone(), filter, 0.5, &camera, &settings).expect("backward");
            let scale = s.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(
                scale > 1.0,
                "{:?}: largest sensitivity {scale}",
                filter.kind()
            );
            let mut nonzero = 0;
            for (i, &got) in s.iter().enumerate() {
                let up = image_sum(&g, i, 1.0 + h, filter, &settings, &camera);
                let down = image_sum(&g, i, 1.0 - h, filter, &settings, &camera);
                let fd = (up - down) / (2.0 * h);
                let tol = 1e-5 * got.abs().max(fd.abs()) + 1e-7 * scale;
                assert!(
                    (got - fd).abs() <= tol,
                    "{:?} row {i}: {got} vs {fd}",
                    filter.kind()
                );
                nonzero += usize::from(got.abs() > 1e-3 * scale);
            }
            assert!(
                nonzero > n / 2,
                "{:?}: {nonzero} of {n} Gaussians reach the image",
                filter.kind()
            );
        }
    }

    #[test]
    fn keep_highest_removes_the_lowest_fraction_and_keeps_order() {
        let scores = [5.0, 1.0, 3.0, 1.0, 9.0, 0.5, 7.0, 2.0, 4.0, 6.0];
        // floor(0.35 * 10) = 3 rows go: 0.5 (row 5), then the tie 1.0 of rows 1 and 3.
        assert_eq!(keep_highest(&scores, 0.35), vec![0, 2, 4, 6, 7, 8, 9]);
        // A tie at the boundary goes to the lower index first.
        assert_eq!(keep_highest(&scores, 0.2), vec![0, 2, 3, 4, 6, 7, 8, 9]);
        assert_eq!(keep_highest(&scores, 0.0).len(), 10);
        assert_eq!(keep_highest(&scores, 0.8), vec![4, 6]);
    }
}
