//! Writing a new loss term and trusting its gradient: a total-variation regulariser
//! as a user-defined [`Term`], gradchecked in f64 on its own and inside the full
//! objective `0.8 L1 + 0.2 D-SSIM + 0.1 TV`.
//!
//! Run: `cargo run --release --example custom_loss_gradcheck`

use maaf::autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
use maaf::autodiff::{Float, Tensor, Var};
use maaf::train::loss::{Objective, Term, TermCtx};

// ---- the user's code ----
/// Squared total variation `mean (x[i+1,j] - x[i,j])^2 + mean (x[i,j+1] - x[i,j])^2`.
struct TotalVariation(f64);
impl<T: Float> Term<T> for TotalVariation {
    fn name(&self) -> &str {
        "tv"
    }
    fn weight(&self) -> f64 {
        self.0
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        let (x, s) = (ctx.render, ctx.render.shape());
        let dy = x.slice(0, 1, s[0]) - x.slice(0, 0, s[0] - 1);
        let dx = x.slice(1, 1, s[1]) - x.slice(1, 0, s[1] - 1);
        dy.square().mean() + dx.square().mean()
    }
}
// ---- end of the user's code ----

fn main() {
    let gt: Tensor<f64> = random_tensor(&[12, 10, 3], 0.0, 1.0, 1);
    let render: Tensor<f64> = random_tensor(&[12, 10, 3], 0.0, 1.0, 2);
    // Gradients of image means are O(1/N) ~ 1e-3: atol 2e-9 sits ~5x above the
    // central-difference roundoff (~1e-16 / eps = 1e-10 per unit of output).
    let cfg = GradcheckConfig::default().with_tol(2e-9, 1e-5);

    let term = gradcheck(
        |_, v| TotalVariation(1.0).value(&TermCtx::new(v[0], &gt)),
        std::slice::from_ref(&render),
        &cfg,
    );
    let objective = Objective::photometric(0.2).with(TotalVariation(0.1));
    let full = gradcheck(
        |_, v| objective.evaluate(&TermCtx::new(v[0], &gt)).total,
        &[render],
        &cfg,
    );
    println!("term alone:          {term}objective with term: {full}");
    assert!(term.passed() && full.passed(), "gradcheck failed");
}

#[test]
fn example_runs() {
    main();
}
