//! Cost of one LPIPS distance (two backbone passes) at the evaluation sizes, AlexNet and,
//! when its weights were fetched (`bash lpips/tools/fetch_vgg_weights.sh`), VGG16.
//!
//! `cargo bench -p maaf-lpips --bench lpips`

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use maaf_autodiff::Tensor;
use maaf_lpips::{Lpips, Net};

/// A deterministic smooth colour image with some texture, `[n, n, 3]` on [0, 1].
fn image(n: usize, phase: f32) -> Tensor<f32> {
    let data = (0..n * n * 3)
        .map(|i| {
            let (p, c) = (i / 3, i % 3);
            let (y, x) = ((p / n) as f32, (p % n) as f32);
            0.5 + 0.4 * (0.07 * x + 0.05 * y + phase + c as f32).sin() * (0.11 * y - 0.03 * x).cos()
        })
        .collect();
    Tensor::from_vec(data, &[n, n, 3])
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("lpips_distance");
    group.sample_size(10);
    for net in [Net::Alex, Net::Vgg] {
        let lpips = match Lpips::load_default(net) {
            Ok(m) => m,
            Err(e) if net == Net::Vgg => {
                eprintln!("skipping VGG16: {e}");
                continue;
            }
            Err(e) => panic!("{e}"),
        };
        for n in [100, 200, 800] {
            let (a, b) = (image(n, 0.0), image(n, 0.3));
            group.bench_with_input(BenchmarkId::new(net.name(), n), &n, |bch, _| {
                bch.iter(|| lpips.distance(&a, &b).expect("distance"))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
