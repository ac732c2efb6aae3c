//! Gradient checking: finite differences, VJP comparison against a reference, and
//! tensor comparison with a combined tolerance `|a - b| <= atol + rtol * max(|a|, |b|)`.

use std::fmt;

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use crate::{Float, Tape, Tensor, Var};

/// Settings of [`gradcheck`] and [`check_vjp`].
#[derive(Clone, Debug)]
pub struct GradcheckConfig {
    /// Central-difference step.
    pub eps: f64,
    /// Absolute tolerance.
    pub atol: f64,
    /// Relative tolerance.
    pub rtol: f64,
    /// Coordinates checked per input; larger inputs are sampled (seeded) down to this.
    pub max_coords: usize,
    /// Seed for the output cotangent and the coordinate sample.
    pub seed: u64,
}

impl Default for GradcheckConfig {
    /// `eps = 1e-6`, `atol = 1e-7`, `rtol = 1e-5`, 256 coordinates per input, seed 0.
    /// Central differences in f64 are accurate to about `eps^2 f''' + 1e-16 / eps`,
    /// i.e. ~1e-10 for smooth functions of O(1) values, so these tolerances catch a
    /// wrong factor or a missing term by several orders of magnitude.
    fn default() -> Self {
        GradcheckConfig {
            eps: 1e-6,
            atol: 1e-7,
            rtol: 1e-5,
            max_coords: 256,
            seed: 0,
        }
    }
}

impl GradcheckConfig {
    /// The same config with other tolerances.
    pub fn with_tol(mut self, atol: f64, rtol: f64) -> Self {
        self.atol = atol;
        self.rtol = rtol;
        self
    }

    /// The same config with another seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
}

/// One coordinate whose analytic gradient disagrees with the expected one.
#[derive(Clone, Debug)]
pub struct Failure {
    /// Which input (position in the input slice).
    pub input: usize,
    /// Flat index in that input.
    pub index: usize,
    /// Value of the input coordinate.
    pub value: f64,
    /// Expected gradient (finite difference, or the reference's VJP).
    pub expected: f64,
    /// Gradient computed by the backward under test.
    pub analytic: f64,
    /// Tolerance that was exceeded.
    pub tol: f64,
}

/// Outcome of a check: every failing coordinate plus summary statistics.
#[derive(Clone, Debug)]
pub struct GradcheckReport {
    /// What was compared (for the report header).
    pub what: &'static str,
    /// Coordinates checked.
    pub checked: usize,
    /// Largest absolute error over checked coordinates.
    pub max_abs_err: f64,
    /// Seed used.
    pub seed: u64,
    failures: Vec<Failure>,
}

impl GradcheckReport {
    /// True when no coordinate failed and at least one was checked.
    pub fn passed(&self) -> bool {
        self.failures.is_empty() && self.checked > 0
    }

    /// The failing coordinates.
    pub fn failures(&self) -> &[Failure] {
        &self.failures
    }

    /// Panics with the full report unless the check passed.
    pub fn assert_passed(&self) {
        assert!(self.passed(), "{self}");
    }
}

impl fmt::Display for GradcheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: {} of {} coordinates failed (max abs err {:.3e}, seed {})",
            self.what,
            self.failures.len(),
            self.checked,
            self.max_abs_err,
            self.seed
        )?;
        for x in &self.failures {
            writeln!(
                f,
                "  input {} index {}: x = {:.6e}, expected {:.9e}, analytic {:.9e}, |diff| {:.3e} > tol {:.3e}",
                x.input,
                x.index,
                x.value,
                x.expected,
                x.analytic,
                (x.expected - x.analytic).abs(),
                x.tol
            )?;
        }
        Ok(())
    }
}

fn within(a: f64, b: f64, atol: f64, rtol: f64) -> (bool, f64) {
    let tol = atol + rtol * a.abs().max(b.abs());
    ((a - b).abs() <= tol, tol)
}

fn sample_coords(len: usize, max: usize, rng: &mut Pcg64) -> Vec<usize> {
    if len <= max {
        return (0..len).collect();
    }
    // Partial Fisher-Yates: a seeded sample without replacement.
    let mut all: Vec<usize> = (0..len).collect();
    for i in 0..max {
        let j = rng.random_range(i..len);
        all.swap(i, j);
    }
    let mut picked = all[..max].to_vec();
    picked.sort_unstable();
    picked
}

fn random_like<T: Float>(shape: &[usize], rng: &mut Pcg64) -> Tensor<T> {
    let n: usize = shape.iter().product();
    Tensor::from_vec(
        (0..n).map(|_| T::of(rng.random_range(-1.0..1.0))).collect(),
        shape,
    )
}

