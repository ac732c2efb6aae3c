//! Matmul and MLP forward+backward at the sizes the trainer uses (N = 50k rows,
//! width 64 and 128). Throughput is reported in FLOP/s ("elements" = FLOPs).
//!
//! Run: `cargo bench -p maaf-autodiff --bench matmul_mlp`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use maaf_autodiff::check::tests_support::random_tensor;
use maaf_autodiff::nn::Mlp;
use maaf_autodiff::{Tape, Tensor};

const ROWS: usize = 50_000;

fn matmul(c: &mut Criterion) {
    let mut group = c.benchmark_group("matmul");
    group.sample_size(10);
    for width in [64, 128] {
        let a: Tensor<f32> = random_tensor(&[ROWS, width], -1.0, 1.0, 1);
        let b: Tensor<f32> = random_tensor(&[width, width], -1.0, 1.0, 2);
        group.throughput(Throughput::Elements((2 * ROWS * width * width) as u64));
        group.bench_function(format!("forward {ROWS}x{width}x{width}"), |bench| {
            bench.iter(|| {
                let tape = Tape::new();
                let y = tape.constant(a.clone()).matmul(tape.constant(b.clone()));
                std::hint::black_box(y.value().data()[0])
            })
        });
        // Forward plus both backward products: 3 GEMMs of the same size.
        group.throughput(Throughput::Elements((3 * 2 * ROWS * width * width) as u64));
        group.bench_function(
            format!("forward+backward {ROWS}x{width}x{width}"),
            |bench| {
                bench.iter(|| {
                    let tape = Tape::new();
                    let y = tape.var(a.clone()).matmul(tape.var(b.clone())).sum();
                    std::hint::black_box(tape.backward(y).expect("finite").wrt(y).is_some())
                })
            },
        );
    }
    group.finish();
}

fn mlp(c: &mut Criterion) {
    let mut group = c.benchmark_group("mlp");
    group.sample_size(10);
    // The residual-MLP shape of the trainer: [features + PE] -> width -> width -> 10.
    let inputs = 48;
    for width in [64, 128] {
        let net = Mlp::<f32>::new(&[inputs, width, width, 10], false, 3);
        let x: Tensor<f32> = random_tensor(&[ROWS, inputs], -1.0, 1.0, 4);
        let flops = 2 * ROWS * (inputs * width + width * width + width * 10);
        group.throughput(Throughput::Elements((3 * flops) as u64));
        group.bench_function(
            format!("forward+backward N={ROWS} width={width}"),
            |bench| {
                bench.iter(|| {
                    let tape = Tape::new();
                    let bound = net.bind(&tape, "mlp");
                    let loss = bound.forward(tape.constant(x.clone())).square().mean();
                    let grads = tape.backward(loss).expect("finite");
                    std::hint::black_box(grads.param("mlp.0.weight").map(|g| g.data()[0]))
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, matmul, mlp);
criterion_main!(benches);
