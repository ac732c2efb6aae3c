//! Rendering benchmarks: forward and forward+backward of the full pipeline at 200x200
//! and 800x800 with 10k / 50k / 200k Gaussians shaped like a trained D-NeRF object
//! (a unit-radius shell of flat splats seen from distance 4 with D-NeRF's field of
//! view), a breakdown into projection / binning+sort / blend, and a blend-loop
//! microbenchmark (one 16x16 tile against 2000 Gaussians) for the ratio.
//!
//! Throughput is reported as tile-pixel-Gaussian pairs (each Gaussian listed in a
//! tile counts once per tile pixel; pixels that stop at T < 1e-4 skip some of them).
//!
//! The benchmark allocates through mimalloc, as the `maaf` binary does: glibc's
//! malloc returns each frame's freed buffers to the kernel and faults them in again.
//!
//! Run (short, the machine is shared):
//! `cargo bench -p maaf-splat --bench rasterize -- --warm-up-time 1 --measurement-time 3`
//! Filter with a name, e.g. `-- 'fwd\+bwd 200x200 50k'`.

// Reading a tape value borrows the tape, so results are bound before being returned.
#![allow(clippy::let_and_return)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use maaf_autodiff::{Tape, Tensor};
use maaf_splat::binning::bin_gaussians;
use maaf_splat::cov3d::quat_scale_to_cov;
use maaf_splat::project::project_ewa;
use maaf_splat::sh::sh_color;
use maaf_splat::{Camera, GaussianVars, RenderSettings, render};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

struct Scene {
    means: Tensor<f32>,
    scales: Tensor<f32>,
    quats: Tensor<f32>,
    opacity: Tensor<f32>,
    sh: Tensor<f32>,
}

/// `n` flat splats on a noisy unit shell (85 %) and inside it (15 %), sized so that
/// they tile the surface, SH degree 3.
fn object(n: usize, seed: u64) -> Scene {
    let mut rng = Pcg64::seed_from_u64(seed);
    let base = (4.0 * std::f64::consts::PI / n as f64).sqrt() * 0.6;
    let mut v = |lo: f64, hi: f64| rng.random_range(lo..hi);
    let (mut m, mut s, mut q, mut o, mut sh) = (vec![], vec![], vec![], vec![], vec![]);
    for _ in 0..n {
        let (z, phi) = (v(-1.0, 1.0), v(0.0, std::f64::consts::TAU));
        let rad = if v(0.0, 1.0) < 0.85 {
            1.0 + 0.03 * v(-1.0, 1.0)
        } else {
            v(0.2, 0.95)
        };
        let r = (1.0 - z * z).sqrt();
        m.extend([rad * r * phi.cos(), rad * r * phi.sin(), rad * z]);
        let k = v(-0.7, 0.7).exp();
        s.extend([base * k, base * k * v(0.5, 1.5), base * k * 0.15]);
        q.extend([v(-1.0, 1.0), v(-1.0, 1.0), v(-1.0, 1.0), v(-1.0, 1.0)]);
        o.push(v(0.05, 1.0));
        for j in 0..16 {
            for _ in 0..3 {
                sh.push(if j == 0 { v(-1.0, 1.5) } else { v(-0.1, 0.1) });
            }
        }
    }
    Scene {
        means: Tensor::from_f64(&m, &[n, 3]),
        scales: Tensor::from_f64(&s, &[n, 3]),
        quats: Tensor::from_f64(&q, &[n, 4]),
        opacity: Tensor::from_f64(&o, &[n]),
        sh: Tensor::from_f64(&sh, &[n, 16, 3]),
    }
}

/// D-NeRF-like camera: distance 4, `camera_angle_x = 0.6911`.
fn camera(size: u32) -> Camera {
    let f = 0.5 * size as f64 / (0.6911f64 / 2.0).tan();
    let mut w2c = [[0.0; 4]; 4];
    for (i, row) in w2c.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    w2c[2][3] = 4.0;
    Camera::new(size, size, f, f, size as f64 / 2.0, size as f64 / 2.0, w2c).expect("camera")
}

/// One render; with `backward` also its backward pass, and with `abs` that pass also
/// sums AbsGS's absolute per-pixel gradients (`densify.gradient` `abs`).
fn run(scene: &Scene, cam: &Camera, backward: bool, abs: bool) -> f32 {
    let t = Tape::<f32>::new();
    let mk = |x: &Tensor<f32>| {
        if backward {
            t.var(x.clone())
        } else {
            t.constant(x.clone())
        }
    };
    let g = GaussianVars {
        means: mk(&scene.means),
        scales: mk(&scene.scales),
        quats: mk(&scene.quats),
        opacity: mk(&scene.opacity),
        sh: mk(&scene.sh),
    };
    let out = render(&t, &g, cam, &RenderSettings::default());
    if abs {
        out.abs_means2d.request();
    }
    if backward {
        let loss = out.image.mean();
        let grads = t.backward(loss).expect("finite");
        grads.wrt(g.means).map_or(0.0, |x| x.data()[0])
    } else {
        out.image.value().data()[0]
    }
}

