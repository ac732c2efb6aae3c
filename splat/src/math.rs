//! Small fixed-size matrix helpers generic over [`Float`], used by the per-Gaussian
//! kernels (glam has no generic-scalar matrices, and the kernels must also run in f64
//! for gradient checks), and the one quaternion-to-rotation function of the crate.

use maaf_autodiff::Float;

/// A row-major 3x3 matrix.
pub(crate) type M3<T> = [[T; 3]; 3];

/// `A B`.
pub(crate) fn mul3<T: Float>(a: &M3<T>, b: &M3<T>) -> M3<T> {
    let mut c = [[T::zero(); 3]; 3];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

/// `A^T`.
pub(crate) fn transpose3<T: Float>(a: &M3<T>) -> M3<T> {
    let mut c = [[T::zero(); 3]; 3];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[j][i];
        }
    }
    c
}

/// `A v`.
pub(crate) fn mul3v<T: Float>(a: &M3<T>, v: [T; 3]) -> [T; 3] {
    [
        a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
        a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
        a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2],
    ]
}

/// `A^T v`.
pub(crate) fn mul3tv<T: Float>(a: &M3<T>, v: [T; 3]) -> [T; 3] {
    [
        a[0][0] * v[0] + a[1][0] * v[1] + a[2][0] * v[2],
        a[0][1] * v[0] + a[1][1] * v[1] + a[2][1] * v[2],
        a[0][2] * v[0] + a[1][2] * v[1] + a[2][2] * v[2],
    ]
}

/// Unpacks the upper triangle `(xx, xy, xz, yy, yz, zz)` into a symmetric matrix.
pub(crate) fn sym_from6<T: Float>(c: &[T]) -> M3<T> {
    [[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]]
}

/// Rotation matrix of an unnormalised quaternion `q = (w, x, y, z)` (Hamilton
/// convention, as gsplat `_quat_to_rotmat` and Inria `computeCov3D`, which normalise
/// first). With `s = 2 / (w^2 + x^2 + y^2 + z^2)`:
///
/// ```text
///     | 1 - s(y^2 + z^2)    s(xy - wz)        s(xz + wy)     |
/// R = | s(xy + wz)          1 - s(x^2 + z^2)  s(yz - wx)     |
///     | s(xz - wy)          s(yz + wx)        1 - s(x^2 + y^2) |
/// ```
///
/// which equals the unit-quaternion matrix of `q / |q|` (the `1/|q|^2` of every
/// quadratic term is folded into `s`). `q = 0` gives non-finite entries.
pub fn quat_to_rotmat<T: Float>(q: [T; 4]) -> [[T; 3]; 3] {
    let [w, x, y, z] = q;
    let one = T::one();
    let s = T::of(2.0) / (w * w + x * x + y * y + z * z);
    [
        [
            one - s * (y * y + z * z),
            s * (x * y - w * z),
            s * (x * z + w * y),
        ],
        [
            s * (x * y + w * z),
            one - s * (x * x + z * z),
            s * (y * z - w * x),
        ],
        [
            s * (x * z - w * y),
            s * (y * z + w * x),
            one - s * (x * x + y * y),
        ],
    ]
}

/// Vector-Jacobian product of [`quat_to_rotmat`] at a unit quaternion `q` with `s = 2`
/// held fixed: given `G = dL/dR`, returns `dL/dq` treating `q` as free. The caller
/// adds the normalisation, `dq = (dq_hat - q_hat (q_hat . dq_hat)) / |q|`.
pub fn rotmat_vjp<T: Float>(q: [T; 4], g: &[[T; 3]; 3]) -> [T; 4] {
    let [w, x, y, z] = q;
    let two = T::of(2.0);
    let four = T::of(4.0);
    let dw =
        two * (-z * g[0][1] + y * g[0][2] + z * g[1][0] - x * g[1][2] - y * g[2][0] + x * g[2][1]);
    let dx = two
        * (y * g[0][1] + z * g[0][2] + y * g[1][0] - w * g[1][2] + z * g[2][0] + w * g[2][1])
        - four * x * (g[1][1] + g[2][2]);
    let dy = two
        * (x * g[0][1] + w * g[0][2] + x * g[1][0] + z * g[1][2] - w * g[2][0] + z * g[2][1])
        - four * y * (g[0][0] + g[2][2]);
    let dz = two
        * (-w * g[0][1] + x * g[0][2] + w * g[1][0] + y * g[1][2] + x * g[2][0] + y * g[2][1])
        - four * z * (g[0][0] + g[1][1]);
    [dw, dx, dy, dz]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `R` is a rotation (orthonormal, det 1), independent of the quaternion's length
    /// and sign, and maps as the Hamilton product: a 90 degree turn about z sends x
    /// to y.
    #[test]
    fn quat_to_rotmat_is_a_rotation_for_any_length() {
        let q = [0.7f64, -0.2, 0.5, 0.3];
        let r = quat_to_rotmat(q);
        let rtr = mul3(&transpose3(&r), &r);
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((rtr[i][j] - want).abs() < 1e-14, "R^T R [{i}][{j}]");
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        assert!((det - 1.0).abs() < 1e-14);
        for k in [3.0, -0.01] {
            let rk = quat_to_rotmat(q.map(|v| v * k));
            for i in 0..3 {
                for j in 0..3 {
                    assert!((rk[i][j] - r[i][j]).abs() < 1e-14, "scale {k}");
                }
            }
        }
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let y = mul3v(&quat_to_rotmat([h, 0.0, 0.0, h]), [1.0, 0.0, 0.0]);
        assert!((y[0]).abs() < 1e-15 && (y[1] - 1.0).abs() < 1e-15 && y[2].abs() < 1e-15);
    }
}
