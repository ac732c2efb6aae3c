//! Small fixed-size matrix helpers generic over [`Float`], used by the per-Gaussian
//! kernels (glam has no generic-scalar matrices, and the kernels must also run in f64
//! for gradient checks).

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

/// Rotation matrix of a unit quaternion `(w, x, y, z)` (Hamilton convention, as in
/// gsplat `_quat_to_rotmat` and Inria `computeCov3D`).
pub(crate) fn rotmat<T: Float>(q: [T; 4]) -> M3<T> {
    let [w, x, y, z] = q;
    let one = T::one();
    let two = T::of(2.0);
    [
        [
            one - two * (y * y + z * z),
            two * (x * y - w * z),
            two * (x * z + w * y),
        ],
        [
            two * (x * y + w * z),
            one - two * (x * x + z * z),
            two * (y * z - w * x),
        ],
        [
            two * (x * z - w * y),
            two * (y * z + w * x),
            one - two * (x * x + y * y),
        ],
    ]
}

/// Vector-Jacobian product of [`rotmat`]: given `G = dL/dR`, returns `dL/dq` for the
/// (already unit) quaternion `q`, treating `q` as free (no normalisation term).
pub(crate) fn rotmat_vjp<T: Float>(q: [T; 4], g: &M3<T>) -> [T; 4] {
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
