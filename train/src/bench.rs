//! The step benchmark (`maaf bench`): one training iteration timed phase by phase
//! through the tape's op profile, on a trained SaRO model resized to N Gaussians,
//! against this machine's GEMM and memory-copy throughput measured in the same run.
//!
//! Each size starts from a trained run (its model, filter kind, stage and SH degree),
//! resized to N Gaussians by sampling its rows, and runs [`Trainer::step`] itself (the
//! step that trains) with no densification, so N stays fixed. Work per phase:
//! - MLP (`dense`, `matmul` ops): `2 N sum(in * out)` FLOPs forward over every MLP
//!   the step evaluates (lifespan, L_SR's rotation head at Dt = 0, motion, rotation
//!   and SH heads at t), twice that backward (input and weight gradients); the
//!   fraction is of the measured GEMM rate;
//! - optimiser: Adam reads parameter, gradient and both moments and writes three of
//!   them, `7 x 4` bytes per scalar; the fraction is of the measured copy rate;
//! - renderer, K-plane field, loss and elementwise ops, and the statistics recorded
//!   after the update: time only (not GEMM-shaped).

use std::time::Instant;

use maaf_autodiff::{OpProfile, Tape, Tensor};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use crate::Error;
use crate::models::DeformConfig;
use crate::models::ModelConfig;
use crate::models::saro::SaroConfig;
use crate::trainer::{DensifyPlan, Trainer};
use maaf_scene::TrainConfig;

/// Throughput of this machine measured in the run: the library's f32 GEMM and a large
/// memory copy.
#[derive(Clone, Copy, Debug)]
pub struct Peak {
    /// Best f32 GEMM rate, GFLOP/s (square product of [`PEAK_GEMM_SIZE`], all threads).
    pub gemm_gflops: f64,
    /// Best copy rate, GB/s (bytes read plus bytes written).
    pub copy_gbps: f64,
}

/// Side of the square GEMM that measures the peak.
pub const PEAK_GEMM_SIZE: usize = 1536;

/// Measures [`Peak`]: the best of five GEMMs through the tape's matmul (the path the
/// MLPs use) and the best of five copies of 64 Mi floats.
pub fn measure_peak() -> Peak {
    let s = PEAK_GEMM_SIZE;
    let mut rng = Pcg64::seed_from_u64(7);
    let mut random =
        |len: usize| -> Vec<f32> { (0..len).map(|_| rng.random_range(-1.0..1.0)).collect() };
    let (a, b) = (random(s * s), random(s * s));
    let best_gemm = (0..5)
        .map(|_| {
            let tape = Tape::<f32>::new();
            let x = tape.constant(Tensor::from_vec(a.clone(), &[s, s]));
            let y = tape.constant(Tensor::from_vec(b.clone(), &[s, s]));
            let t0 = Instant::now();
            let z = x.matmul(y);
            let dt = t0.elapsed().as_secs_f64();
            std::hint::black_box(z.value().data()[0]);
            dt
        })
        .fold(f64::INFINITY, f64::min);
    let len = 64 << 20;
    let src = vec![1.0f32; len];
    let mut dst = vec![0.0f32; len];
    let best_copy = (0..5)
        .map(|_| {
            let t0 = Instant::now();
            dst.copy_from_slice(std::hint::black_box(&src));
            let dt = t0.elapsed().as_secs_f64();
            std::hint::black_box(dst[len / 2]);
            dt
        })
        .fold(f64::INFINITY, f64::min);
    Peak {
        gemm_gflops: 2.0 * (s as f64).powi(3) / best_gemm / 1e9,
        copy_gbps: (2 * 4 * len) as f64 / best_copy / 1e9,
    }
}

/// One phase of a benchmarked step.
#[derive(Clone, Debug)]
pub struct PhaseRow {
    /// Phase name.
    pub phase: &'static str,
    /// Forward milliseconds per iteration.
    pub forward_ms: f64,
    /// Backward milliseconds per iteration.
    pub backward_ms: f64,
    /// FLOPs per iteration (forward + backward), where counted.
    pub flops: Option<f64>,
    /// Bytes moved per iteration, where counted.
    pub bytes: Option<f64>,
}

/// What one size of the benchmark measured.
#[derive(Clone, Debug)]
pub struct StepBench {
    /// Gaussians.
    pub gaussians: usize,
    /// Image size of the training views.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Views per iteration (the trainer's `batch`).
    pub views: usize,
    /// Whole step, milliseconds per iteration.
    pub step_ms: f64,
    /// Phases (their sum is below `step_ms` by the step's own bookkeeping).
    pub rows: Vec<PhaseRow>,
}

/// Options of [`bench_step`].
#[derive(Clone, Debug)]
pub struct StepBenchOptions {
    /// Timed iterations per size.
    pub iterations: usize,
    /// Untimed iterations first (SH degree reaches 3, buffers warm).
    pub warmup: usize,
    /// Seed of the model and the view order.
    pub seed: u64,
    /// Views per iteration (None: the run's `batch`).
    pub batch: Option<usize>,
}

