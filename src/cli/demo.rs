//! `maaf demo`: the paper's multi-scale protocol in one command. Generates the
//! built-in synthetic scene (or takes `--data`), trains the same representation with
//! no 3D filter, Mip-Splatting's static 3D filter and the motion-aware filter, evaluates
//! each at 1/4x .. 4x of the training scale, and writes a report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use maaf_eval::{EvalOptions, evaluate_run};
use maaf_filter::FilterKind;
use maaf_scene::TrainConfig;
use maaf_train::data::synthetic::{self, GenerateOptions};
use maaf_train::data::{Dataset, DatasetOptions, Split};
use maaf_train::trainer::train_run;

/// Arguments of `maaf demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Output folder (data, runs, report).
    #[arg(long, default_value = "maaf-demo")]
    pub out: PathBuf,
    /// A smoke-test sized run (about a minute): smaller scene, fewer iterations.
    #[arg(long)]
    pub quick: bool,
    /// Run the protocol on this D-NeRF-format data set instead of the built-in scene
    /// (training at 1/4 of its resolution, as in the paper) [default: the built-in
    /// scene, generated into OUT/data].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Training iterations per run [default: 2500; 150 with --quick; 20000 with --data].
    #[arg(long)]
    pub iters: Option<usize>,
    /// Seed shared by all runs.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Demo sizes: source image size of the generated scene, iterations, initial points,
/// and the Gaussian budget (`None`: the training default).
struct Plan {
    size: u32,
    frames: usize,
    iterations: usize,
    init_points: usize,
    max_gaussians: Option<usize>,
}

impl Plan {
    /// The plan for `maaf demo [--quick]`; with `own_data` (`--data`, the paper's
    /// protocol on a real scene) there is no Gaussian budget below the default.
    fn new(quick: bool, own_data: bool) -> Self {
        let plan = if quick {
            Plan {
                size: 256,
                frames: 24,
                iterations: 150,
                init_points: 1500,
                max_gaussians: Some(12_000),
            }
        } else {
            // 100x100 training images hold 10^4 pixels; most of a step's cost grows
            // with the Gaussian count, so a budget of 4000 Gaussians buys 2500
            // iterations for about 1.3x the time of 1000 at 12 000 (88-92 s against
            // 65-74 s per filter on 2 cores), and more iterations are worth more to
            // a run that is still far from converged.
            Plan {
                size: 400,
                frames: 60,
                iterations: 2500,
                init_points: 3000,
                max_gaussians: Some(4000),
            }
        };
        Plan {
            max_gaussians: plan.max_gaussians.filter(|_| !own_data),
            ..plan
        }
    }

    /// The training configuration, with the schedule compressed to the iteration budget
    /// (densification, warm-up and filter refreshes at the same fractions of the run as
    /// the 20k-iteration D-NeRF schedule).
    fn config(&self, iterations: usize, filter: FilterKind, seed: u64) -> TrainConfig {
        let mut c = TrainConfig {
            iterations,
            train_scale: 0.25,
            seed,
            init_points: self.init_points,
            checkpoint_every: iterations,
            log_every: (iterations / 100).max(1),
            // Ten validation points per run: the report's quality-vs-time curves.
            val_every: (iterations / 100).max(1) * 10,
            sh_degree_every: (iterations / 20).max(1),
            ..TrainConfig::default()
        };
        let frac = |f: f64| ((iterations as f64 * f) as usize).max(1);
        // The warm-up keeps its share of the full schedule (SaRO 1000, deform 3000 of
        // 20 000 iterations).
        if let Some(warm_up) = c.model.warm_up_mut() {
            *warm_up = frac(*warm_up as f64 / TrainConfig::default().iterations as f64);
        }
        c.densify.from = frac(0.025);
        c.densify.until = frac(0.75);
        // Statistics need many views per Gaussian before they mean anything: keep the
        // 3DGS interval of 100 iterations rather than compressing it.
        c.densify.every = 100;
        if let Some(cap) = self.max_gaussians {
            c.densify.max_gaussians = cap;
        }
        // 3DGS resets opacity every 3000 iterations (SaRO-GS: 2000) and prunes screen-large
        // Gaussians after the first reset. Compressed into a short run, the reset comes
        // before densification has split the large initial Gaussians, and the pruning
        // wipes out most of the scene; runs shorter than the first reset have none.
        c.densify.opacity_reset_every = if iterations >= 4000 { 2000 } else { 0 };
        c.filter.kind = filter;
        c.filter.refresh.start = frac(0.03) as u64;
        c.filter.refresh.every = 100;
        c
    }
}

