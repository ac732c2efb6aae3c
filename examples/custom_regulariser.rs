//! The whole `maaf` command line plus a loss term of one's own (README, "Extending
//! maaf"): every command works as in `maaf`, and a training config names the term
//! with a weight, `"terms": {"smoothness": 0.01}`. Runs that use it resume with this
//! program; `maaf train --resume` refuses them, naming the term. The term is generic
//! over the float type, so the test below checks its gradient in f64 as written.
//!
//! Run: `cargo run --release --example custom_regulariser -- train --data DATA --out RUN --config C.json`
//! (the code down to the marker is the README's, line for line).

use maaf::autodiff::{Float, Var};
use maaf::train::loss::TermCtx;
/// Edge-aware smoothness `mean(|dx R| exp(-10 |dx G|))`.
fn smoothness<'t, T: Float>(ctx: &TermCtx<'t, T>) -> Var<'t, T> {
    let w = ctx.render.shape()[1];
    let dx = |x: Var<'t, T>| x.slice(1, 1, w) - x.slice(1, 0, w - 1);
    (dx(ctx.render).abs() * dx(ctx.gt).abs().scale(-10.0).exp()).mean()
}
fn main() {
    maaf::cli::Maaf::new().term("smoothness", smoothness).run()
}
// ---- end of the README's program ----

#[cfg(test)]
mod tests {
    use maaf::autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    use super::*;

    #[test]
    fn the_readme_term_passes_gradcheck_as_written() {
        let gt = random_tensor(&[9, 11, 3], 0.0, 1.0, 3);
        let render = random_tensor(&[9, 11, 3], 0.0, 1.0, 4);
        // Gradients of an image mean are O(1/N): atol well above the f64
        // central-difference roundoff, as the other term examples use.
        let cfg = GradcheckConfig::default().with_tol(2e-9, 1e-5);
        let report = gradcheck(
            |_, v| smoothness(&TermCtx::new(v[0], &gt)),
            std::slice::from_ref(&render),
            &cfg,
        );
        assert!(report.passed(), "{report}");
        // The program's entry point is the command line, not run here.
        let _: fn() = main;
    }
}
