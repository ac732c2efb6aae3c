//! End-to-end f64 gradient check of one training step's loss, through the same
//! `forward` the trainer calls: residual field -> MLPs -> temporal opacity -> 3D
//! filter fold -> splatting -> objective (L1, D-SSIM, L_SR), with respect to every
//! parameter of the SaRO model, plus a negative control.

use maaf::autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
use maaf::autodiff::{BackwardCtx, Op, Tape, Tensor, Var};
use maaf::filter::FilterState;
use maaf::scene::forward::{forward, forward_bound};
use maaf::splat::{AlphaCutoff, Camera, Filter2d, RenderSettings};
use maaf::train::loss::{ForwardTerms, Objective, batch_mean};
use maaf::train::models::params::BoundParams;
use maaf::train::models::{KPlaneConfig, PointCloud, Representation, SaroConfig, SaroModel};

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
fn model() -> SaroModel<f64> {
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
        duration: Some(150.0),
        ..SaroConfig::default()
    };
    let cloud = PointCloud {
        points,
        colours,
        times: None,
    };
    let mut m = SaroModel::from_point_cloud(&cloud, config, 2.0, 1);
    m.set_dynamic(true);
    for (k, p) in m.params.iter_mut().enumerate() {
        // Keep the canonical geometry and colours near their initial values (so every
        // Gaussian stays in view) and give planes and MLP heads O(0.3) random values.
        let noise: Tensor<f64> = random_tensor(p.value.shape(), -0.3, 0.3, 100 + k as u64);
        let scale = if p.name.starts_with("field") || p.name.contains("mlp") {
            1.0
        } else {
            0.1
        };
        p.value = match p.name.as_str() {
            // Opaque enough to matter (sigmoid(logit 0.1 + 3) ~ 0.7) and centred in
            // time near the rendered t = 0.4, so the temporal factor is not ~0.
            "opacity" => p.value.zip_map(&noise, |v, n| v + 3.0 + 0.1 * n),
            "t_centre" => p.value.zip_map(&noise, |_, n| 0.4 + 0.1 * n),
            _ => p.value.zip_map(&noise, |v, n| v + scale * n),
        };
    }
    m
}

/// The static 3D filter with variances `var` (`s3d / nu^2`, s3d = 0.2).
fn filter(var: &[f32]) -> FilterState {
    FilterState::Mip3d {
        s3d: 0.2,
        nu: var.iter().map(|&v| (0.2 / v).sqrt()).collect(),
    }
}

fn settings() -> RenderSettings {
    RenderSettings {
        background: [1.0, 1.0, 1.0],
        filter2d: Filter2d::Mip,
        sh_degree: 1,
        alpha_cutoff: AlphaCutoff::Smooth,
        ..RenderSettings::default()
    }
}

/// The training loss of one step, through the trainer's `forward` and `objective`.
fn loss<'t>(
    m: &SaroModel<f64>,
    v: &[Var<'t, f64>],
    gt: &Tensor<f64>,
    objective: &Objective<f64>,
) -> Var<'t, f64> {
    let params = BoundParams::from_vars(&m.params, v);
    let f = filter(&[0.002, 0.0005, 0.003, 0.001, 0.0]);
    let fwd = forward(m, &params, &f, &camera(), 0.4, &settings());
    assert!(
        fwd.regularisers.iter().any(|(n, _)| n == "l_sr"),
        "the dynamic model provides L_SR"
    );
    fwd.objective(objective, gt, 5000).total
}

