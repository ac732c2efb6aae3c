//! The rigid motion that best maps one point set onto another (least squares), by
//! Horn's quaternion method (Horn 1987, "Closed-form solution of absolute orientation
//! using unit quaternions"): the rotation is the eigenvector of the largest eigenvalue
//! of a symmetric 4x4 matrix built from the cross-covariance. It gives the same
//! rotation as the SVD (Kabsch) fit GroupFlow uses, without a 3x3 SVD.

use glam::{DQuat, DVec3};

/// The rotation `R` minimising `sum_i |R (a_i - mean(a)) - (b_i - mean(b))|^2`, as a unit
/// quaternion. `a` and `b` are paired points; fewer than two points, or points that
/// do not fix a rotation (all equal), give the identity.
pub fn best_rotation(a: &[DVec3], b: &[DVec3]) -> DQuat {
    assert_eq!(a.len(), b.len(), "best_rotation: unpaired points");
    if a.len() < 2 {
        return DQuat::IDENTITY;
    }
    let n = a.len() as f64;
    let ca = a.iter().copied().sum::<DVec3>() / n;
    let cb = b.iter().copied().sum::<DVec3>() / n;
    // s[i][j] = sum (a - ca)_i (b - cb)_j
    let mut s = [[0.0f64; 3]; 3];
    for (p, q) in a.iter().zip(b) {
        let (p, q) = ((*p - ca).to_array(), (*q - cb).to_array());
        for (row, pi) in s.iter_mut().zip(p) {
            for (v, qj) in row.iter_mut().zip(q) {
                *v += pi * qj;
            }
        }
    }
    let scale: f64 = s.iter().flatten().map(|v| v.abs()).sum();
    if scale <= f64::MIN_POSITIVE {
        return DQuat::IDENTITY;
    }
    let [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = s;
    let m = [
        [xx + yy + zz, yz - zy, zx - xz, xy - yx],
        [yz - zy, xx - yy - zz, xy + yx, zx + xz],
        [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
        [xy - yx, zx + xz, yz + zy, -xx - yy + zz],
    ];
    let (values, vectors) = symmetric_eigen4(m);
    let best = (0..4)
        .max_by(|&i, &j| values[i].total_cmp(&values[j]))
        .unwrap_or(0);
    let [w, x, y, z] = [0, 1, 2, 3].map(|r| vectors[r][best]);
    DQuat::from_xyzw(x, y, z, w).normalize()
}

/// Eigenvalues and eigenvectors (as the columns of the second result) of a symmetric
/// 4x4 matrix by cyclic Jacobi rotations (Golub & Van Loan, Alg. 8.4.3), to full f64
/// precision.
fn symmetric_eigen4(mut a: [[f64; 4]; 4]) -> ([f64; 4], [[f64; 4]; 4]) {
    let mut v = [[0.0; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _sweep in 0..64 {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        let total: f64 = a.iter().flatten().map(|x| x * x).sum();
        if off <= 1e-30 * total {
            break;
        }
        for p in 0..3 {
            for q in p + 1..4 {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                // A <- J^T A J with J the rotation in the (p, q) plane.
                for row in a.iter_mut() {
                    let (akp, akq) = (row[p], row[q]);
                    row[p] = c * akp - s * akq;
                    row[q] = s * akp + c * akq;
                }
                let (rp, rq) = (a[p], a[q]);
                for k in 0..4 {
                    a[p][k] = c * rp[k] - s * rq[k];
                    a[q][k] = s * rp[k] + c * rq[k];
                }
                for row in v.iter_mut() {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2], a[3][3]], v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_points(n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = Pcg64::seed_from_u64(seed);
        let u = |rng: &mut Pcg64| rng.random_range(-1.0..1.0);
        (0..n)
            .map(|_| DVec3::new(u(&mut rng), u(&mut rng), u(&mut rng)))
            .collect()
    }

    #[test]
    fn recovers_a_known_rigid_motion() {
        let a = random_points(40, 1);
        for (k, angle) in [0.1, 1.3, 2.9, 3.1].into_iter().enumerate() {
            let axis = DVec3::new(0.3, -0.8, 0.5 + k as f64).normalize();
            let truth = DQuat::from_axis_angle(axis, angle);
            let shift = DVec3::new(0.7, -2.0, 5.0);
            let b: Vec<DVec3> = a.iter().map(|&p| truth * p + shift).collect();
            let fit = best_rotation(&a, &b);
            // q and -q are the same rotation.
            let err = (fit - truth).length().min((fit + truth).length());
            assert!(err < 1e-10, "angle {angle}: quaternion error {err}");
        }
    }

    #[test]
    fn noisy_points_give_the_least_squares_rotation() {
        // Perturbing the fit in any direction must not lower the residual.
        let a = random_points(30, 2);
        let noise = random_points(30, 3);
        let truth = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, -1.0).normalize(), 0.8);
        let b: Vec<DVec3> = a
            .iter()
            .zip(&noise)
            .map(|(&p, &e)| truth * p + 0.05 * e)
            .collect();
        let residual = |q: DQuat| -> f64 {
            let ca = a.iter().copied().sum::<DVec3>() / 30.0;
            let cb = b.iter().copied().sum::<DVec3>() / 30.0;
            a.iter()
                .zip(&b)
                .map(|(&p, &r)| (q * (p - ca) - (r - cb)).length_squared())
                .sum()
        };
        let fit = best_rotation(&a, &b);
        let best = residual(fit);
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            for step in [-1e-3, 1e-3] {
                let nudged = DQuat::from_axis_angle(axis, step) * fit;
                assert!(
                    residual(nudged) > best,
                    "a nudge about {axis} lowered the residual"
                );
            }
        }
    }

    #[test]
    fn degenerate_sets_give_the_identity() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        assert_eq!(best_rotation(&[p], &[p + DVec3::X]), DQuat::IDENTITY);
        assert_eq!(best_rotation(&[p, p], &[p, p]), DQuat::IDENTITY);
    }
}
