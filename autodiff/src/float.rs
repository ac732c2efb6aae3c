//! The scalar types a tape can run on.

use std::fmt::{Debug, Display};

use rayon::prelude::*;

/// A floating-point scalar the tape runs on: `f32` for training, `f64` for gradient
/// checks. Adds lossless-enough conversions and GEMM entry points to
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
    /// `A` m x k, `B` k x n, `C` m x n; with `beta = 0` the old C is never read.
    ///
    /// Products of 2^20 multiply-adds or more run on rayon in fixed blocks: blocks of
    /// rows of C (1024 rows, fewer for C under 8192 rows) when C has at least two,
    /// else blocks of 2048 steps of the inner dimension (partial products added in
    /// block order) when there are at least two; the blocks depend on the shapes only,
    /// so the result never depends on the number of threads.
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
    ) {
        let strides = |rs: isize, cs: isize| {
            assert!(
                rs >= 0 && cs >= 0,
                "gemm: negative strides are not supported"
            );
            (rs as usize, cs as usize)
        };
        gemm_blocked(
            alpha,
            MatRef::new(a, m, k, strides(rsa, csa)),
            MatRef::new(b, k, n, strides(rsb, csb)),
            beta,
            MatMut::new(c, m, n, strides(rsc, csc)),
        );
    }

    /// [`Float::gemm`] on the calling thread only, through the `gemm` crate's kernels
    /// (`Parallelism::None`); the building block of the blocked products.
    fn gemm_serial(
        alpha: Self,
        a: MatRef<'_, Self>,
        b: MatRef<'_, Self>,
        beta: Self,
        c: MatMut<'_, Self>,
    );
}

/// A read-only strided matrix view: element `(i, j)` is `data[i * rs + j * cs]`.
#[derive(Clone, Copy, Debug)]
pub struct MatRef<'a, T> {
    data: &'a [T],
    rows: usize,
    cols: usize,
    rs: usize,
    cs: usize,
}

/// A mutable strided matrix view: element `(i, j)` is `data[i * rs + j * cs]`.
#[derive(Debug)]
pub struct MatMut<'a, T> {
    data: &'a mut [T],
    rows: usize,
    cols: usize,
    rs: usize,
    cs: usize,
}

/// Index one past the last element a `rows x cols` view with strides `(rs, cs)` touches
/// (0 when empty).
fn extent(rows: usize, cols: usize, (rs, cs): (usize, usize)) -> usize {
    if rows == 0 || cols == 0 {
        0
    } else {
        (rows - 1) * rs + (cols - 1) * cs + 1
    }
}

impl<'a, T> MatRef<'a, T> {
    /// Views `data` as `rows x cols` with `(row, column)` strides; panics when an
    /// element would fall outside `data`.
    pub fn new(data: &'a [T], rows: usize, cols: usize, (rs, cs): (usize, usize)) -> Self {
        assert!(
            extent(rows, cols, (rs, cs)) <= data.len(),
            "MatRef: {rows}x{cols} with strides ({rs}, {cs}) exceeds {} values",
            data.len()
        );
        MatRef {
            data,
            rows,
            cols,
            rs,
            cs,
        }
    }

    /// A row-major contiguous `rows x cols` view.
    pub fn row_major(data: &'a [T], rows: usize, cols: usize) -> Self {
        Self::new(data, rows, cols, (cols, 1))
    }

    /// The transpose (a stride swap, no copy).
    pub fn t(self) -> Self {
        MatRef {
            rows: self.cols,
            cols: self.rows,
            rs: self.cs,
            cs: self.rs,
            ..self
        }
    }

    /// Rows `start..start + count`.
    pub fn rows(self, start: usize, count: usize) -> Self {
        assert!(start + count <= self.rows, "MatRef::rows out of range");
        let offset = if count == 0 { 0 } else { start * self.rs };
        MatRef::new(&self.data[offset..], count, self.cols, (self.rs, self.cs))
    }

    /// Columns `start..start + count`.
    pub fn cols(self, start: usize, count: usize) -> Self {
        assert!(start + count <= self.cols, "MatRef::cols out of range");
        let offset = if count == 0 { 0 } else { start * self.cs };
        MatRef::new(&self.data[offset..], self.rows, count, (self.rs, self.cs))
    }

    /// `(rows, columns)`.
    pub fn dims(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }
}

