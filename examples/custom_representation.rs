//! A representation of your own, trained by the normal trainer: a small
//! Deformable-3DGS-style model (canonical 3D Gaussians plus one MLP that maps the
//! positional encodings of the detached canonical centre and of t to residuals of
//! position, rotation and log-scale; Yang et al. 2024), written only against maaf's
//! public API. It trains on the built-in scene with the motion-aware filter and a
//! custom regulariser, checkpoints, resumes bit-identically from a checkpoint, resumes
//! its run directory with the term re-supplied, is registered by name so that its run
//! loads as a trained scene without the training code's trainer (rendering exactly as
//! the trainer does), and is evaluated at three scales; the same registration in
//! `maaf::cli::Maaf` lets `maaf eval` and `export-ply` load the run.
//!
//! Run: `cargo run --release --example custom_representation [-- OUT_DIR]`
//! (default `target/custom_representation`; also runs as a test).

use std::path::{Path, PathBuf};

use maaf::autodiff::nn::Mlp;
use maaf::autodiff::ops::concat;
use maaf::autodiff::optim::LrSchedule;
use maaf::autodiff::scalar::logit;
use maaf::autodiff::{Tensor, Var};
use maaf::cli::Maaf;
use maaf::filter::FilterKind;
use maaf::splat::GaussianVars;
use maaf::train::data::synthetic::{self, GenerateOptions};
use maaf::train::data::{Dataset, DatasetOptions, Split};
use maaf::train::eval::{EvalOptions, evaluate_scene};
use maaf::train::models::{
    Bound, CanonicalIds, ModelInit, Representation, knn_mean_sq_dist, rgb_to_sh_dc,
};
use maaf::train::params::{BoundParams, MlpParams, ParamId, ParamStore, Rows};
use maaf::train::scene::{ModelRegistry, TrainedScene};
use maaf::train::trainer::{TrainConfig, Trainer, checkpoint_dir, model_init, train_run_with};

// ---- the user's representation: about 120 lines ----

/// NeRF positional encoding `[x, sin(2^k x), cos(2^k x)]_{k < freqs}` per column.
fn encode(values: &[f32], cols: usize, freqs: usize) -> Tensor<f32> {
    let rows = values.len() / cols;
    let mut out = Vec::with_capacity(rows * cols * (1 + 2 * freqs));
    for row in values.chunks_exact(cols) {
        out.extend_from_slice(row);
        for k in 0..freqs {
            let f = (1u32 << k) as f32;
            out.extend(row.iter().map(|v| (f * v).sin()));
            out.extend(row.iter().map(|v| (f * v).cos()));
        }
    }
    Tensor::from_vec(out, &[rows, cols * (1 + 2 * freqs)])
}

/// Canonical Gaussians + a deformation MLP on `[PE(sg(x)), PE(t)]` -> (dx, dq, ds).
struct Deform {
    params: ParamStore<f32>,
    canon: CanonicalIds,
    sh: ParamId,
    mlp: MlpParams,
    /// Static warm-up: plain 3D Gaussians until this iteration (Deformable-3DGS: 3000).
    warm_up: usize,
    dynamic: bool,
}

const X_FREQS: usize = 6;
const T_FREQS: usize = 4;

impl Deform {
    fn new(init: &ModelInit, hidden: usize, warm_up: usize) -> Self {
        let n = init.cloud.len();
        let d2 = knn_mean_sq_dist(&init.cloud.points, 3);
        let mut p = ParamStore::new();
        let per = |p: &mut ParamStore<f32>, name: &str, v: Vec<f32>, shape: &[usize], lr| {
            p.add(
                name,
                Tensor::from_vec(v, shape),
                Rows::PerGaussian,
                LrSchedule::Constant(lr),
                0.0,
            )
        };
        let xyz = init
            .cloud
            .points
            .iter()
            .flatten()
            .map(|&v| v as f32)
            .collect();
        let means = per(&mut p, "xyz", xyz, &[n, 3], 1.6e-4 * init.extent);
        let s = d2
            .iter()
            .flat_map(|&d| [(d.sqrt().ln().clamp(-10.0, 1.0)) as f32; 3]);
        let log_scales = per(&mut p, "log_scale", s.collect(), &[n, 3], 5e-3);
        let q = (0..n).flat_map(|_| [1.0, 0.0, 0.0, 0.0]).collect();
        let quats = per(&mut p, "rotation", q, &[n, 4], 1e-3);
        let opacity_logits = per(&mut p, "opacity", vec![logit(0.1f32); n], &[n], 0.05);
        let dc = init
            .cloud
            .colours
            .iter()
            .flatten()
            .map(|&c| rgb_to_sh_dc(c) as f32);
        let sh = per(&mut p, "sh", dc.collect(), &[n, 1, 3], 2.5e-3);
        let input = 3 * (1 + 2 * X_FREQS) + 1 + 2 * T_FREQS;
        let net = Mlp::new(&[input, hidden, hidden, 10], true, init.seed);
        let lr = LrSchedule::ExpDecay {
            init: 8e-4 * init.extent,
            last: 1.6e-6 * init.extent,
            max_steps: 20_000,
        };
        let mlp = MlpParams::add(&mut p, "deform", net, &lr, 0.0);
        let canon = CanonicalIds {
            means,
            log_scales,
            quats,
            opacity_logits,
        };
        Deform {
            params: p,
            canon,
            sh,
            mlp,
            warm_up,
            dynamic: false,
        }
    }
}

