//! Times the motion-aware refresh outside criterion (for `perf stat`, which reports
//! the CPU time of this process alone on a shared machine).
//!
//! `cargo run -p maaf-filter --release --example refresh_timing -- [dnerf|video] [N] [reps]`

use std::time::Instant;

use maaf_filter::{FilterConfig, MotionCurves, ObservationTable};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let kind = args.get(1).map_or("dnerf", String::as_str);
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(50_000);
    let reps: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3);
    let (times, cams): (Vec<f32>, usize) = match kind {
        "video" => (
            (0..300)
                .flat_map(|i| std::iter::repeat_n(i as f32 / 299.0, 20))
                .collect(),
            20,
        ),
        _ => ((0..150).map(|i| i as f32 / 149.0).collect(), 1),
    };
    let table = synthetic(&times, cams, n);
    let cfg = FilterConfig::default();
    for _ in 0..reps {
        let t0 = Instant::now();
        let curves = MotionCurves::refresh(&table, &cfg).expect("refresh");
        println!(
            "{kind} N={n} J={}: refresh {:.3} s ({} B/Gaussian state)",
            times.len(),
            t0.elapsed().as_secs_f64(),
            curves.bytes_per_gaussian()
        );
    }
}

/// Deterministic synthetic observations: half static (per-camera constant f/d),
/// half moving, 10% empty slots (a cheap hash instead of an RNG).
fn synthetic(times: &[f32], cams: usize, n: usize) -> ObservationTable {
    let hash = |a: usize, b: usize| {
        let mut h = (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (b as u64);
        h ^= h >> 31;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 29;
        (h >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut table = ObservationTable::new(times.to_vec(), n);
    for g in 0..n {
        let base = 50.0 + 750.0 * hash(g, 0);
        let amp = if g % 2 == 0 {
            0.0
        } else {
            0.1 + 0.7 * hash(g, 1)
        };
        let phase = std::f32::consts::TAU * hash(g, 2);
        let row = table.row_mut(g);
        for (f, x) in row.iter_mut().enumerate() {
            if hash(g, 10 + f) < 0.1 {
                continue;
            }
            let cam = 0.7 + 0.3 * hash(g, 100_000 + f % cams);
            *x = base * cam * (1.0 - amp * (0.5 + 0.5 * (5.0 * times[f] + phase).sin()));
        }
    }
    table
}