impl<'a, T> MatMut<'a, T> {
    /// Views `data` as `rows x cols` with `(row, column)` strides; panics when an
    /// element would fall outside `data`. Overlapping strides (two indices on one
    /// element) are rejected too, so the kernel never writes one element twice.
    pub fn new(data: &'a mut [T], rows: usize, cols: usize, (rs, cs): (usize, usize)) -> Self {
        assert!(
            extent(rows, cols, (rs, cs)) <= data.len(),
            "MatMut: {rows}x{cols} with strides ({rs}, {cs}) exceeds {} values",
            data.len()
        );
        let distinct = rows * cols <= 1
            || (rows == 1 && cs >= 1)
            || (cols == 1 && rs >= 1)
            || (cs >= 1 && rs >= cols * cs)
            || (rs >= 1 && cs >= rows * rs);
        assert!(distinct, "MatMut: strides ({rs}, {cs}) alias elements");
        MatMut {
            data,
            rows,
            cols,
            rs,
            cs,
        }
    }

    /// A row-major contiguous `rows x cols` view.
    pub fn row_major(data: &'a mut [T], rows: usize, cols: usize) -> Self {
        Self::new(data, rows, cols, (cols, 1))
    }

    /// `(rows, columns)`.
    pub fn dims(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }
}

/// Rows of C per block when a product is split over rows.
pub(crate) const ROW_BLOCK: usize = 1024;
/// Reduction steps per block when a product is split over its inner dimension.
pub(crate) const DEPTH_BLOCK: usize = 2048;
/// Products below this many multiply-adds run on one thread (rayon's hand-off costs
/// more than it saves).
pub(crate) const PARALLEL_MIN_MACS: usize = 1 << 20;

/// Rows of C per block when a product with `m` rows is split over rows: 1024 from
/// 8192 rows up, else an eighth of the rows rounded up to a multiple of 16, so medium
/// products (an SSIM blur with 200 rows) still spread over the cores.
fn row_block(m: usize) -> usize {
    if m >= 8 * ROW_BLOCK {
        ROW_BLOCK
    } else {
        m.div_ceil(8).next_multiple_of(16)
    }
}

/// The sizes `(m, k, n)` of `C [m x n] = A [m x k] B [k x n]`; panics naming the three
/// shapes when they do not chain.
fn gemm_dims<T>(a: &MatRef<'_, T>, b: &MatRef<'_, T>, c: &MatMut<'_, T>) -> (usize, usize, usize) {
    let (m, k) = (a.rows, a.cols);
    let n = b.cols;
    assert!(
        b.rows == k && c.rows == m && c.cols == n,
        "gemm: shapes {m}x{k} * {}x{n} -> {}x{}",
        b.rows,
        c.rows,
        c.cols
    );
    (m, k, n)
}

/// `C = alpha A B + beta C`, split into blocks that depend on the shapes only:
/// - C with at least two [`row_block`]s of rows, stored by rows (`rs >= n cs`):
///   blocks of rows of C, each one single-threaded product, in parallel;
/// - otherwise, a reduction of at least two [`DEPTH_BLOCK`]s (the weight gradient
///   `x^T g` of a dense layer): one partial product per block of the inner dimension,
///   in parallel, added in block order;
/// - small products (under 2^20 multiply-adds) and everything else: one serial call.
pub(crate) fn gemm_blocked<T: Float>(
    alpha: T,
    a: MatRef<'_, T>,
    b: MatRef<'_, T>,
    beta: T,
    c: MatMut<'_, T>,
) {
    let (m, k, n) = gemm_dims(&a, &b, &c);
    if m * k * n < PARALLEL_MIN_MACS {
        return T::gemm_serial(alpha, a, b, beta, c);
    }
    let rb = row_block(m);
    if m >= 2 * rb && c.rs >= n * c.cs {
        let (rs, cs) = (c.rs, c.cs);
        return c.data[..extent(m, n, (rs, cs))]
            .par_chunks_mut(rb * rs)
            .enumerate()
            .for_each(|(i, block)| {
                let rows = rb.min(m - i * rb);
                T::gemm_serial(
                    alpha,
                    a.rows(i * rb, rows),
                    b,
                    beta,
                    MatMut::new(block, rows, n, (rs, cs)),
                );
            });
    }
    if k >= 2 * DEPTH_BLOCK {
        let partials: Vec<Vec<T>> = (0..k.div_ceil(DEPTH_BLOCK))
            .into_par_iter()
            .map(|j| {
                let depth = DEPTH_BLOCK.min(k - j * DEPTH_BLOCK);
                let mut part = vec![T::zero(); m * n];
                T::gemm_serial(
                    alpha,
                    a.cols(j * DEPTH_BLOCK, depth),
                    b.rows(j * DEPTH_BLOCK, depth),
                    T::zero(),
                    MatMut::row_major(&mut part, m, n),
                );
                part
            })
            .collect();
        let (rs, cs) = (c.rs, c.cs);
        for i in 0..m {
            for j in 0..n {
                let at = i * rs + j * cs;
                let sum = partials.iter().fold(T::zero(), |s, p| s + p[i * n + j]);
                c.data[at] = if beta == T::zero() {
                    sum
                } else {
                    beta * c.data[at] + sum
                };
            }
        }
        return;
    }
    T::gemm_serial(alpha, a, b, beta, c)
}

