//! The objective: named weighted terms, their values, their gradients.

use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
use maaf_autodiff::{Tape, Tensor, Var};
use maaf_train::loss::{Objective, Provided, Term, TermCtx, ssim};
use maaf_train::models::SaroConfig;

/// SaRO's regulariser name and weight, as the model declares them.
const L_SR: &str = "l_sr";
fn lambda_sr() -> f64 {
    SaroConfig::default().lambda_sr
}

/// The SaRO objective as the trainer builds it from the model's declaration.
fn saro_objective<T: maaf_autodiff::Float>() -> Objective<T> {
    Objective::photometric(0.2).with(Provided::new(L_SR, lambda_sr()))
}

fn image(seed: u64) -> Tensor<f64> {
    random_tensor(&[12, 10, 3], 0.0, 1.0, seed)
}

/// A training step reduced to what the objective sees: it takes any objective, so
/// adding a term is a change to the objective value only.
fn step<'t>(obj: &Objective<f64>, render: Var<'t, f64>, gt: &Tensor<f64>) -> (f64, Vec<String>) {
    let out = obj.evaluate(&TermCtx::new(render, gt));
    let names = out.terms.iter().map(|t| t.name.clone()).collect();
    (out.total_value(), names)
}

#[test]
fn photometric_total_is_the_weighted_sum_of_l1_and_dssim() {
    let (x, y) = (image(1), image(2));
    let tape = Tape::new();
    let render = tape.var(x.clone());
    let out = Objective::photometric(0.2).evaluate(&TermCtx::new(render, &y));
    let l1 = x
        .data()
        .iter()
        .zip(y.data())
        .map(|(a, b)| (a - b).abs())
        .sum::<f64>()
        / x.len() as f64;
    let s = ssim(render, tape.constant(y)).value().item();
    assert_eq!(out.terms.len(), 2);
    assert!((out.get("l1").expect("l1") - l1).abs() < 1e-14);
    assert!((out.get("dssim").expect("dssim") - (1.0 - s)).abs() < 1e-14);
    assert_eq!(out.terms[0].weight, 0.8);
    assert_eq!(out.terms[1].weight, 0.2);
    let expect = 0.8 * l1 + 0.2 * (1.0 - s);
    assert!((out.total_value() - expect).abs() < 1e-14);
}

#[test]
fn photometric_objective_passes_gradcheck() {
    // |x - y| is not differentiable at 0; random images keep every |x - y| >~ 1e-3,
    // far from the eps = 1e-6 step. Gradients are O(1/N), N = 360, so atol 2e-9 (see
    // the SSIM gradcheck for the roundoff estimate).
    let gt = image(4);
    let cfg = GradcheckConfig::default().with_tol(2e-9, 1e-5);
    let obj = Objective::photometric(0.2);
    let r = gradcheck(
        |_, v| obj.evaluate(&TermCtx::new(v[0], &gt)).total,
        &[image(3)],
        &cfg,
    );
    assert!(r.passed(), "{r}");
}

#[test]
fn provided_regulariser_is_zero_when_absent_and_weighted_when_present() {
    let (x, y) = (image(5), image(6));
    let obj = saro_objective::<f64>();
    assert_eq!(obj.names(), ["l1", "dssim", L_SR]);

    // Static stage: the model provides no L_SR.
    let tape = Tape::new();
    let render = tape.var(x.clone());
    let base = obj.evaluate(&TermCtx::new(render, &y));
    assert_eq!(base.get(L_SR), Some(0.0));

    // Dynamic stage: L_SR = ||d||_2 of a residual, provided by the model.
    let tape = Tape::new();
    let render = tape.var(x);
    let d = tape.param("dlog_s", Tensor::from_vec(vec![3.0, 4.0], &[2]));
    let l_sr = d.square().sum().sqrt();
    let out = obj.evaluate(&TermCtx::new(render, &y).with(L_SR, l_sr));
    assert_eq!(out.get(L_SR), Some(5.0));
    let diff = out.total_value() - base.total_value();
    assert!((diff - lambda_sr() * 5.0).abs() < 1e-15, "{diff}");
    let g = tape.backward(out.total).expect("finite");
    // d(w ||d||)/dd = w d / ||d||.
    let gd = g.param("dlog_s").expect("gradient reaches the regulariser");
    assert!((gd.data()[0] - lambda_sr() * 0.6).abs() < 1e-18);
    assert!((gd.data()[1] - lambda_sr() * 0.8).abs() < 1e-18);
}

/// Mean squared error, a user term written outside the crate.
struct Mse;
impl Term<f64> for Mse {
    fn name(&self) -> &str {
        "mse"
    }
    fn weight(&self) -> f64 {
        0.5
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, f64>) -> Var<'t, f64> {
        (ctx.render - ctx.gt).square().mean()
    }
}

#[test]
fn adding_a_term_changes_only_the_objective() {
    let (x, y) = (image(7), image(8));
    let tape = Tape::new();
    let render = tape.var(x.clone());
    let (base, names) = step(&Objective::photometric(0.2), render, &y);
    assert_eq!(names, ["l1", "dssim"]);
    let (more, names) = step(&Objective::photometric(0.2).with(Mse), render, &y);
    assert_eq!(names, ["l1", "dssim", "mse"]);
    let mse = x
        .data()
        .iter()
        .zip(y.data())
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / x.len() as f64;
    assert!((more - base - 0.5 * mse).abs() < 1e-14);
}

