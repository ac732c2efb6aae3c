//! How stale observations change nu(t): the incremental recorder (one training
//! frame per iteration, values kept from whenever that frame was last trained on)
//! against a full observation pass with the current deformation, on a synthetic
//! scene whose motion is still being learnt (amplitude `1 - exp(-it / tau)`).
//!
//! `cargo run -p maaf-filter --release --example stale_observations [-- EXPORT_DIR]`
//!
//! With `EXPORT_DIR`, also writes `dnerf_fd.json` / `dnerf_fd.csv`: observations and
//! nu(t) of two static and two moving Gaussians at the last refresh (the paper's
//! f/d-over-time figure).

use std::path::Path;

use maaf_filter::{
    AnalysisExport, CameraTime, FilterConfig, MotionCurves, ObservationTable, static_nu,
};
use maaf_splat::Camera;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// Camera at `pos` looking at the origin (OpenCV axes, world z up), `size` px square.
fn look_at(pos: [f64; 3], focal: f64, size: u32) -> Camera {
    let norm = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let f = norm([-pos[0], -pos[1], -pos[2]]);
    let r = norm(cross(f, [0.0, 0.0, 1.0]));
    let d = cross(f, r);
    let mut w2c = [[0.0; 4]; 4];
    for (i, axis) in [r, d, f].iter().enumerate() {
        w2c[i][..3].copy_from_slice(axis);
        w2c[i][3] = -(axis[0] * pos[0] + axis[1] * pos[1] + axis[2] * pos[2]);
    }
    w2c[3][3] = 1.0;
    let c = size as f64 / 2.0;
    Camera::new(size, size, focal, focal, c, c, w2c).expect("camera")
}

struct Scene {
    canonical: Vec<[f32; 3]>,
    /// Per Gaussian: motion direction * amplitude (zero for static ones) and phase.
    motion: Vec<([f32; 3], f32)>,
    tau: f32,
}

impl Scene {
    fn new(n: usize, rng: &mut Pcg64) -> Scene {
        let canonical = (0..n)
            .map(|_| {
                [
                    rng.random_range(-1.0f32..1.0),
                    rng.random_range(-1.0f32..1.0),
                    rng.random_range(-1.0f32..1.0),
                ]
            })
            .collect();
        let motion = (0..n)
            .map(|i| {
                if i % 2 == 0 {
                    ([0.0; 3], 0.0)
                } else {
                    let a = rng.random_range(0.5f32..1.5);
                    let dir = [
                        rng.random_range(-1.0f32..1.0),
                        rng.random_range(-1.0f32..1.0),
                        rng.random_range(-1.0f32..1.0),
                    ];
                    let l = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
                    (
                        [a * dir[0] / l, a * dir[1] / l, a * dir[2] / l],
                        rng.random_range(0.0f32..std::f32::consts::TAU),
                    )
                }
            })
            .collect();
        Scene {
            canonical,
            motion,
            tau: 2000.0,
        }
    }

    /// Deformed centres at time `t` after `it` training iterations.
    fn centres(&self, t: f32, it: usize) -> Vec<[f32; 3]> {
        let learnt = 1.0 - (-(it as f32) / self.tau).exp();
        self.canonical
            .iter()
            .zip(&self.motion)
            .map(|(c, (m, ph))| {
                let s = learnt * (std::f32::consts::TAU * t + ph).sin();
                [c[0] + s * m[0], c[1] + s * m[1], c[2] + s * m[2]]
            })
            .collect()
    }
}

struct Stats {
    same_code: f64,
    mean_rel: f64,
    p95_rel: f64,
    max_rel: f64,
    empty_slots: f64,
}

fn compare(rec: &MotionCurves, full: &MotionCurves, table: &ObservationTable) -> Stats {
    let mut rel = Vec::new();
    let mut same = 0usize;
    for n in 0..full.x_max().len() {
        for s in 0..full.grid_t() {
            let (a, b) = (rec.nu(n, s), full.nu(n, s));
            rel.push(((a - b) / b).abs() as f64);
            same += usize::from(rec.codes(n)[s] == full.codes(n)[s]);
        }
    }
    rel.sort_by(f64::total_cmp);
    let slots = table.num_frames() * full.x_max().len();
    let empty = (0..full.x_max().len())
        .map(|n| table.row(n).iter().filter(|&&x| x == 0.0).count())
        .sum::<usize>();
    Stats {
        same_code: same as f64 / rel.len() as f64,
        mean_rel: rel.iter().sum::<f64>() / rel.len() as f64,
        p95_rel: rel[rel.len() * 95 / 100],
        max_rel: rel[rel.len() - 1],
        empty_slots: empty as f64 / slots as f64,
    }
}