#[test]
fn one_training_loss_passes_gradcheck_end_to_end() {
    let m = model();
    let inputs = m.params.tensors();
    let gt: Tensor<f64> = random_tensor(&[16, 16, 3], 0.0, 1.0, 7);
    // The rendered image must actually contain the Gaussians, or the check is vacuous.
    let tape = Tape::new();
    let params = m.params.bind_constants(&tape);
    let out = forward(&m, &params, &filter(&[0.0; 5]), &camera(), 0.4, &settings());
    assert!(
        out.render.radii.iter().all(|&r| r > 0),
        "every Gaussian is in view: {:?}",
        out.render.radii
    );
    assert!(out.render.alpha.value().data().iter().any(|&a| a > 0.1));

    let objective = Objective::for_model(0.2, &m as &dyn Representation<f64>);
    assert_eq!(objective.names(), ["l1", "dssim", "l_sr"]);
    // Every step is a smooth f64 composition (Smooth cutoff, L1 away from its kink on a
    // random ground truth); central differences with eps 1e-6 are accurate to ~1e-9 on
    // these O(1e-3..1) gradients, so atol 1e-7 / rtol 1e-4 still catch a 1% error.
    let cfg = GradcheckConfig {
        max_coords: 24,
        ..GradcheckConfig::default().with_tol(1e-7, 1e-4)
    };
    let report = gradcheck(|_, v| loss(&m, v, &gt, &objective), &inputs, &cfg);
    report.assert_passed();
    assert!(
        report.checked > 150,
        "only {} coordinates checked",
        report.checked
    );

    // Negative control: a term whose image cotangent is 1% wrong must be caught.
    let corrupt =
        Objective::for_model(0.2, &m as &dyn Representation<f64>).with_fn("corrupt", 1.0, |ctx| {
            let tape = ctx.render.tape();
            (tape.apply1(OffByOnePercent, &[ctx.render]) - ctx.gt)
                .square()
                .mean()
        });
    let bad = gradcheck(|_, v| loss(&m, v, &gt, &corrupt), &inputs, &cfg);
    assert!(
        !bad.passed(),
        "a 1% wrong backward passed the end-to-end check"
    );
}

/// A batch (one binding, each view deformed at its own time, the mean objective)
/// gives the mean of the views' separate objectives and gradients: the shared
/// binding carries nothing from one time to the next.
#[test]
fn a_batch_is_the_mean_of_its_views() {
    let m = model();
    let objective = Objective::for_model(0.2, &m as &dyn Representation<f64>);
    let f = filter(&[0.002, 0.0005, 0.003, 0.001, 0.0]);
    let views: Vec<(f64, Tensor<f64>)> = [(0.3, 11), (0.55, 12)]
        .into_iter()
        .map(|(t, seed)| (t, random_tensor(&[16, 16, 3], 0.0, 1.0, seed)))
        .collect();

    let tape = Tape::new();
    let params = m.params.bind(&tape);
    let bound = m.bind(&params);
    let totals: Vec<_> = views
        .iter()
        .map(|(t, gt)| {
            forward_bound(bound.as_ref(), &f, &camera(), *t, &settings())
                .objective(&objective, gt, 5000)
                .total
        })
        .collect();
    let batch = batch_mean(&totals);
    let batch_grads = tape.backward(batch).expect("backward");

    let mut single = Vec::new();
    for (t, gt) in &views {
        let tape = Tape::new();
        let params = m.params.bind(&tape);
        let total = forward(&m, &params, &f, &camera(), *t, &settings())
            .objective(&objective, gt, 5000)
            .total;
        let grads = tape.backward(total).expect("backward");
        let by_name: Vec<Tensor<f64>> = m
            .params
            .iter()
            .map(|p| grads.param(&p.name).expect("every parameter").clone())
            .collect();
        single.push((total.value().item(), by_name));
    }
    let mean_value = (single[0].0 + single[1].0) / 2.0;
    assert!((batch.value().item() - mean_value).abs() <= 1e-14 * mean_value.abs());
    let mut views_differ = false;
    for (k, p) in m.params.iter().enumerate() {
        let got = batch_grads.param(&p.name).expect("every parameter");
        let (a, b) = (&single[0].1[k], &single[1].1[k]);
        for ((&g, &x), &y) in got.data().iter().zip(a.data()).zip(b.data()) {
            let want = (x + y) / 2.0;
            assert!(
                (g - want).abs() <= 1e-12 + 1e-10 * want.abs(),
                "{}: batch gradient {g} vs mean of views {want}",
                p.name
            );
            views_differ |= (x - y).abs() > 1e-6 * (x.abs() + y.abs());
        }
    }
    assert!(views_differ, "the two views must give different gradients");
}