impl Default for StepBenchOptions {
    fn default() -> Self {
        StepBenchOptions {
            iterations: 20,
            warmup: 5,
            seed: 0,
            batch: None,
        }
    }
}

/// FLOPs of one forward through an MLP of `widths` for `n` rows: `2 n sum(in * out)`.
fn mlp_flops(n: usize, widths: &[usize]) -> f64 {
    2.0 * n as f64 * widths.windows(2).map(|w| (w[0] * w[1]) as f64).sum::<f64>()
}

/// Forward FLOPs of every MLP a SaRO step of `views` views evaluates for `n`
/// Gaussians: the lifespan MLP and L_SR's rotation MLP once, the residual MLPs per view.
fn saro_mlp_forward_flops(n: usize, c: &SaroConfig, views: usize) -> f64 {
    let (h, ch, input, k) = (
        c.hidden,
        c.field.channels,
        c.field.channels + c.pe_dim(),
        c.sh_coeffs(),
    );
    let life = mlp_flops(n, &[ch, h, (h / 2).max(1), 1]);
    let rot = mlp_flops(n, &[input, h, h, 7]);
    let motion = mlp_flops(n, &[input, h, h, 3]);
    let sh = if c.sh_residual {
        mlp_flops(n, &[input, h, h, 3 * k])
    } else {
        0.0
    };
    life + rot + views as f64 * (rot + motion + sh)
}

/// Forward FLOPs of the deformation MLP of a Deformable-3DGS step of `views` views for
/// `n` Gaussians (the time network runs on one row and is left out).
fn deform_mlp_forward_flops(n: usize, c: &DeformConfig, views: usize) -> f64 {
    let (trunk, rest) = c.network_widths();
    views as f64 * (mlp_flops(n, &trunk) + rest.map_or(0.0, |w| mlp_flops(n, &w)))
}

/// Forward FLOPs of every MLP one step of `views` views of `model` evaluates for `n`
/// Gaussians (0 for the tracking model, which has none, and for a custom
/// representation, whose networks maaf does not know).
fn mlp_forward_flops(n: usize, model: &ModelConfig, views: usize) -> f64 {
    match model {
        ModelConfig::Saro(c) => saro_mlp_forward_flops(n, c, views),
        ModelConfig::Deform(c) => deform_mlp_forward_flops(n, c, views),
        ModelConfig::Track(_) | ModelConfig::Custom { .. } => 0.0,
    }
}

/// Prepares `trainer` for timing at `gaussians` Gaussians: rows sampled with
/// replacement (seeded) from its model, as densification's clones would add them;
/// no densification, opacity reset or filter refresh during the timed steps.
fn resize_for_bench(trainer: &mut Trainer, gaussians: usize, opts: &StepBenchOptions) {
    resample_rows(trainer, gaussians, opts.seed);
    let c = &mut trainer.config;
    c.batch = opts.batch.unwrap_or(c.batch);
    hold_schedule(c, trainer.iteration + opts.warmup + opts.iterations + 1);
}

/// A schedule that only steps, for timing steps at a fixed Gaussian count: `iterations`
/// in all, no densification, opacity reset or filter refresh.
pub(crate) fn hold_schedule(c: &mut TrainConfig, iterations: usize) {
    c.iterations = iterations;
    c.densify.from = usize::MAX;
    c.densify.opacity_reset_every = 0;
    c.filter.refresh.start = u64::MAX;
    c.filter.refresh.after_densify = false;
}

/// Resizes `trainer` to `gaussians` Gaussians: its first rows, then rows sampled with
/// replacement (seeded by `seed`) from its model, as densification's clones would add
/// them (every per-Gaussian container follows, [`Trainer::apply_plan`]).
pub fn resample_rows(trainer: &mut Trainer, gaussians: usize, seed: u64) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let n = trainer.num_gaussians();
    let index: Vec<usize> = (0..gaussians)
        .map(|i| if i < n { i } else { rng.random_range(0..n) })
        .collect();
    trainer.state.apply_plan(&DensifyPlan {
        index,
        new_rows: Vec::new(),
        new_means: Vec::new(),
        new_scales: Vec::new(),
        cloned: 0,
        split: 0,
        pruned: 0,
    });
}