fn run(
    name: &str,
    times: usize,
    cams_per_time: usize,
    n: usize,
    last: usize,
    export: Option<&Path>,
) {
    let cfg = FilterConfig::default();
    let mut rng = Pcg64::seed_from_u64(42);
    let scene = Scene::new(n, &mut rng);
    // Cameras on a ring of radius 4 (height varies), focal 400 px, 400 x 400.
    let num_cams = if cams_per_time == 1 {
        times
    } else {
        cams_per_time
    };
    let cams: Vec<Camera> = (0..num_cams)
        .map(|_| {
            let a = rng.random_range(0.0f64..std::f64::consts::TAU);
            let h = rng.random_range(-1.0f64..2.0);
            let r = rng.random_range(3.5f64..4.5);
            look_at([r * a.cos(), r * a.sin(), h], 400.0, 400)
        })
        .collect();
    let frames: Vec<CameraTime> = (0..times * cams_per_time)
        .map(|i| CameraTime {
            camera: if cams_per_time == 1 {
                i
            } else {
                i % cams_per_time
            },
            time: (i / cams_per_time) as f32 / (times - 1) as f32,
        })
        .collect();
    let mut recorder = ObservationTable::for_frames(&frames, n);
    let mut order: Vec<usize> = Vec::new();
    println!(
        "\n{name}: N = {n}, {} frames ({times} times x {cams_per_time} cameras), tau = {}",
        frames.len(),
        scene.tau
    );
    println!("iter  empty-slots  same-argmax  mean|dnu|/nu  p95       max");
    for it in 1..=last {
        // Epoch-shuffled frame order, as the trainer's viewpoint stack.
        if order.is_empty() {
            order = (0..frames.len()).collect();
            order.shuffle(&mut rng);
        }
        let f = order.pop().expect("non-empty");
        let fr = frames[f];
        recorder
            .record_centres(f, &cams[fr.camera], &scene.centres(fr.time, it), &cfg)
            .expect("record");
        if cfg.refresh.due(it as u64, last as u64 + 1, false) && (it == 600 || it % 1000 == 0) {
            let mut full = ObservationTable::for_frames(&frames, n);
            full.observe_all(&frames, &cams, &cfg, |t| scene.centres(t, it))
                .expect("observe");
            let a = MotionCurves::refresh(&recorder, &cfg).expect("refresh");
            let b = MotionCurves::refresh(&full, &cfg).expect("refresh");
            let st = compare(&a, &b, &recorder);
            println!(
                "{it:5}  {:10.1}%  {:10.1}%  {:11.2}%  {:7.2}%  {:7.1}%",
                100.0 * st.empty_slots,
                100.0 * st.same_code,
                100.0 * st.mean_rel,
                100.0 * st.p95_rel,
                100.0 * st.max_rel
            );
            if let (Some(dir), true) = (export, it == last) {
                // Even indices are static, odd ones move (Scene::new).
                let chosen: Vec<(usize, String)> =
                    [(0, "static"), (2, "static"), (1, "moving"), (3, "moving")]
                        .iter()
                        .map(|&(i, l)| (i, l.to_string()))
                        .collect();
                let nu_static = static_nu(&scene.canonical, &cams, &cfg).expect("visible");
                let ex =
                    AnalysisExport::collect(&full, &b, cfg.estimator, &chosen, Some(&nu_static))
                        .expect("export");
                ex.write_json(&dir.join("dnerf_fd.json"))
                    .expect("write json");
                ex.write_csv(&dir.join("dnerf_fd.csv")).expect("write csv");
                println!("wrote {}/dnerf_fd.{{json,csv}}", dir.display());
            }
        }
    }
}

fn main() {
    let export = std::env::args().nth(1);
    let export = export.as_deref().map(Path::new);
    run("D-NeRF layout", 150, 1, 2000, 5000, export);
    run("multi-view video layout", 300, 20, 300, 5000, None);
}
