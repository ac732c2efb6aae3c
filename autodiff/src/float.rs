//! The scalar types a tape can run on.

use std::fmt::{Debug, Display};

/// A floating-point scalar the tape runs on: `f32` for training, `f64` for gradient
/// checks. Adds lossless-enough conversions and a GEMM entry point to
/// [`num_traits::Float`].
pub trait Float:
    num_traits::Float
    + num_traits::FloatConst
    + std::iter::Sum
    + std::ops::AddAssign
    + std::ops::SubAssign
    + std::ops::MulAssign
    + std::ops::DivAssign
    + Default
    + Debug
    + Display
    + Send
    + Sync
    + 'static
{
    /// Converts from f64 (rounding for f32).
    fn of(x: f64) -> Self;
    /// Converts to f64.
    fn to_f64(self) -> f64;
    /// `C = alpha * A B + beta * C` with explicit row and column strides (in elements),
    /// `A` m x k, `B` k x n, `C` m x n, through the `matrixmultiply` crate.
    #[allow(clippy::too_many_arguments)]
    fn gemm(
        m: usize,
        k: usize,
        n: usize,
        alpha: Self,
        a: &[Self],
        rsa: isize,
        csa: isize,
        b: &[Self],
        rsb: isize,
        csb: isize,
        beta: Self,
        c: &mut [Self],
        rsc: isize,
        csc: isize,
    );
}

macro_rules! impl_float {
    ($t:ty, $gemm:path) => {
        impl Float for $t {
            fn of(x: f64) -> Self {
                x as $t
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            fn gemm(
                m: usize,
                k: usize,
                n: usize,
                alpha: Self,
                a: &[Self],
                rsa: isize,
                csa: isize,
                b: &[Self],
                rsb: isize,
                csb: isize,
                beta: Self,
                c: &mut [Self],
                rsc: isize,
                csc: isize,
            ) {
                if m == 0 || n == 0 {
                    return;
                }
                let max_index = |rows: usize, cols: usize, rs: isize, cs: isize| {
                    (rows as isize - 1) * rs + (cols as isize - 1) * cs
                };
                assert!(
                    rsa >= 0 && csa >= 0 && rsb >= 0 && csb >= 0 && rsc >= 0 && csc >= 0,
                    "gemm: negative strides are not supported"
                );
                if k > 0 {
                    assert!(
                        (max_index(m, k, rsa, csa) as usize) < a.len(),
                        "gemm: A out of bounds"
                    );
                    assert!(
                        (max_index(k, n, rsb, csb) as usize) < b.len(),
                        "gemm: B out of bounds"
                    );
                }
                assert!(
                    (max_index(m, n, rsc, csc) as usize) < c.len(),
                    "gemm: C out of bounds"
                );
                // SAFETY: every index the kernel touches, (i*rs + j*cs) for i < rows and
                // j < cols, was checked to lie inside the slices above; C is borrowed
                // mutably so it cannot alias A or B.
                #[allow(unsafe_code)]
                unsafe {
                    $gemm(
                        m,
                        k,
                        n,
                        alpha,
                        a.as_ptr(),
                        rsa,
                        csa,
                        b.as_ptr(),
                        rsb,
                        csb,
                        beta,
                        c.as_mut_ptr(),
                        rsc,
                        csc,
                    );
                }
            }
        }
    };
}

impl_float!(f32, matrixmultiply::sgemm);
impl_float!(f64, matrixmultiply::dgemm);