#[test]
fn zero_weight_terms_are_logged_but_add_nothing() {
    let (x, y) = (image(9), image(10));
    let tape = Tape::new();
    let render = tape.var(x);
    let out = Objective::photometric(0.0).evaluate(&TermCtx::new(render, &y));
    assert!(out.get("dssim").expect("logged") > 0.0);
    assert!((out.total_value() - out.get("l1").expect("l1")).abs() < 1e-15);
}

#[test]
#[should_panic(expected = "already present")]
fn duplicate_term_names_are_refused() {
    let _ = Objective::<f64>::photometric(0.2).with(maaf_train::loss::L1 { weight: 1.0 });
}

#[test]
fn f32_objective_runs_and_backpropagates() {
    let x: Tensor<f32> = random_tensor(&[16, 16, 3], 0.0, 1.0, 11);
    let y: Tensor<f32> = random_tensor(&[16, 16, 3], 0.0, 1.0, 12);
    let tape = Tape::new();
    let render = tape.param("render", x);
    let out = saro_objective::<f32>().evaluate(&TermCtx::new(render, &y).at_iteration(3));
    let g = tape.backward(out.total).expect("finite");
    let g = g.param("render").expect("gradient");
    assert!(g.first_non_finite().is_none());
    assert!(g.data().iter().any(|&v| v != 0.0));
}

#[test]
fn closure_terms_read_alpha_and_are_logged_by_name() {
    let tape = Tape::<f64>::new();
    let render = tape.var(image(7));
    let alpha = tape.param("alpha", Tensor::full(&[12, 10], 0.25));
    let depth = tape.constant(Tensor::zeros(&[12, 10]));
    let ctx = TermCtx::new(render, &image(8)).with_render(alpha, depth);
    let obj = Objective::<f64>::new().with_fn("alpha_l1", 2.0, |c| c.alpha().abs().mean());
    let out = obj.evaluate(&ctx);
    assert_eq!(out.get("alpha_l1"), Some(0.25));
    assert!((out.total_value() - 0.5).abs() < 1e-15);
    let g = tape.backward(out.total).expect("finite");
    let ga = g.param("alpha").expect("gradient");
    assert!(ga.data().iter().all(|&v| (v - 2.0 / 120.0).abs() < 1e-15));
}

#[test]
#[should_panic(expected = "no alpha")]
fn a_hand_built_context_names_what_it_lacks() {
    let tape = Tape::<f64>::new();
    let ctx = TermCtx::new(tape.var(image(1)), &image(2));
    let _ = ctx.alpha();
}

/// A run's objective on SaRO: the photometric loss, SaRO's `l_sr`, then the config's
/// terms in name order; a name no registry knows is listed, not added.
#[test]
fn a_run_objective_adds_the_config_terms_in_name_order_and_lists_unknown_ones() {
    use maaf_train::loss::TermRegistry;
    use maaf_train::models::{PointCloud, SaroModel};
    let cloud = PointCloud {
        points: vec![[0.0, 0.0, 0.0], [0.1, 0.2, 0.3]],
        colours: vec![[0.5, 0.5, 0.5]; 2],
        times: None,
    };
    let model = SaroModel::<f64>::from_point_cloud(&cloud, SaroConfig::default(), 1.0, 0);
    let mut registry = TermRegistry::<f64>::builtin();
    registry
        .register_fn("render_mean", |ctx| ctx.render.mean())
        .expect("a new name");
    let terms: std::collections::BTreeMap<String, f64> = [
        ("scale_anisotropy", 0.5),
        ("render_mean", 2.0),
        ("not_here", 1.0),
    ]
    .iter()
    .map(|&(n, w)| (n.to_string(), w))
    .collect();
    let obj = Objective::for_run(0.2, &model, &terms, &registry).expect("objective");
    assert_eq!(
        obj.names(),
        ["l1", "dssim", L_SR, "render_mean", "scale_anisotropy"]
    );
    assert_eq!(obj.terms()[3].weight(), 2.0);
    assert_eq!(obj.unregistered(), ["not_here"]);

    // The model's own regulariser is weighted in its settings, not in `terms`.
    let clash = [(L_SR.to_string(), 1.0)].into_iter().collect();
    let msg = Objective::for_run(0.2, &model, &clash, &registry)
        .err()
        .expect("refused")
        .to_string();
    assert!(msg.contains("`l_sr` is already a term"), "{msg}");

    // A maker that renames its term is refused rather than logged under another name.
    registry
        .register("renamed", |w| Box::new(Provided::new("other", w)))
        .expect("a new name");
    let renamed = [("renamed".to_string(), 1.0)].into_iter().collect();
    let msg = Objective::for_run(0.2, &model, &renamed, &registry)
        .err()
        .expect("refused")
        .to_string();
    assert!(msg.contains("returned a term named `other`"), "{msg}");
}
