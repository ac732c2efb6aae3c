//! Training with a user-defined regulariser: an edge-aware smoothness term added to the
//! objective as a named term, logged by name next to L1 and D-SSIM. Adding it does not
//! touch the training step.
//!
//! Run: `cargo run --release --example custom_regulariser -- [DATA_DIR] [ITERATIONS]`
//! (defaults: the mutant scene in ../shared/data/dnerf/mutant, 100 iterations at 1/8 scale).

use maaf::autodiff::{Float, Var};
use maaf::train::data::{Dataset, DatasetOptions};
use maaf::train::loss::{Term, TermCtx};
use maaf::train::trainer::{TrainConfig, Trainer};

// ---- the user's code: ten lines ----
/// Edge-aware smoothness: horizontal render gradients, damped where the ground truth
/// has an edge, `mean(|dx R| exp(-10 |dx G|))`.
struct EdgeAwareSmoothness;
impl<T: Float> Term<T> for EdgeAwareSmoothness {
    fn name(&self) -> &str {
        "smoothness"
    }
    fn weight(&self) -> f64 {
        0.01
    }
    fn value<'t>(&self, ctx: &TermCtx<'t, T>) -> Var<'t, T> {
        let dx = |x: Var<'t, T>, w: usize| x.slice(1, 1, w) - x.slice(1, 0, w - 1);
        let w = ctx.render.shape()[1];
        (dx(ctx.render, w).abs() * dx(ctx.gt, w).abs().scale(-10.0).exp()).mean()
    }
}
// ---- end of the user's code ----

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let data_dir = args
        .next()
        .unwrap_or_else(|| "../shared/data/dnerf/mutant".into());
    let iterations: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(100);
    let data = Dataset::open(std::path::Path::new(&data_dir), DatasetOptions::default())?;
    let config = TrainConfig {
        iterations,
        train_scale: 0.125,
        init_points: 2000,
        ..TrainConfig::default()
    };
    let mut trainer = Trainer::new(&data, config)?;
    trainer.objective.push(Box::new(EdgeAwareSmoothness));
    while trainer.iteration < iterations {
        trainer.step();
        if trainer.iteration % 20 == 0 {
            let terms: Vec<String> = trainer
                .last_terms
                .iter()
                .map(|(n, v)| format!("{n} {v:.4}"))
                .collect();
            println!("iteration {:4}: {}", trainer.iteration, terms.join("  "));
        }
    }
    Ok(())
}