/// Runs `maaf demo`.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let plan = Plan::new(args.quick, args.data.is_some());
    let iterations = args.iters.unwrap_or(if args.data.is_some() && !args.quick {
        20_000
    } else {
        plan.iterations
    });
    // The settings are checked before the scene is generated (minutes of work).
    plan.config(iterations, FilterKind::Motion, args.seed)
        .validate()
        .context("the demo's settings")?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let data_dir = match &args.data {
        Some(d) => d.clone(),
        None => generate_scene(&args.out.join("data"), &plan)?,
    };
    let data = Dataset::open(&data_dir, DatasetOptions::default())?;
    let (w, h) = data.size(Split::Train, 1.0)?;
    println!(
        "demo: data {} ({w}x{h}), training at 1/4 scale for {iterations} iterations per filter",
        data_dir.display()
    );
    let mut runs = Vec::new();
    for (kind, label) in [
        (FilterKind::None, "none"),
        (FilterKind::Mip3d, "mip3d"),
        (FilterKind::Motion, "motion"),
    ] {
        let run_dir = args.out.join("runs").join(label);
        let config = plan.config(iterations, kind, args.seed);
        // A started run (its config.json written) continues from its newest complete
        // checkpoint, so an interrupted demo picks up where it stopped.
        let resume = run_dir.join("config.json").exists();
        if resume {
            println!("demo: {label}: continuing the run in {}", run_dir.display());
        }
        let t = Instant::now();
        let summary = train_run(&data, config, &run_dir, resume)?;
        println!(
            "demo: {label}: {} iterations, {} Gaussians, trained in {:.0} s",
            summary.iterations,
            summary.num_gaussians,
            t.elapsed().as_secs_f64()
        );
        let options = EvalOptions {
            scales: vec![0.25, 0.5, 1.0, 2.0, 4.0],
            ..EvalOptions::default()
        };
        let report = evaluate_run(&run_dir, &data, &options)?;
        let cells: Vec<String> = report
            .scales
            .iter()
            .map(|s| format!("{}x {:.2}", maaf_eval::trim_float(s.scale), s.psnr))
            .collect();
        println!("demo: {label}: PSNR {}", cells.join("  "));
        runs.push(run_dir);
    }
    let report_dir = args.out.join("report");
    let report = maaf_eval::report::write_report(&runs, &report_dir)?;
    println!("\n{}", report.table);
    println!(
        "demo finished in {:.0} s; report: {}",
        start.elapsed().as_secs_f64(),
        report.markdown.display()
    );
    let zoom = report_dir.join(maaf_eval::report::zoom::ZOOM_FIGURE);
    if zoom.is_file() {
        println!("zoomed out and in, the README's figure: {}", zoom.display());
    }
    Ok(())
}

/// Generates the built-in scene into `dir` unless a previous demo already did.
fn generate_scene(dir: &Path, plan: &Plan) -> anyhow::Result<PathBuf> {
    if dir.join("transforms_train.json").exists() {
        println!("demo: reusing the scene in {}", dir.display());
        return Ok(dir.to_path_buf());
    }
    let opts = GenerateOptions {
        size: plan.size,
        frames: Some(plan.frames),
        ..GenerateOptions::default()
    };
    let summary = synthetic::generate(dir, &opts, &mut |_, _| {})?;
    println!(
        "demo: generated the built-in scene in {:.1} s",
        summary.seconds
    );
    Ok(dir.to_path_buf())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `configs/demo.json` is the configuration `maaf demo` trains its motion-aware run
    /// with (the other two runs differ in `filter.kind` only).
    #[test]
    fn demo_preset_is_the_demo_config() {
        let preset: TrainConfig = serde_json::from_str(include_str!("../../configs/demo.json"))
            .expect("configs/demo.json is a training config");
        let plan = Plan::new(false, false);
        let demo = plan.config(plan.iterations, FilterKind::Motion, 0);
        assert_eq!(
            preset,
            demo,
            "configs/demo.json differs from the demo's config:\n{}",
            serde_json::to_string_pretty(&demo).expect("serialise")
        );
    }
}