fn dot(a: &Tensor<f64>, b: &Tensor<f64>) -> f64 {
    a.data().iter().zip(b.data()).map(|(x, y)| x * y).sum()
}

/// Checks the gradient of `f` at `inputs` against central differences in f64.
///
/// `f` may return a tensor of any shape: the check draws a seeded random cotangent
/// `w` and compares the tape's vector-Jacobian product `w^T df/dx` with
/// `(<w, f(x + eps e_i)> - <w, f(x - eps e_i)>) / (2 eps)` for each checked coordinate
/// `i` of every input. Inputs with more than `max_coords` elements are sampled.
pub fn gradcheck<F>(f: F, inputs: &[Tensor<f64>], cfg: &GradcheckConfig) -> GradcheckReport
where
    F: for<'t> Fn(&'t Tape<f64>, &[Var<'t, f64>]) -> Var<'t, f64>,
{
    let mut rng = Pcg64::seed_from_u64(cfg.seed);
    let (analytic, w) = {
        let tape = Tape::new();
        let vars: Vec<_> = inputs.iter().map(|x| tape.var(x.clone())).collect();
        let out = f(&tape, &vars);
        let w: Tensor<f64> = random_like(&out.shape(), &mut rng);
        let grads = tape
            .backward_from(&[(out, w.clone())])
            .expect("gradcheck: non-finite values in backward");
        let analytic: Vec<Tensor<f64>> = vars
            .iter()
            .zip(inputs)
            .map(|(v, x)| {
                grads
                    .wrt(*v)
                    .cloned()
                    .unwrap_or_else(|| Tensor::zeros(x.shape()))
            })
            .collect();
        (analytic, w)
    };
    let eval = |xs: &[Tensor<f64>]| {
        let tape = Tape::new();
        let vars: Vec<_> = xs.iter().map(|x| tape.constant(x.clone())).collect();
        let out = f(&tape, &vars);
        dot(&out.value(), &w)
    };
    let mut report = GradcheckReport {
        what: "gradcheck",
        checked: 0,
        max_abs_err: 0.0,
        seed: cfg.seed,
        failures: Vec::new(),
    };
    let mut xs: Vec<Tensor<f64>> = inputs.to_vec();
    for (input, x) in inputs.iter().enumerate() {
        for index in sample_coords(x.len(), cfg.max_coords, &mut rng) {
            let value = x.data()[index];
            xs[input].data_mut()[index] = value + cfg.eps;
            let plus = eval(&xs);
            xs[input].data_mut()[index] = value - cfg.eps;
            let minus = eval(&xs);
            xs[input].data_mut()[index] = value;
            let numeric = (plus - minus) / (2.0 * cfg.eps);
            let a = analytic[input].data()[index];
            record(&mut report, input, index, value, numeric, a, cfg);
        }
    }
    report
}

fn record(
    report: &mut GradcheckReport,
    input: usize,
    index: usize,
    value: f64,
    expected: f64,
    analytic: f64,
    cfg: &GradcheckConfig,
) {
    let (ok, tol) = within(expected, analytic, cfg.atol, cfg.rtol);
    report.checked += 1;
    report.max_abs_err = report.max_abs_err.max((expected - analytic).abs());
    if !ok {
        report.failures.push(Failure {
            input,
            index,
            value,
            expected,
            analytic,
            tol,
        });
    }
}

/// A function that builds outputs from inputs on a tape (an op under test or its reference).
type Build<'a, T> = dyn for<'t> Fn(&'t Tape<T>, &[Var<'t, T>]) -> Vec<Var<'t, T>> + 'a;