struct DeformBound<'t> {
    means: Var<'t, f32>,
    log_scales: Var<'t, f32>,
    quats: Var<'t, f32>,
    opacity: Var<'t, f32>,
    sh: Var<'t, f32>,
    net: Option<(maaf::autodiff::nn::MlpVars<'t, f32>, Tensor<f32>)>,
}

impl<'t> Bound<'t, f32> for DeformBound<'t> {
    fn deform(&self, time: f64) -> GaussianVars<'t, f32> {
        let (mut means, mut log_scales, mut quats) = (self.means, self.log_scales, self.quats);
        if let Some((net, pe_x)) = &self.net {
            let tape = self.means.tape();
            let n = pe_x.rows();
            let pe_t = encode(&vec![time as f32; n], 1, T_FREQS);
            let h = concat(&[tape.constant(pe_x.clone()), tape.constant(pe_t)], 1);
            let d = net.forward(h);
            means = means + d.slice(1, 0, 3);
            quats = quats + d.slice(1, 3, 7);
            log_scales = log_scales + d.slice(1, 7, 10);
        }
        GaussianVars {
            means,
            scales: log_scales.exp(),
            quats,
            opacity: self.opacity,
            sh: self.sh,
        }
    }
}

/// Modelling only: the five required methods and the stage switch. Densification, the
/// opacity reset and checkpoints work on the store through `canonical_ids`; the
/// optional `TrainingHooks` (state outside the store, per-Gaussian learning-rate
/// scales, temporal pruning) are not needed.
impl Representation<f32> for Deform {
    fn name(&self) -> &str {
        "deform-example"
    }
    fn params(&self) -> &ParamStore<f32> {
        &self.params
    }
    fn params_mut(&mut self) -> &mut ParamStore<f32> {
        &mut self.params
    }
    fn canonical_ids(&self) -> CanonicalIds {
        self.canon
    }
    fn set_iteration(&mut self, iteration: usize) {
        self.dynamic = iteration > self.warm_up;
    }
    fn bind<'t>(&self, p: &BoundParams<'t, f32>) -> Box<dyn Bound<'t, f32> + 't> {
        let c = self.canon;
        // The encoding of the detached canonical centre is the same for every t.
        let net = self.dynamic.then(|| {
            let x = self.params.value(c.means).data();
            (self.mlp.bind(p), encode(x, 3, X_FREQS))
        });
        Box::new(DeformBound {
            means: p.get(c.means),
            log_scales: p.get(c.log_scales),
            quats: p.get(c.quats),
            opacity: p.get(c.opacity_logits).sigmoid(),
            sh: p.get(self.sh),
            net,
        })
    }
}

// ---- end of the user's representation ----

/// The same trainer every time (fresh run, resume): the model and a custom term,
/// a displacement regulariser that reads the deformed Gaussians.
fn build(data: &Dataset, config: &TrainConfig) -> Result<Trainer, Box<dyn std::error::Error>> {
    let init = model_init(data, config)?;
    let model = Deform::new(&init, 32, config.iterations / 4);
    let mut trainer = Trainer::with_model(data, config.clone(), Box::new(model))?;
    trainer
        .objective
        .push_fn("opacity_mean", 1e-3, |ctx| ctx.gaussians().opacity.mean());
    Ok(trainer)
}

fn params(t: &Trainer) -> Vec<(String, Tensor<f32>)> {
    t.model
        .params()
        .named_tensors()
        .map(|(n, v)| (n.to_string(), v.clone()))
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).map_or_else(
        || PathBuf::from("target/custom_representation"),
        PathBuf::from,
    );
    run_in(&out)
}

