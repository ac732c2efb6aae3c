//! Initial values of a representation: the point cloud it starts from, the
//! 3DGS nearest-neighbour scale, the colour-to-SH-DC conversion, and the canonical
//! 3DGS tensors built from them.

use maaf_autodiff::scalar::logit;
use maaf_autodiff::{Float, Tensor};
use maaf_data::PointCloud;
use maaf_splat::sh::SH_C0;

use crate::knn::knn;

/// The canonical 3DGS tensors a representation starts from (3DGS `create_from_pcd`,
/// as SaRO-GS and Deformable-3DGS do it).
#[derive(Clone, Debug, PartialEq)]
pub struct InitialGaussians<T: Float> {
    /// Centres = the points \[N,3].
    pub xyz: Tensor<T>,
    /// `ln sqrt(mean squared distance to the 3 nearest neighbours)`, clamped to
    /// \[-10, 1], on every axis \[N,3].
    pub log_scale: Tensor<T>,
    /// Identity rotations (1, 0, 0, 0) \[N,4].
    pub rotation: Tensor<T>,
    /// Opacity 0.1 as a logit \[N].
    pub opacity: Tensor<T>,
    /// SH DC from the colours \[N,1,3].
    pub sh_dc: Tensor<T>,
    /// Zero higher bands \[N,K-1,3].
    pub sh_rest: Tensor<T>,
}

impl<T: Float> InitialGaussians<T> {
    /// The tensors for `cloud` with `sh_coeffs` = K coefficients per colour channel.
    pub fn from_cloud(cloud: &PointCloud, sh_coeffs: usize) -> Self {
        let n = cloud.len();
        let of = |v: Vec<f64>, shape: &[usize]| -> Tensor<T> {
            Tensor::from_vec(v.into_iter().map(T::of).collect(), shape)
        };
        let log_scale = knn_mean_sq_dist(&cloud.points, 3)
            .iter()
            .flat_map(|&d| [(d.sqrt().ln()).clamp(-10.0, 1.0); 3])
            .collect();
        let sh_dc = cloud.colours.iter().flatten().map(|&c| rgb_to_sh_dc(c));
        InitialGaussians {
            xyz: of(cloud.points.concat(), &[n, 3]),
            log_scale: of(log_scale, &[n, 3]),
            rotation: of((0..n).flat_map(|_| [1.0, 0.0, 0.0, 0.0]).collect(), &[n, 4]),
            opacity: Tensor::full(&[n], logit(T::of(0.1))),
            sh_dc: of(sh_dc.collect(), &[n, 1, 3]),
            sh_rest: Tensor::zeros(&[n, sh_coeffs - 1, 3]),
        }
    }
}

/// DC coefficient that renders as colour `c`: `(c - 0.5) / C0` (3DGS `RGB2SH`).
pub fn rgb_to_sh_dc(c: f64) -> f64 {
    (c - 0.5) / SH_C0
}

/// Mean squared distance from each point to its `k` nearest other points (3DGS
/// `distCUDA2` uses k = 3), clamped below at 1e-7 as 3DGS does; exact ([`knn`]).
pub fn knn_mean_sq_dist(points: &[[f64; 3]], k: usize) -> Vec<f64> {
    let near = knn(points, k);
    if near.k == 0 {
        return vec![1e-7; points.len()];
    }
    near.sq_dist
        .chunks_exact(near.k)
        .map(|row| (row.iter().sum::<f64>() / near.k as f64).max(1e-7))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subsample_keeps_distinct_points_in_order_with_their_times() {
        let mut cloud = PointCloud::random_in_box(50, -1.0, 1.0, 2);
        cloud.times = Some((0..50).map(|i| i as f64 / 50.0).collect());
        let sub = cloud.subsample(20, 9);
        assert_eq!(sub.len(), 20);
        let times = sub.times.clone().expect("times");
        // Times are the original indices / 50: strictly increasing means distinct
        // points kept in order, and each point kept its colour and time.
        assert!(times.windows(2).all(|w| w[0] < w[1]));
        for (k, t) in times.iter().enumerate() {
            let i = (t * 50.0).round() as usize;
            assert_eq!(sub.points[k], cloud.points[i]);
            assert_eq!(sub.colours[k], cloud.colours[i]);
        }
        assert_eq!(sub, cloud.subsample(20, 9), "seeded");
        assert_ne!(sub, cloud.subsample(20, 10));
        assert_eq!(cloud.subsample(50, 9), cloud);
    }

    #[test]
    fn sh_dc_inverts_the_renderer_colour() {
        for c in [0.0, 0.3, 1.0] {
            assert!((rgb_to_sh_dc(c) * SH_C0 + 0.5 - c).abs() < 1e-15);
        }
    }
}
