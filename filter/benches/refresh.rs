//! Criterion bench of the motion-aware filter refresh: N = 50k Gaussians
//! with J = 150 observations (D-NeRF: 150 training frames, one camera per time) and
//! J = 300 x 20 (multi-view video: 300 times x 20 cameras). The video case is run
//! at N = 5k (its observation table alone is 24 kB per Gaussian, 1.2 GB at 50k, and
//! one refresh takes seconds): the work is independent per Gaussian, so the 50k
//! time is 10x (the `refresh_timing` example measures it directly). Prints the
//! memory per Gaussian of the observation table and of the stored curves.
//!
//! `CARGO_TARGET_DIR=/work/target-filter cargo bench -p maaf-filter --bench refresh -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use maaf_filter::{FilterConfig, MotionCurves, ObservationTable};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

const N: usize = 50_000;
const N_VIDEO: usize = 5_000;

/// Observations of `N` synthetic Gaussians: half static (constant f/d per camera),
/// half moving (f/d oscillating with time), 10% of slots empty (not visible).
fn synthetic(times: Vec<f32>, cameras: usize, rows: usize) -> ObservationTable {
    let mut rng = Pcg64::seed_from_u64(1);
    let mut table = ObservationTable::new(times.clone(), rows);
    for n in 0..rows {
        let base = rng.random_range(50.0f32..800.0);
        let amp = if n % 2 == 0 {
            0.0
        } else {
            rng.random_range(0.1f32..0.8)
        };
        let phase = rng.random_range(0.0f32..std::f32::consts::TAU);
        let cam_scale: Vec<f32> = (0..cameras)
            .map(|_| rng.random_range(0.7f32..1.0))
            .collect();
        let row = table.row_mut(n);
        for (f, x) in row.iter_mut().enumerate() {
            if rng.random_range(0.0f32..1.0) < 0.1 {
                continue;
            }
            let t = times[f];
            *x =
                base * cam_scale[f % cameras] * (1.0 - amp * (0.5 + 0.5 * (5.0 * t + phase).sin()));
        }
    }
    table
}

fn refresh(c: &mut Criterion) {
    let cfg = FilterConfig::default();
    let dnerf_times: Vec<f32> = (0..150).map(|i| i as f32 / 149.0).collect();
    let video_times: Vec<f32> = (0..300)
        .flat_map(|i| std::iter::repeat_n(i as f32 / 299.0, 20))
        .collect();
    let mut group = c.benchmark_group("motion_refresh");
    group.sample_size(10);
    for (name, times, cameras, rows) in [
        ("dnerf_n50k_j150", dnerf_times, 1, N),
        ("video_n5k_j300x20", video_times, 20, N_VIDEO),
    ] {
        let table = synthetic(times, cameras, rows);
        let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
        eprintln!(
            "{name}: observation table {} B/Gaussian, curves {} B/Gaussian (paper density: {} B/Gaussian)",
            table.bytes() / rows,
            curves.bytes_per_gaussian(),
            4 * cfg.grid_x * cfg.grid_t
        );
        group.bench_function(name, |b| {
            b.iter(|| MotionCurves::refresh(black_box(&table), &cfg).expect("refresh"))
        });
    }
    group.finish();
}

criterion_group!(benches, refresh);
criterion_main!(benches);