/// Generates the scene into `out/data` and runs everything in `out/run`.
fn run_in(out: &Path) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(out)?;
    let data_dir = out.join("data");
    if !data_dir.join("transforms_train.json").exists() {
        let opts = GenerateOptions {
            size: 96,
            frames: Some(24),
            samples: 2,
            test_frames: 4,
            val_frames: 2,
            video_frames: 4,
            force: true,
            ..GenerateOptions::default()
        };
        synthetic::generate(&data_dir, &opts, &mut |_, _| {})?;
    }
    let data = Dataset::open(&data_dir, DatasetOptions::default())?;
    let mut config = TrainConfig {
        iterations: 300,
        train_scale: 0.5,
        init_points: 1500,
        checkpoint_every: 100,
        log_every: 10,
        ..TrainConfig::default()
    };
    config.filter.kind = FilterKind::Motion;
    config.filter.refresh.start = 60;
    config.densify.from = 50;
    config.densify.until = 250;
    config.densify.every = 50;
    config.densify.opacity_reset_every = 0;

    // 1. A whole run in a run directory, through the library's run entry point.
    let run = out.join("run");
    let _ = std::fs::remove_dir_all(&run);
    let summary = train_run_with(build(&data, &config)?, &run, false)?;
    println!(
        "trained {} iterations: {} Gaussians",
        summary.iterations, summary.num_gaussians
    );

    // 2. Resume from the checkpoint at iteration 200: bit-identical to the run.
    let mut resumed = build(&data, &config)?;
    resumed.restore(&checkpoint_dir(&run, 200))?;
    while resumed.iteration < config.iterations {
        resumed.step();
    }
    let mut finished = build(&data, &config)?;
    finished.restore(&run.join("model"))?;
    let identical = params(&resumed) == params(&finished);
    println!("resumed from iteration 200: parameters bit-identical: {identical}");
    if !identical {
        return Err("the resumed run differs from the uninterrupted one".into());
    }

    // 3. Continue the run directory for 50 more iterations, the term re-supplied.
    let more = TrainConfig {
        iterations: 350,
        ..config.clone()
    };
    let summary = train_run_with(build(&data, &more)?, &run, true)?;
    let log = std::fs::read_to_string(run.join("log.csv"))?;
    let header = log.lines().next().unwrap_or("");
    println!(
        "resumed to {} iterations; log.csv: {header}",
        summary.iterations
    );
    if !header.contains("opacity_mean") {
        return Err("the custom term is missing from log.csv".into());
    }

    // 4. Register the representation by name: its run then loads as a trained scene
    // (no trainer, no data set), which renders exactly as the trainer does.
    let mut registry = ModelRegistry::builtin();
    registry.register("deform-example", |config, init| {
        let model = Deform::new(init, 32, config.iterations / 4);
        Ok(Box::new(model) as Box<dyn Representation<f32>>)
    });
    let scene = TrainedScene::load(&run, &registry)?;
    let mut trainer = build(&data, &more)?;
    trainer.restore(&run.join("model"))?;
    let camera = data.camera(Split::Test, 0, more.train_scale)?;
    let same = scene.render(&camera, 0.5) == trainer.into_scene().render(&camera, 0.5);
    println!("the registered run loads as a scene; renders as the trainer does: {same}");
    if !same {
        return Err("the loaded scene renders differently from the trainer".into());
    }

    // 5. Evaluate like any run.
    let options = EvalOptions {
        scales: vec![0.5, 1.0, 2.0],
        save_images: false,
        ..EvalOptions::default()
    };
    let report = evaluate_scene(&scene, &run, &data, &options)?;
    for s in &report.scales {
        println!("  {}x: PSNR {:.2} dB, SSIM {:.3}", s.scale, s.psnr, s.ssim);
    }
    ensure_finite(&run)?;

    // 6. The same registration gives the whole command line (`maaf::cli::Maaf`):
    // `eval` and `export-ply` load the run by its representation's name, which plain
    // `maaf` does not know.
    let cli = Maaf::new().representation("deform-example", |config, init| {
        let model = Deform::new(init, 32, config.iterations / 4);
        Ok(Box::new(model) as Box<dyn Representation<f32>>)
    });
    let run_arg = run.display().to_string();
    let ply = out.join("frame.ply").display().to_string();
    let data_arg = data_dir.display().to_string();
    let eval = [
        "maaf",
        "eval",
        "--run",
        &run_arg,
        "--data",
        &data_arg,
        "--scales",
        "1",
        "--no-images",
    ];
    cli.run_args(eval)?;
    cli.run_args([
        "maaf",
        "export-ply",
        "--run",
        &run_arg,
        "--time",
        "0.5",
        "--out",
        &ply,
    ])?;
    ensure_finite(&run)?;
    match Maaf::new().run_args(eval) {
        Err(e) if e.to_string().contains("deform-example") => {
            println!("plain maaf refuses the run: {e}")
        }
        other => return Err(format!("plain maaf should refuse the run: {other:?}").into()),
    }
    Ok(())
}

/// The evaluation wrote finite numbers (a diverged model would not).
fn ensure_finite(run: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let text = std::fs::read_to_string(run.join("eval.json"))?;
    let v: serde_json::Value = serde_json::from_str(&text)?;
    let ok = v["scales"].as_array().is_some_and(|s| {
        s.iter()
            .all(|e| e["psnr"].as_f64().is_some_and(f64::is_finite))
    });
    if ok {
        Ok(())
    } else {
        Err("eval.json holds a non-finite PSNR".into())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn trains_resumes_and_evaluates() {
        let dir = std::env::temp_dir().join(format!("maaf-custom-rep-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        super::run_in(&dir).expect("the example runs");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