/// Times `opts.iterations` training steps of the trained run `trainer` (see
/// [`crate::load_run`]) at `gaussians` Gaussians; also returns the op profile
/// of the timed steps. The filter is recomputed once for the resized model, untimed.
pub fn bench_step(
    mut trainer: Trainer,
    gaussians: usize,
    opts: &StepBenchOptions,
) -> Result<(StepBench, OpProfile), Error> {
    if trainer.num_gaussians() == 0 {
        return Err(Error::Input("the run's model has no Gaussians".into()));
    }
    trainer.config.batch = opts.batch.unwrap_or(trainer.config.batch);
    trainer.check_memory(gaussians)?;
    resize_for_bench(&mut trainer, gaussians, opts);
    trainer.refresh_filter();
    for _ in 0..opts.warmup {
        trainer.step();
    }
    trainer.timings = Default::default();
    trainer.op_profile = Some(OpProfile::default());
    let t0 = Instant::now();
    for _ in 0..opts.iterations {
        trainer.step();
    }
    let per = |s: f64| 1e3 * s / opts.iterations as f64;
    let step_ms = per(t0.elapsed().as_secs_f64());
    let profile = trainer.op_profile.take().unwrap_or_default();
    let n = trainer.num_gaussians();
    let group = |pick: &dyn Fn(&str) -> bool| {
        let (f, b) = profile.seconds_where(pick);
        (per(f), per(b))
    };
    let is_mlp = |op: &str| op.starts_with("dense") || op == "matmul" || op == "mlp";
    let is_render = |op: &str| {
        [
            "quat_scale_to_cov",
            "project_ewa",
            "sh_color",
            "rasterize",
            "apply_3d_filter",
        ]
        .contains(&op)
    };
    let is_field = |op: &str| op == "kplane_sample";
    let is_loss = |op: &str| ["l1", "ssim", "dssim"].contains(&op);
    let (mlp_f, mlp_b) = group(&is_mlp);
    let (ren_f, ren_b) = group(&is_render);
    let (fld_f, fld_b) = group(&is_field);
    let (loss_f, loss_b) = group(&is_loss);
    let (oth_f, oth_b) = group(&|op| !(is_mlp(op) || is_render(op) || is_field(op) || is_loss(op)));
    let scalars: usize = trainer
        .state
        .model
        .params()
        .iter()
        .map(|p| p.value.len())
        .sum();
    let views = trainer.config.batch;
    let fwd_flops = mlp_forward_flops(n, &trainer.config.model, views);
    let camera = &trainer.cameras()[0];
    let row = |phase, forward_ms, backward_ms, flops, bytes| PhaseRow {
        phase,
        forward_ms,
        backward_ms,
        flops,
        bytes,
    };
    let bench = StepBench {
        gaussians: n,
        views,
        width: camera.width,
        height: camera.height,
        step_ms,
        rows: vec![
            row(
                "MLPs (mlp, dense, matmul)",
                mlp_f,
                mlp_b,
                Some(3.0 * fwd_flops),
                None,
            ),
            row("K-plane field", fld_f, fld_b, None, None),
            row(
                "renderer (cov, EWA, SH, raster, 3D filter)",
                ren_f,
                ren_b,
                None,
                None,
            ),
            row("loss (L1, SSIM)", loss_f, loss_b, None, None),
            row("elementwise, concat, slice, sum", oth_f, oth_b, None, None),
            row(
                "optimiser (Adam)",
                per(trainer.timings.optimiser),
                0.0,
                None,
                Some(28.0 * scalars as f64),
            ),
            row(
                "statistics (densification, liveness, observations)",
                per(trainer.timings.statistics),
                0.0,
                None,
                None,
            ),
        ],
    };
    Ok((bench, profile))
}

/// A markdown table of `runs` with each counted phase's rate and fraction of `peak`.
pub fn format_table(runs: &[StepBench], peak: &Peak) -> String {
    let mut out = format!(
        "peak measured in this run: GEMM {:.1} GFLOP/s ({s}x{s}x{s} f32), copy {:.1} GB/s\n\n",
        peak.gemm_gflops,
        peak.copy_gbps,
        s = PEAK_GEMM_SIZE
    );
    out += "| N | size | phase | fwd ms | bwd ms | work | rate | of peak |\n|---:|---|---|---:|---:|---:|---:|---:|\n";
    for r in runs {
        for p in &r.rows {
            let ms = p.forward_ms + p.backward_ms;
            let (work, rate, frac) = match (p.flops, p.bytes) {
                (Some(f), _) => {
                    let g = f / (ms * 1e-3) / 1e9;
                    (
                        format!("{:.2} GFLOP", f / 1e9),
                        format!("{g:.1} GFLOP/s"),
                        format!("{:.0}%", 100.0 * g / peak.gemm_gflops),
                    )
                }
                (None, Some(b)) => {
                    let g = b / (ms * 1e-3) / 1e9;
                    (
                        format!("{:.1} MB", b / 1e6),
                        format!("{g:.1} GB/s"),
                        format!("{:.0}%", 100.0 * g / peak.copy_gbps),
                    )
                }
                (None, None) => ("-".into(), "-".into(), "-".into()),
            };
            out += &format!(
                "| {} | {}x{} | {} | {:.2} | {:.2} | {work} | {rate} | {frac} |\n",
                r.gaussians, r.width, r.height, p.phase, p.forward_ms, p.backward_ms
            );
        }
        out += &format!(
            "| {} | {}x{} | **whole step, {} view{}** | | | | **{:.1} ms** ({:.1} ms per view) | |\n",
            r.gaussians,
            r.width,
            r.height,
            r.views,
            if r.views == 1 { "" } else { "s" },
            r.step_ms,
            r.step_ms / r.views as f64
        );
    }
    out
}
