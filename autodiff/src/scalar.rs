//! Scalar activations shared by the tape's ops and by code that works on plain values
//! (initialisation, densification, PLY conversion), so both agree bit for bit.

use crate::Float;

/// The logistic function `1 / (1 + e^-x)` in its overflow-free form: `1/(1+e^-x)` for
/// `x >= 0`, `e^x/(1+e^x)` otherwise. The tape's `sigmoid` op evaluates this.
pub fn sigmoid<T: Float>(x: T) -> T {
    if x >= T::zero() {
        T::one() / (T::one() + (-x).exp())
    } else {
        let e = x.exp();
        e / (T::one() + e)
    }
}

/// Smallest distance of a probability from 0 or 1 that [`logit`] accepts; values
/// closer are clamped so the result stays finite (an opacity of exactly 1 in a PLY).
pub const LOGIT_EPS: f64 = 1e-7;

/// `ln(p / (1 - p))`, the inverse of [`sigmoid`] (3DGS `inverse_sigmoid`), with `p`
/// clamped to `[LOGIT_EPS, 1 - LOGIT_EPS]`.
pub fn logit<T: Float>(p: T) -> T {
    let p = p.max(T::of(LOGIT_EPS)).min(T::of(1.0 - LOGIT_EPS));
    (p / (T::one() - p)).ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logit_inverts_sigmoid_and_stays_finite_at_the_ends() {
        for p in [0.01f64, 0.1, 0.5, 0.9] {
            assert!((sigmoid(logit(p)) - p).abs() < 1e-15, "{p}");
        }
        assert!(logit(1.0f32).is_finite() && logit(0.0f32).is_finite());
        assert!((sigmoid(-800.0f64)).is_finite() && sigmoid(800.0f64) == 1.0);
    }
}
