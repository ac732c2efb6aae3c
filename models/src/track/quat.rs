//! Quaternions `(w, x, y, z)` as Dynamic 3D Gaussians uses them (`helpers.quat_mult`,
//! `external.build_rotation`), with the vector-Jacobian products the neighbour ops
//! need.

/// A quaternion `(w, x, y, z)`.
pub type Quat = [f64; 4];

/// `q / |q|`, and `|q|`.
pub fn normalise(q: Quat) -> (Quat, f64) {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    (q.map(|v| v / n), n)
}

/// The conjugate `(w, -x, -y, -z)`: the inverse of a unit quaternion.
pub fn conj(q: Quat) -> Quat {
    [q[0], -q[1], -q[2], -q[3]]
}

/// The Hamilton product `a b` (`helpers.quat_mult`).
pub fn mul(a: Quat, b: Quat) -> Quat {
    let [w1, x1, y1, z1] = a;
    let [w2, x2, y2, z2] = b;
    [
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ]
}

/// The rotation matrix of a unit quaternion (`build_rotation` after its
/// normalisation), row-major `R[row][col]`.
pub fn rotation(q: Quat) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// `sum_ab G[a][b] dR[a][b]/dq` for [`rotation`] (the formula's partial derivatives,
/// without a normalisation).
pub fn rotation_vjp(q: Quat, g: &[[f64; 3]; 3]) -> Quat {
    let [w, x, y, z] = q;
    let [[g00, g01, g02], [g10, g11, g12], [g20, g21, g22]] = *g;
    [
        2.0 * (-z * g01 + y * g02 + z * g10 - x * g12 - y * g20 + x * g21),
        2.0 * (y * g01 + z * g02 + y * g10 - 2.0 * x * g11 - w * g12 + z * g20 + w * g21
            - 2.0 * x * g22),
        2.0 * (-2.0 * y * g00 + x * g01 + w * g02 + x * g10 + z * g12 - w * g20 + z * g21
            - 2.0 * y * g22),
        2.0 * (-2.0 * z * g00 - w * g01 + x * g02 + w * g10 - 2.0 * z * g11
            + y * g12
            + x * g20
            + y * g21),
    ]
}

/// The relative rotation of a Gaussian between two frames: `u c` with
/// `u = q / |q|` (this frame's quaternion, a variable) and `c = conj(p)` (`p` the
/// previous frame's unit quaternion, a constant): Dynamic 3D Gaussians'
/// `quat_mult(fg_rot, prev_inv_rot_fg)`.
pub struct Relative {
    /// `q / |q|`.
    pub unit: Quat,
    /// `|q|`.
    pub norm: f64,
    /// The previous frame's unit quaternion `p`.
    pub previous: Quat,
    /// `u conj(p)`.
    pub value: Quat,
}

impl Relative {
    /// The relative rotation of `q` against the previous frame's `previous`.
    pub fn new(q: Quat, previous: Quat) -> Self {
        let (unit, norm) = normalise(q);
        Relative {
            unit,
            norm,
            previous,
            value: mul(unit, conj(previous)),
        }
    }

    /// The cotangent of `q` from the cotangent `g` of [`Relative::value`]: right
    /// multiplication by `c` is the matrix `M(c)` with `M(c)^T = M(conj c)`, so
    /// `dL/du = g conj(c) = g p`; then through the normalisation,
    /// `dL/dq = (dL/du - u (u . dL/du)) / |q|`.
    pub fn vjp(&self, g: Quat) -> Quat {
        let gu = mul(g, self.previous);
        let radial: f64 = self.unit.iter().zip(&gu).map(|(u, g)| u * g).sum();
        std::array::from_fn(|a| (gu[a] - self.unit[a] * radial) / self.norm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_turns_as_the_quaternion_does() {
        // q v conj(q) for a pure quaternion v equals R v.
        let (q, _) = normalise([0.3, -0.5, 0.7, 0.2]);
        let v = [0.4, -1.1, 2.0];
        let turned = mul(mul(q, [0.0, v[0], v[1], v[2]]), conj(q));
        let r = rotation(q);
        for a in 0..3 {
            let rv: f64 = (0..3).map(|b| r[a][b] * v[b]).sum();
            assert!((rv - turned[a + 1]).abs() < 1e-12);
        }
    }

    #[test]
    fn rotation_vjp_matches_finite_differences() {
        let q = [0.3, -0.5, 0.7, 0.2];
        let g = [[0.1, -0.4, 0.9], [0.3, 0.2, -0.7], [-0.6, 0.5, 0.8]];
        let f = |q: Quat| -> f64 {
            let r = rotation(q);
            (0..9).map(|k| r[k / 3][k % 3] * g[k / 3][k % 3]).sum()
        };
        let got = rotation_vjp(q, &g);
        for a in 0..4 {
            let mut hi = q;
            let mut lo = q;
            hi[a] += 1e-6;
            lo[a] -= 1e-6;
            let fd = (f(hi) - f(lo)) / 2e-6;
            assert!((fd - got[a]).abs() < 1e-8, "{a}: {fd} vs {}", got[a]);
        }
    }
}
