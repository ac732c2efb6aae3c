//! Quaternions `(w, x, y, z)` as Dynamic 3D Gaussians uses them (`helpers.quat_mult`),
//! with the vector-Jacobian product the neighbour ops need; rotation matrices are
//! the renderer's ([`maaf_splat::quat_to_rotmat`], `external.build_rotation`).

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
    fn the_product_turns_as_the_rotation_matrix_does() {
        // q v conj(q) for a pure quaternion v equals R v.
        let (q, _) = normalise([0.3, -0.5, 0.7, 0.2]);
        let v = [0.4, -1.1, 2.0];
        let turned = mul(mul(q, [0.0, v[0], v[1], v[2]]), conj(q));
        let r = maaf_splat::quat_to_rotmat(q);
        for a in 0..3 {
            let rv: f64 = (0..3).map(|b| r[a][b] * v[b]).sum();
            assert!((rv - turned[a + 1]).abs() < 1e-12);
        }
    }
}
