//! `maaf bench`: the step benchmark of [`maaf_train::bench`] at several Gaussian
//! counts, as a markdown table with each phase's fraction of this machine's peak.

use std::path::PathBuf;

use maaf_scene::MAX_BATCH;
use maaf_train::bench::{StepBenchOptions, bench_step, format_table, measure_peak};
use maaf_train::{Plugins, load_run};

/// Most timed or warm-up iterations per count: a benchmark, not a training (the
/// timing settles within tens).
const MAX_BENCH_ITERS: usize = 10_000;

/// Arguments of `maaf bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// A trained run (`maaf train --out RUN`) whose model, resized to each count, is
    /// timed on its training views.
    #[arg(long)]
    pub run: PathBuf,
    /// The run's data set [default: the one recorded in the run].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Gaussian counts to time, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "10000,30000,60000")]
    pub gaussians: Vec<usize>,
    /// Timed iterations per count (at most 10000).
    #[arg(long, default_value_t = 20)]
    pub iters: usize,
    /// Untimed iterations before timing (at most 10000).
    #[arg(long, default_value_t = 5)]
    pub warmup: usize,
    /// Views per iteration [default: the run's `batch`].
    #[arg(long)]
    pub batch: Option<usize>,
    /// Also list the ten slowest tape ops per count.
    #[arg(long)]
    pub ops: bool,
}

/// Runs the benchmark and prints the table; the run's representation, filter,
/// strategy and terms must be among `plugins` (a program's own through
/// `maaf::cli::Maaf`).
pub fn run(args: &BenchArgs, plugins: &Plugins) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=MAX_BENCH_ITERS).contains(&args.iters),
        "--iters {}: must be in 1..={MAX_BENCH_ITERS}",
        args.iters
    );
    anyhow::ensure!(
        args.warmup <= MAX_BENCH_ITERS,
        "--warmup {}: must be in 0..={MAX_BENCH_ITERS}",
        args.warmup
    );
    anyhow::ensure!(
        args.gaussians.iter().all(|&n| n > 0),
        "--gaussians: counts must be positive"
    );
    anyhow::ensure!(
        args.batch.is_none_or(|b| (1..=MAX_BATCH).contains(&b)),
        "--batch must be in 1..={MAX_BATCH}"
    );
    let _lock = super::eval::read_lock(&args.run)?;
    let data = super::eval::open_run_data(&args.run, args.data.as_deref(), None, &plugins.formats)?;
    let opts = StepBenchOptions {
        iterations: args.iters,
        warmup: args.warmup,
        batch: args.batch,
        ..StepBenchOptions::default()
    };
    let peak = measure_peak();
    let mut runs = Vec::new();
    for &n in &args.gaussians {
        let trainer = load_run(&args.run, &data, plugins)?;
        let (bench, profile) = bench_step(trainer, n, &opts)?;
        if args.ops {
            println!("slowest ops at N = {n} (ms per iteration, forward / backward):");
            for (name, t) in profile.by_total().into_iter().take(10) {
                let per = |s: f64| 1e3 * s / args.iters as f64;
                println!(
                    "  {name:<28} {:8.2} {:8.2}",
                    per(t.forward),
                    per(t.backward)
                );
            }
        }
        runs.push(bench);
    }
    println!("{}", format_table(&runs, &peak));
    Ok(())
}
