//! End-to-end f64 gradient check of one training step's loss: residual field -> MLPs
//! -> temporal opacity -> 3D filter fold -> splatting -> objective (L1, D-SSIM, L_SR),
//! with respect to every parameter of the SaRO model, plus a negative control.

use maaf::autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
use maaf::autodiff::{BackwardCtx, Op, Tape, Tensor, Var};
use maaf::splat::{
    AlphaCutoff, Camera, Filter2d, GaussianVars, RenderSettings, apply_3d_filter, render,
};
use maaf::train::loss::{L_SR, Objective, TermCtx};
use maaf::train::models::{Bound, KPlaneConfig, PointCloud, SaroConfig, SaroModel};

/// Identity whose backward is 1% off: placed in the chain, the check must fail.
struct OffByOnePercent;

impl Op<f64> for OffByOnePercent {
    type Saved = ();
    fn name(&self) -> String {
        "off_by_one_percent".into()
    }
    fn forward(&self, x: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, ()) {
        (vec![x[0].clone()], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, f64, ()>) -> Vec<Option<Tensor<f64>>> {
        vec![Some(c.grad_outputs[0].map(|g| 1.01 * g))]
    }
}

/// A 16x16 camera 3 units in front of the origin, looking at it (OpenCV axes).
fn camera() -> Camera {
    let mut w2c = [[0.0; 4]; 4];
    for (i, row) in w2c.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    w2c[2][3] = 3.0;
    Camera::new(16, 16, 18.0, 18.0, 8.0, 8.0, w2c).expect("valid camera")
}

/// A tiny dynamic SaRO model (5 Gaussians, small planes and MLPs) whose parameters
/// are then randomised so no path is trivially zero.
fn model() -> (SaroModel<f64>, Vec<Tensor<f64>>) {
    let mut points = Vec::new();
    let mut colours = Vec::new();
    for k in 0..5 {
        let a = k as f64 * 1.3;
        points.push([0.4 * a.cos(), 0.3 * a.sin(), 0.2 * (k as f64 - 2.0) / 2.0]);
        colours.push([0.2 + 0.15 * k as f64, 0.5, 0.8 - 0.1 * k as f64]);
    }
    let config = SaroConfig {
        field: KPlaneConfig {
            spatial_res: 4,
            time_res: 4,
            channels: 3,
            max_mip_level: 1,
        },
        hidden: 6,
        time_freqs: 1,
        sh_degree: 1,
        ..SaroConfig::default()
    };
    let mut m = SaroModel::from_point_cloud(&PointCloud { points, colours }, config, 2.0, 1);
    m.set_dynamic(true);
    let names = m.param_names();
    let inputs: Vec<Tensor<f64>> = m
        .param_tensors()
        .into_iter()
        .zip(&names)
        .enumerate()
        .map(|(k, (t, name))| {
            // Keep the canonical geometry and colours near their initial values (so every
            // Gaussian stays in view) and give planes and MLP heads O(0.3) random values.
            let noise: Tensor<f64> = random_tensor(t.shape(), -0.3, 0.3, 100 + k as u64);
            let scale = if name.starts_with("field") || name.contains("mlp") {
                1.0
            } else {
                0.1
            };
            match name.as_str() {
                // Opaque enough to matter (sigmoid(logit 0.1 + 3) ~ 0.7) and centred in
                // time near the rendered t = 0.4, so the temporal factor is not ~0.
                "opacity" => t.zip_map(&noise, |v, n| v + 3.0 + 0.1 * n),
                "t_centre" => t.zip_map(&noise, |_, n| 0.4 + 0.1 * n),
                _ => t.zip_map(&noise, |v, n| v + scale * n),
            }
        })
        .collect();
    (m, inputs)
}

fn loss<'t>(
    m: &SaroModel<f64>,
    tape: &'t Tape<f64>,
    v: &[Var<'t, f64>],
    gt: &Tensor<f64>,
    corrupt: bool,
) -> Var<'t, f64> {
    let bound = m.bind_vars(v, &m.detached());
    let g = bound.deform(0.4);
    let var = Tensor::from_vec(vec![0.002, 0.0005, 0.003, 0.001, 0.0], &[5]);
    let (scales, opacity) = apply_3d_filter(g.scales, g.opacity, &var);
    let settings = RenderSettings {
        background: [1.0, 1.0, 1.0],
        filter2d: Filter2d::Mip,
        sh_degree: 1,
        alpha_cutoff: AlphaCutoff::Smooth,
        ..RenderSettings::default()
    };
    let out = render(
        tape,
        &GaussianVars {
            means: g.means,
            scales,
            quats: g.quats,
            opacity,
            sh: g.sh,
        },
        &camera(),
        &settings,
    );
    let image = if corrupt {
        tape.apply1(OffByOnePercent, &[out.image])
    } else {
        out.image
    };
    let mut ctx = TermCtx::new(image, gt);
    for r in bound.regularisers() {
        ctx.insert(&r.name, r.value);
    }
    assert!(ctx.get(L_SR).is_some(), "the dynamic model provides L_SR");
    Objective::saro().evaluate(&ctx).total
}

#[test]
fn one_training_loss_passes_gradcheck_end_to_end() {
    let (m, inputs) = model();
    let gt: Tensor<f64> = random_tensor(&[16, 16, 3], 0.0, 1.0, 7);
    // The rendered image must actually contain the Gaussians, or the check is vacuous.
    let tape = Tape::new();
    let vars: Vec<_> = inputs.iter().map(|x| tape.constant(x.clone())).collect();
    let bound = m.bind_vars(&vars, &m.detached());
    let g = bound.deform(0.4);
    let out = render(
        &tape,
        &GaussianVars {
            means: g.means,
            scales: g.scales,
            quats: g.quats,
            opacity: g.opacity,
            sh: g.sh,
        },
        &camera(),
        &RenderSettings {
            background: [1.0; 3],
            alpha_cutoff: AlphaCutoff::Smooth,
            ..RenderSettings::default()
        },
    );
    assert!(
        out.radii.iter().all(|&r| r > 0),
        "every Gaussian is in view: {:?}",
        out.radii
    );
    assert!(out.alpha.value().data().iter().any(|&a| a > 0.1));

    // Every step is a smooth f64 composition (Smooth cutoff, L1 away from its kink on a
    // random ground truth); central differences with eps 1e-6 are accurate to ~1e-9 on
    // these O(1e-3..1) gradients, so atol 1e-7 / rtol 1e-4 still catch a 1% error.
    let cfg = GradcheckConfig {
        max_coords: 24,
        ..GradcheckConfig::default().with_tol(1e-7, 1e-4)
    };
    let report = gradcheck(|t, v| loss(&m, t, v, &gt, false), &inputs, &cfg);
    report.assert_passed();
    assert!(
        report.checked > 150,
        "only {} coordinates checked",
        report.checked
    );

    // Negative control: a 1% error in the image cotangent must be caught.
    let bad = gradcheck(|t, v| loss(&m, t, v, &gt, true), &inputs, &cfg);
    assert!(
        !bad.passed(),
        "a 1% wrong backward passed the end-to-end check"
    );
}
