//! A representation of your own in the whole `maaf` command line: a small
//! Deformable-3DGS-style model (canonical 3D Gaussians plus one MLP that maps the
//! positional encodings of the detached canonical centre and of t to residuals of
//! position, rotation and log-scale; Yang et al. 2024), written only against maaf's
//! public API and registered under the name `tiny_deform`. A training config names
//! it with its own options, which its factory reads and checks, naming the field:
//!
//! ```text
//! # "model": {"kind": "tiny_deform", "width": 32, "warm_up": 100} in C.json
//! cargo run --release --example custom_representation -- train --data DATA --out RUN --config C.json
//! cargo run --release --example custom_representation -- train --resume RUN
//! cargo run --release --example custom_representation -- eval --run RUN
//! ```
//!
//! The same registration lets `eval`, `render`, `render-video` and `export-ply` load
//! its runs; plain `maaf` refuses them, naming the representation.
//! `tests/cli/custom_plugins.rs` runs it: trains, is killed, resumes bit-identical,
//! evaluates, exports.

use maaf::autodiff::nn::Mlp;
use maaf::autodiff::ops::concat;
use maaf::autodiff::optim::LrSchedule;
use maaf::autodiff::scalar::logit;
use maaf::autodiff::{Tensor, Var};
use maaf::scene::TrainConfig;
use maaf::splat::GaussianVars;
use maaf::train::models::params::{BoundParams, MlpParams, ParamId, ParamStore, Rows};
use maaf::train::models::{
    Bound, CanonicalIds, ModelInit, Representation, knn_mean_sq_dist, rgb_to_sh_dc,
};
use serde_json::{Map, Value};

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
        "tiny_deform"
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

/// A count option of the model section: `default` when absent, else an integer in
/// `lo..=hi`; the error names the field.
fn count(
    options: &Map<String, Value>,
    key: &str,
    default: usize,
    lo: usize,
    hi: usize,
) -> Result<usize, String> {
    match options.get(key) {
        None => Ok(default),
        Some(v) => v
            .as_u64()
            .map(|n| n as usize)
            .filter(|n| (lo..=hi).contains(n))
            .ok_or_else(|| format!("model.{key} = {v}: must be an integer in {lo}..={hi}")),
    }
}

/// Builds the model from the run's config: its options are `width` (hidden units
/// of the deformation MLP, 32) and `warm_up` (static iterations, a quarter of the
/// run); any other key is refused, naming it.
fn tiny_deform(
    config: &TrainConfig,
    init: &ModelInit,
) -> Result<Box<dyn Representation<f32>>, String> {
    let empty = Map::new();
    let options = config.model.options().unwrap_or(&empty);
    if let Some(key) = options
        .keys()
        .find(|k| !["width", "warm_up"].contains(&k.as_str()))
    {
        return Err(format!(
            "model.{key}: unknown option of tiny_deform (width, warm_up)"
        ));
    }
    let width = count(options, "width", 32, 1, 1024)?;
    let warm_up = count(options, "warm_up", config.iterations / 4, 0, usize::MAX)?;
    Ok(Box::new(Deform::new(init, width, warm_up)))
}

fn main() {
    maaf::cli::Maaf::new()
        .representation("tiny_deform", tiny_deform)
        .run()
}
