//! Seeded test scenes shared by the splat integration tests.
#![allow(dead_code)]

use maaf_autodiff::{Float, Tensor};
use maaf_splat::Camera;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// Activated parameters of a scene.
#[derive(Clone, Debug)]
pub struct Scene<T> {
    pub means: Tensor<T>,
    pub scales: Tensor<T>,
    pub quats: Tensor<T>,
    pub opacity: Tensor<T>,
    pub sh: Tensor<T>,
}

impl<T: Float> Scene<T> {
    pub fn n(&self) -> usize {
        self.opacity.len()
    }

    pub fn tensors(&self) -> Vec<Tensor<T>> {
        vec![
            self.means.clone(),
            self.scales.clone(),
            self.quats.clone(),
            self.opacity.clone(),
            self.sh.clone(),
        ]
    }

    pub fn cast<U: Float>(&self) -> Scene<U> {
        Scene {
            means: self.means.cast(),
            scales: self.scales.cast(),
            quats: self.quats.cast(),
            opacity: self.opacity.cast(),
            sh: self.sh.cast(),
        }
    }

    /// Appends another scene's Gaussians.
    pub fn extend(&self, other: &Scene<T>) -> Scene<T> {
        let cat = |a: &Tensor<T>, b: &Tensor<T>| {
            let mut shape = a.shape().to_vec();
            shape[0] += b.shape()[0];
            let mut d = a.data().to_vec();
            d.extend_from_slice(b.data());
            Tensor::from_vec(d, &shape)
        };
        Scene {
            means: cat(&self.means, &other.means),
            scales: cat(&self.scales, &other.scales),
            quats: cat(&self.quats, &other.quats),
            opacity: cat(&self.opacity, &other.opacity),
            sh: cat(&self.sh, &other.sh),
        }
    }
}

/// A camera at `(0, 0, -4)` looking down +z (OpenCV axes), slightly rotated so that
/// the world-to-camera matrix is not trivial.
pub fn camera(width: u32, height: u32) -> Camera {
    let (a, b) = (0.1f64, -0.07f64);
    // rotation about y by a, then about x by b
    let (ca, sa, cb, sb) = (a.cos(), a.sin(), b.cos(), b.sin());
    let ry = [[ca, 0.0, sa], [0.0, 1.0, 0.0], [-sa, 0.0, ca]];
    let rx = [[1.0, 0.0, 0.0], [0.0, cb, -sb], [0.0, sb, cb]];
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = (0..3).map(|k| rx[i][k] * ry[k][j]).sum();
        }
    }
    let t = [0.05, -0.03, 4.0];
    let mut m = [[0.0; 4]; 4];
    for i in 0..3 {
        m[i][..3].copy_from_slice(&r[i]);
        m[i][3] = t[i];
    }
    m[3][3] = 1.0;
    let f = 1.1 * width as f64;
    Camera::new(
        width,
        height,
        f,
        f * 1.05,
        width as f64 / 2.0 + 0.7,
        height as f64 / 2.0 - 0.4,
        m,
    )
    .expect("valid camera")
}

/// Random Gaussians in front of [`camera`], `degree` SH, opacity in `[lo, hi]`.
pub fn random_scene<T: Float>(n: usize, degree: usize, seed: u64) -> Scene<T> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let k = (degree + 1) * (degree + 1);
    let mut means = Vec::new();
    let mut scales = Vec::new();
    let mut quats = Vec::new();
    let mut opacity = Vec::new();
    let mut sh = Vec::new();
    for _ in 0..n {
        means.extend([
            rng.random_range(-1.2..1.2),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.5),
        ]);
        for _ in 0..3 {
            scales.push(rng.random_range(0.03..0.25));
        }
        for _ in 0..4 {
            quats.push(rng.random_range(-1.0..1.0));
        }
        opacity.push(rng.random_range(0.2..0.9));
        for j in 0..k {
            for _ in 0..3 {
                let amp = if j == 0 { 1.0 } else { 0.3 };
                sh.push(rng.random_range(-amp..amp));
            }
        }
    }
    Scene {
        means: Tensor::from_f64(&means, &[n, 3]),
        scales: Tensor::from_f64(&scales, &[n, 3]),
        quats: Tensor::from_f64(&quats, &[n, 4]),
        opacity: Tensor::from_f64(&opacity, &[n]),
        sh: Tensor::from_f64(&sh, &[n, k, 3]),
    }
}

/// Hard cases: behind the camera, straddling the near plane, very thin, very large,
/// zero opacity, off-screen, at a tile corner.
pub fn hard_cases<T: Float>(degree: usize) -> Scene<T> {
    let k = (degree + 1) * (degree + 1);
    // (mean, scales, quat, opacity)
    #[allow(clippy::type_complexity)]
    let rows: Vec<([f64; 3], [f64; 3], [f64; 4], f64)> = vec![
        ([0.0, 0.0, -6.0], [0.3, 0.3, 0.3], [1.0, 0.0, 0.0, 0.0], 0.8), // behind camera
        ([0.3, 0.1, -3.7], [0.5, 0.5, 0.5], [1.0, 0.2, 0.0, 0.0], 0.7), // near plane, straddles
        (
            [0.2, -0.2, 0.0],
            [1e-3, 0.4, 0.3],
            [0.9, 0.1, 0.3, 0.0],
            0.9,
        ), // very thin
        (
            [-0.1, 0.1, 1.0],
            [1e-3, 1e-3, 0.5],
            [0.5, 0.5, 0.5, 0.5],
            0.9,
        ), // needle
        ([0.0, 0.0, 3.0], [2.5, 2.0, 1.5], [1.0, 0.0, 0.2, 0.1], 0.3),  // very large
        ([0.1, 0.0, 0.5], [0.3, 0.3, 0.3], [1.0, 0.0, 0.0, 0.0], 0.0),  // zero opacity
        ([40.0, 0.0, 0.0], [0.3, 0.3, 0.3], [1.0, 0.0, 0.0, 0.0], 0.8), // off-screen
        (
            [-2.0, -1.5, 0.0],
            [0.2, 0.1, 0.1],
            [1.0, 0.0, 0.0, 0.3],
            0.9,
        ), // partly off-screen
        (
            [1e-4, 1e-4, 2e-4],
            [1e-4, 1e-4, 1e-4],
            [1.0, 0.0, 0.0, 0.0],
            0.9,
        ), // sub-pixel
    ];
    let n = rows.len();
    let mut sh = Vec::new();
    for i in 0..n {
        for j in 0..k {
            for c in 0..3 {
                sh.push(if j == 0 {
                    0.3 * (c as f64 - 1.0) + 0.1 * i as f64
                } else {
                    0.05
                });
            }
        }
    }
    Scene {
        means: Tensor::from_f64(&rows.iter().flat_map(|r| r.0).collect::<Vec<_>>(), &[n, 3]),
        scales: Tensor::from_f64(&rows.iter().flat_map(|r| r.1).collect::<Vec<_>>(), &[n, 3]),
        quats: Tensor::from_f64(&rows.iter().flat_map(|r| r.2).collect::<Vec<_>>(), &[n, 4]),
        opacity: Tensor::from_f64(&rows.iter().map(|r| r.3).collect::<Vec<_>>(), &[n]),
        sh: Tensor::from_f64(&sh, &[n, k, 3]),
    }
}