/// Checks a hand-written op against a reference built from differentiable primitives.
///
/// Both `op` and `reference` map the same inputs to the same list of outputs. The
/// check compares forward values (with the config's tolerances), then draws `trials`
/// seeded random cotangents for all outputs at once and compares the two tapes'
/// input gradients coordinate by coordinate.
pub fn check_vjp<T, F, R>(
    op: F,
    reference: R,
    inputs: &[Tensor<T>],
    trials: usize,
    cfg: &GradcheckConfig,
) -> GradcheckReport
where
    T: Float,
    F: for<'t> Fn(&'t Tape<T>, &[Var<'t, T>]) -> Vec<Var<'t, T>>,
    R: for<'t> Fn(&'t Tape<T>, &[Var<'t, T>]) -> Vec<Var<'t, T>>,
{
    let mut rng = Pcg64::seed_from_u64(cfg.seed);
    let mut report = GradcheckReport {
        what: "check_vjp",
        checked: 0,
        max_abs_err: 0.0,
        seed: cfg.seed,
        failures: Vec::new(),
    };
    let run = |g: &Build<'_, T>, seeds: Option<&[Tensor<T>]>| {
        let tape = Tape::new();
        let vars: Vec<_> = inputs.iter().map(|x| tape.var(x.clone())).collect();
        let outs = g(&tape, &vars);
        let values: Vec<Tensor<T>> = outs.iter().map(|o| o.value().clone()).collect();
        let grads = seeds.map(|seeds| {
            let pairs: Vec<_> = outs.iter().copied().zip(seeds.iter().cloned()).collect();
            let grads = tape
                .backward_from(&pairs)
                .expect("check_vjp: non-finite values in backward");
            vars.iter()
                .zip(inputs)
                .map(|(v, x)| {
                    grads
                        .wrt(*v)
                        .cloned()
                        .unwrap_or_else(|| Tensor::zeros(x.shape()))
                })
                .collect::<Vec<_>>()
        });
        (values, grads)
    };
    let (op_out, _) = run(&op, None);
    let (ref_out, _) = run(&reference, None);
    assert_eq!(
        op_out.len(),
        ref_out.len(),
        "check_vjp: op and reference return different output counts"
    );
    for (o, (a, b)) in op_out.iter().zip(&ref_out).enumerate() {
        assert_eq!(a.shape(), b.shape(), "check_vjp: output {o} shapes differ");
        for (i, (&x, &y)) in a.data().iter().zip(b.data()).enumerate() {
            record(
                &mut report,
                usize::MAX - o,
                i,
                f64::NAN,
                y.to_f64(),
                x.to_f64(),
                cfg,
            );
        }
    }
    for _ in 0..trials.max(1) {
        let seeds: Vec<Tensor<T>> = op_out
            .iter()
            .map(|o| random_like(o.shape(), &mut rng))
            .collect();
        let (_, ga) = run(&op, Some(&seeds));
        let (_, gb) = run(&reference, Some(&seeds));
        for (input, (a, b)) in ga
            .into_iter()
            .flatten()
            .zip(gb.into_iter().flatten())
            .enumerate()
        {
            for (index, (&x, &y)) in a.data().iter().zip(b.data()).enumerate() {
                let value = inputs[input].data()[index].to_f64();
                record(
                    &mut report,
                    input,
                    index,
                    value,
                    y.to_f64(),
                    x.to_f64(),
                    cfg,
                );
            }
        }
    }
    report
}

/// Summary of comparing two tensors elementwise.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// Largest `|a - b|`.
    pub max_abs_err: f64,
    /// Flat index of the largest error.
    pub worst_index: usize,
    /// Elements outside `atol + rtol * max(|a|, |b|)`.
    pub mismatches: usize,
}

impl Comparison {
    /// True when every element is within tolerance.
    pub fn passed(&self) -> bool {
        self.mismatches == 0
    }
}

/// Compares two tensors of the same shape with a combined tolerance; NaN never matches.
pub fn compare<T: Float>(a: &Tensor<T>, b: &Tensor<T>, atol: f64, rtol: f64) -> Comparison {
    assert_eq!(
        a.shape(),
        b.shape(),
        "compare: shapes {:?} and {:?} differ",
        a.shape(),
        b.shape()
    );
    let mut c = Comparison {
        max_abs_err: 0.0,
        worst_index: 0,
        mismatches: 0,
    };
    for (i, (&x, &y)) in a.data().iter().zip(b.data()).enumerate() {
        let (x, y) = (x.to_f64(), y.to_f64());
        let err = (x - y).abs();
        if err > c.max_abs_err || err.is_nan() {
            c.max_abs_err = if err.is_nan() { f64::INFINITY } else { err };
            c.worst_index = i;
        }
        if !within(x, y, atol, rtol).0 {
            c.mismatches += 1;
        }
    }
    c
}

/// Helpers for tests across the workspace: seeded random tensors.
pub mod tests_support {
    use super::*;

    /// A tensor of the given shape with values uniform in `[lo, hi)`, seeded.
    pub fn random_tensor<T: Float>(shape: &[usize], lo: f64, hi: f64, seed: u64) -> Tensor<T> {
        let mut rng = Pcg64::seed_from_u64(seed);
        let n: usize = shape.iter().product();
        Tensor::from_vec(
            (0..n).map(|_| T::of(rng.random_range(lo..hi))).collect(),
            shape,
        )
    }

    /// `f()` run on a fresh rayon pool of `threads` threads (the thread-count
    /// independence tests run the same work at 1, 2 and 3 threads).
    pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(f)
    }
}