macro_rules! impl_float {
    ($t:ty) => {
        impl Float for $t {
            fn of(x: f64) -> Self {
                x as $t
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            fn gemm_serial(
                alpha: Self,
                a: MatRef<'_, Self>,
                b: MatRef<'_, Self>,
                beta: Self,
                c: MatMut<'_, Self>,
            ) {
                let (m, k, n) = gemm_dims(&a, &b, &c);
                if m == 0 || n == 0 {
                    return;
                }
                // SAFETY: the views' constructors checked that every index the kernel
                // touches, i*rs + j*cs for i < rows and j < cols, lies inside its slice
                // and that C's strides never map two indices to one element; C is a
                // unique borrow, so it cannot alias A or B. The `gemm` crate computes
                // dst = alpha_dst * dst + beta_prod * lhs rhs and ignores dst when
                // `read_dst` is false.
                #[allow(unsafe_code)]
                unsafe {
                    gemm::gemm(
                        m,
                        n,
                        k,
                        c.data.as_mut_ptr(),
                        c.cs as isize,
                        c.rs as isize,
                        beta != 0.0,
                        a.data.as_ptr(),
                        a.cs as isize,
                        a.rs as isize,
                        b.data.as_ptr(),
                        b.cs as isize,
                        b.rs as isize,
                        beta,
                        alpha,
                        false,
                        false,
                        false,
                        gemm::Parallelism::None,
                    );
                }
            }
        }
    };
}

impl_float!(f32);
impl_float!(f64);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::tests_support::random_tensor;

    /// `alpha A B + beta C` by a triple loop, C row-major.
    #[allow(clippy::too_many_arguments)]
    fn reference(
        m: usize,
        k: usize,
        n: usize,
        alpha: f64,
        a: &[f64],
        (rsa, csa): (usize, usize),
        b: &[f64],
        (rsb, csb): (usize, usize),
        beta: f64,
        c: &[f64],
    ) -> Vec<f64> {
        let mut out = Vec::with_capacity(m * n);
        for i in 0..m {
            for j in 0..n {
                let dot: f64 = (0..k)
                    .map(|p| a[i * rsa + p * csa] * b[p * rsb + j * csb])
                    .sum();
                out.push(alpha * dot + beta * c[i * n + j]);
            }
        }
        out
    }

    #[test]
    fn blocked_gemm_matches_a_triple_loop_on_every_path() {
        // Serial (small), split over rows of C (large and medium blocks), split over the
        // reduction; A and B both plain and transposed; beta 0 (C ignored, even when
        // NaN) and beta != 0.
        for (m, k, n) in [
            (7, 5, 3),
            (2 * ROW_BLOCK + 52, 30, 20),
            (200, 80, 70),
            (6, 2 * DEPTH_BLOCK + 404, 40),
        ] {
            for transposed in [false, true] {
                let a = random_tensor::<f64>(&[m * k], -1.0, 1.0, 1).into_vec();
                let b = random_tensor::<f64>(&[k * n], -1.0, 1.0, 2).into_vec();
                let sa = if transposed { (1, m) } else { (k, 1) };
                let sb = if transposed { (1, k) } else { (n, 1) };
                for (alpha, beta) in [(1.0, 0.0), (-0.5, 2.0)] {
                    let mut c = random_tensor::<f64>(&[m * n], -1.0, 1.0, 3).into_vec();
                    let want = reference(m, k, n, alpha, &a, sa, &b, sb, beta, &c);
                    if beta == 0.0 {
                        c.fill(f64::NAN);
                    }
                    let s = |(r, c): (usize, usize)| (r as isize, c as isize);
                    let ((rsa, csa), (rsb, csb)) = (s(sa), s(sb));
                    f64::gemm(
                        m, k, n, alpha, &a, rsa, csa, &b, rsb, csb, beta, &mut c, n as isize, 1,
                    );
                    for (i, (&g, &w)) in c.iter().zip(&want).enumerate() {
                        assert!(
                            (g - w).abs() < 1e-11,
                            "{m}x{k}x{n} transposed={transposed} beta={beta} at {i}: {g} vs {w}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    #[should_panic(expected = "alias")]
    fn aliasing_output_strides_are_rejected() {
        let mut c = vec![0.0f32; 4];
        MatMut::new(&mut c, 2, 2, (1, 1));
    }
}
