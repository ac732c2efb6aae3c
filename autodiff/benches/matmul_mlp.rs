//! MLP forward+backward at the trainer's shapes, a GEMM peak, and matmul alone.
//!
//! - `mlp`: the residual-MLP shape of the trainer, `[41] -> width -> width -> 16`
//!   (41 = 32 plane channels + 9 time-encoding inputs), at N = 10k, 30k and 60k rows
//!   and width 64 and 128, as one fused op (`fused`, what the trainer runs) and as one
//!   dense op per layer (`layered`), so one run gives their ratio. The input is a gradient-carrying leaf (as the field
//!   features are in training), so the backward runs all three products of every
//!   layer: FLOPs = 3 x 2 N sum(in x out).
//! - `gemm_peak`: the best rate of the GEMM behind `Float::gemm` at 2048^3, the
//!   number to quote fractions of peak against.
//! - `matmul`: one product and its backward at 50000 x 64 x 64 (the MLP layer shape of a 50k-Gaussian step).
//!
//! Throughput is reported as "elem/s" where one element is one FLOP, so
//! `Gelem/s` reads as GFLOP/s.
//!
//! Run: `cargo bench -p maaf-autodiff --bench matmul_mlp`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use maaf_autodiff::check::tests_support::random_tensor;
use maaf_autodiff::nn::{Mlp, MlpVars};
use maaf_autodiff::ops::dense::Activation;
use maaf_autodiff::{Float, Tape, Tensor, Var};

/// Inputs of the trainer's motion/rotation/SH MLPs with the default config.
const INPUTS: usize = 41;
/// A middle output width (the trainer's heads have 3, 7 and 48 outputs).
const OUTPUTS: usize = 16;

/// The network as one dense op per layer (what `MlpVars::forward` did before the
/// fused op): the baseline of the `layered` rows.
fn layered<'t>(net: &MlpVars<'t, f32>, x: Var<'t, f32>) -> Var<'t, f32> {
    let last = net.layers.len() - 1;
    net.layers.iter().enumerate().fold(x, |h, (i, l)| {
        let act = if i < last {
            Activation::Relu
        } else {
            Activation::Identity
        };
        l.forward_act(h, act)
    })
}

fn mlp(c: &mut Criterion) {
    let mut group = c.benchmark_group("mlp");
    group.sample_size(10);
    for width in [64, 128] {
        let widths = [INPUTS, width, width, OUTPUTS];
        let net = Mlp::<f32>::new(&widths, false, 3);
        for rows in [10_000, 30_000, 60_000] {
            let x: Tensor<f32> = random_tensor(&[rows, INPUTS], -1.0, 1.0, 4);
            let macs: usize = widths.windows(2).map(|w| w[0] * w[1]).sum();
            group.throughput(Throughput::Elements((3 * 2 * rows * macs) as u64));
            for fused in [false, true] {
                let how = if fused { "fused" } else { "layered" };
                group.bench_function(format!("fwd+bwd N={rows} width={width} {how}"), |bench| {
                    bench.iter(|| {
                        let tape = Tape::new();
                        let bound = net.bind(&tape, "mlp");
                        let input = tape.var(x.clone());
                        let y = if fused {
                            bound.forward(input)
                        } else {
                            layered(&bound, input)
                        };
                        let grads = tape.backward(y.square().mean()).expect("finite");
                        std::hint::black_box(grads.wrt(input).map(|g| g.data()[0]))
                    })
                });
            }
        }
    }
    group.finish();
}

fn gemm_peak(c: &mut Criterion) {
    let mut group = c.benchmark_group("gemm_peak");
    group.sample_size(10);
    let n = 2048;
    let a: Tensor<f32> = random_tensor(&[n, n], -1.0, 1.0, 1);
    let b: Tensor<f32> = random_tensor(&[n, n], -1.0, 1.0, 2);
    let mut out = vec![0f32; n * n];
    group.throughput(Throughput::Elements((2 * n * n * n) as u64));
    group.bench_function(format!("sgemm {n}x{n}x{n}"), |bench| {
        bench.iter(|| {
            let s = n as isize;
            f32::gemm(
                n,
                n,
                n,
                1.0,
                a.data(),
                s,
                1,
                b.data(),
                s,
                1,
                0.0,
                &mut out,
                s,
                1,
            );
            std::hint::black_box(out[0])
        })
    });
    group.finish();
}

fn matmul(c: &mut Criterion) {
    let mut group = c.benchmark_group("matmul");
    group.sample_size(10);
    let (rows, width) = (50_000, 64);
    let a: Tensor<f32> = random_tensor(&[rows, width], -1.0, 1.0, 1);
    let b: Tensor<f32> = random_tensor(&[width, width], -1.0, 1.0, 2);
    group.throughput(Throughput::Elements((2 * rows * width * width) as u64));
    group.bench_function(format!("forward {rows}x{width}x{width}"), |bench| {
        bench.iter(|| {
            let tape = Tape::new();
            let y = tape.constant(a.clone()).matmul(tape.constant(b.clone()));
            std::hint::black_box(y.value().data()[0])
        })
    });
    // Forward plus both backward products: 3 GEMMs of the same size.
    group.throughput(Throughput::Elements((3 * 2 * rows * width * width) as u64));
    group.bench_function(
        format!("forward+backward {rows}x{width}x{width}"),
        |bench| {
            bench.iter(|| {
                let tape = Tape::new();
                let y = tape.var(a.clone()).matmul(tape.var(b.clone())).sum();
                std::hint::black_box(tape.backward(y).expect("finite").wrt(y).is_some())
            })
        },
    );
    group.finish();
}

criterion_group!(benches, mlp, gemm_peak, matmul);
criterion_main!(benches);