/// Tile-pixel-Gaussian pairs of a frame (the blend loop's work without early stop).
fn pairs(scene: &Scene, cam: &Camera) -> u64 {
    let t = Tape::<f32>::new();
    let cov = quat_scale_to_cov(
        t.constant(scene.quats.clone()),
        t.constant(scene.scales.clone()),
    );
    let p = project_ewa(
        t.constant(scene.means.clone()),
        cov,
        t.constant(scene.opacity.clone()),
        cam,
        maaf_splat::Filter2d::Mip,
        0.2,
    );
    let bins = bin_gaussians(
        p.means2d.value().data(),
        p.conics.value().data(),
        p.opacity.value().data(),
        p.radii.value().data(),
        p.depths.value().data(),
        cam.width,
        cam.height,
    );
    bins.intersections() as u64 * 256
}

fn full(c: &mut Criterion) {
    let mut group = c.benchmark_group("render");
    group.sample_size(10);
    for size in [200u32, 800] {
        let cam = camera(size);
        for n in [10_000usize, 50_000, 200_000] {
            let scene = object(n, 1);
            let label = format!("{size}x{size} {}k", n / 1000);
            group.throughput(Throughput::Elements(pairs(&scene, &cam)));
            group.bench_function(format!("fwd {label}"), |b| {
                b.iter(|| run(&scene, &cam, false, false))
            });
            group.bench_function(format!("fwd+bwd {label}"), |b| {
                b.iter(|| run(&scene, &cam, true, false))
            });
            group.bench_function(format!("fwd+bwd+abs {label}"), |b| {
                b.iter(|| run(&scene, &cam, true, true))
            });
        }
    }
    group.finish();
}

/// Where the forward time goes: projection (cov + EWA + SH), binning + sort, and
/// the whole forward (blend = forward - projection - binning).
fn breakdown(c: &mut Criterion) {
    let mut group = c.benchmark_group("breakdown");
    group.sample_size(10);
    let cam = camera(200);
    let scene = object(50_000, 1);
    group.bench_function("project+sh 200x200 50k", |b| {
        b.iter(|| {
            let t = Tape::<f32>::new();
            let cov = quat_scale_to_cov(
                t.constant(scene.quats.clone()),
                t.constant(scene.scales.clone()),
            );
            let means = t.constant(scene.means.clone());
            let p = project_ewa(
                means,
                cov,
                t.constant(scene.opacity.clone()),
                &cam,
                maaf_splat::Filter2d::Mip,
                0.2,
            );
            let col = sh_color(means, t.constant(scene.sh.clone()), [0.0, 0.0, -4.0], 3);
            let x = p.means2d.value().data()[0] + col.value().data()[0];
            x
        })
    });
    let t = Tape::<f32>::new();
    let cov = quat_scale_to_cov(
        t.constant(scene.quats.clone()),
        t.constant(scene.scales.clone()),
    );
    let p = project_ewa(
        t.constant(scene.means.clone()),
        cov,
        t.constant(scene.opacity.clone()),
        &cam,
        maaf_splat::Filter2d::Mip,
        0.2,
    );
    let (m2, con, op, radii, depths) = (
        p.means2d.value().clone(),
        p.conics.value().clone(),
        p.opacity.value().clone(),
        p.radii.value().clone(),
        p.depths.value().clone(),
    );
    group.bench_function("bin+sort 200x200 50k", |b| {
        b.iter(|| {
            bin_gaussians(
                m2.data(),
                con.data(),
                op.data(),
                radii.data(),
                depths.data(),
                200,
                200,
            )
            .intersections()
        })
    });
    group.finish();
}

/// One 16x16 tile against 2000 low-opacity Gaussians covering it (no early stop):
/// the blend loop alone, in pixel-Gaussian pairs.
fn blend_micro(c: &mut Criterion) {
    let mut group = c.benchmark_group("blend_micro");
    group.sample_size(10);
    let n = 2000;
    let mut rng = Pcg64::seed_from_u64(3);
    let mut m2 = Vec::new();
    let mut con = Vec::new();
    for _ in 0..n {
        m2.extend([
            rng.random_range(4.0..12.0f32),
            rng.random_range(4.0..12.0f32),
        ]);
        let s = rng.random_range(0.02..0.06f32);
        con.extend([s, rng.random_range(-0.005..0.005f32), s]);
    }
    let inputs = [
        Tensor::from_vec(m2, &[n, 2]),
        Tensor::from_vec(con, &[n, 3]),
        Tensor::full(&[n, 3], 0.5f32),
        Tensor::full(&[n], 0.004f32),
        Tensor::from_vec((0..n).map(|i| 1.0 + i as f32 * 1e-3).collect(), &[n]),
        Tensor::full(&[n], 12.0f32),
    ];
    group.throughput(Throughput::Elements((n * 256) as u64));
    group.bench_function("fwd 16x16 x 2000", |b| {
        b.iter(|| {
            let t = Tape::<f32>::new();
            let v: Vec<_> = inputs.iter().map(|x| t.constant(x.clone())).collect();
            let r = maaf_splat::rasterize::rasterize(
                v[0],
                v[1],
                v[2],
                v[3],
                v[4],
                v[5],
                16,
                16,
                [0.0; 3],
                maaf_splat::AlphaCutoff::Hard,
            );
            let x = r.image.value().data()[0];
            x
        })
    });
    group.finish();
}

criterion_group!(benches, full, breakdown, blend_micro);
criterion_main!(benches);
