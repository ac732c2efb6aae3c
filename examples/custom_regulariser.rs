//! The whole `maaf` command line plus a loss term of one's own (README, "Extending
//! maaf"): every command works as in `maaf`, and a training config names the term
//! with a weight, `"terms": {"smoothness": 0.01}`. Runs that use it resume with this
//! program; `maaf train --resume` refuses them, naming the term.
//!
//! Run: `cargo run --release --example custom_regulariser -- train --data DATA --out RUN --config C.json`
//! (the code below is the README's, line for line).

use maaf::{autodiff::Var, train::loss::TermCtx};
/// Edge-aware smoothness `mean(|dx R| exp(-10 |dx G|))`.
fn smoothness<'t>(ctx: &TermCtx<'t, f32>) -> Var<'t, f32> {
    let w = ctx.render.shape()[1];
    let dx = |x: Var<'t, f32>| x.slice(1, 1, w) - x.slice(1, 0, w - 1);
    (dx(ctx.render).abs() * dx(ctx.gt).abs().scale(-10.0).exp()).mean()
}
fn main() {
    maaf::cli::Maaf::new().term("smoothness", smoothness).run()
}
