//! The separable Gaussian window of SSIM, shared by the evaluation metric
//! ([`super::ssim`]) and the training loss (`maaf_train::loss::ssim`): its size,
//! sigma and constants, its taps and the zero-padded "same" blur (self-adjoint, so
//! the SSIM backward reuses it as its own transpose).

use maaf_autodiff::Float;
use rayon::prelude::*;

/// Image rows per rayon task of each blur pass (an 800-wide RGB row is 2400 values).
const ROWS_PER_TASK: usize = 8;

/// Side of the SSIM window (11 taps).
pub const SSIM_WINDOW: usize = 11;
/// Standard deviation of the SSIM Gaussian window, in pixels.
pub const SSIM_SIGMA: f64 = 1.5;
/// `C1 = (K1 L)^2` with `K1 = 0.01` and data range `L = 1` (Wang et al. 2004).
pub const SSIM_C1: f64 = 0.01 * 0.01;
/// `C2 = (K2 L)^2` with `K2 = 0.03` and data range `L = 1` (Wang et al. 2004).
pub const SSIM_C2: f64 = 0.03 * 0.03;

/// Normalised 1D Gaussian taps `w_k = exp(-(k - r)^2 / (2 sigma^2)) / sum`,
/// `k = 0..size`, `r = size / 2` (the 3DGS `gaussian(window_size, sigma)`; the same as
/// scipy's `_gaussian_kernel1d` for `size = 2r + 1`).
pub fn gaussian_taps(size: usize, sigma: f64) -> Vec<f64> {
    assert!(size % 2 == 1, "gaussian_taps: size {size} must be odd");
    let r = (size / 2) as f64;
    let raw: Vec<f64> = (0..size)
        .map(|k| {
            let d = k as f64 - r;
            (-d * d / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let total: f64 = raw.iter().sum();
    raw.into_iter().map(|w| w / total).collect()
}

/// Output values per register block of a blur pass.
const BLOCK: usize = 32;

/// `dst[e] = sum_k taps[k] src[e + k * stride]` for every `e < dst.len()`, summed in
/// tap order; `src` holds `dst.len() + (taps.len() - 1) * stride` values. Blocks of
/// [`BLOCK`] outputs are accumulated in registers and stored once.
fn correlate<T: Float>(src: &[T], dst: &mut [T], taps: &[T], stride: usize) {
    let n = dst.len();
    let full = n - n % BLOCK;
    for e0 in (0..full).step_by(BLOCK) {
        let mut acc = [T::zero(); BLOCK];
        for (k, &wt) in taps.iter().enumerate() {
            let s = &src[e0 + k * stride..e0 + k * stride + BLOCK];
            for (a, &v) in acc.iter_mut().zip(s) {
                *a += wt * v;
            }
        }
        dst[e0..e0 + BLOCK].copy_from_slice(&acc);
    }
    for (e, d) in dst.iter_mut().enumerate().skip(full) {
        let mut a = T::zero();
        for (k, &wt) in taps.iter().enumerate() {
            a += wt * src[e + k * stride];
        }
        *d = a;
    }
}

/// Separable blur of an interleaved `[h, w, c]` image with symmetric odd-length taps
/// and zero-padded "same" borders:
/// `out[i, j] = sum_{a, b} taps[a] taps[b] img[i + a - r, j + b - r]`, out-of-range
/// samples read as 0 (weights are not renormalised at the border). Because `taps` is
/// symmetric this linear map is self-adjoint, so it also computes its own transpose.
///
/// Both passes run over blocks of rows in parallel, each a correlation of a
/// zero-padded copy; every output value is summed in tap order whatever the thread
/// count.
pub fn blur_same<T: Float>(img: &[T], h: usize, w: usize, c: usize, taps: &[T]) -> Vec<T> {
    assert_eq!(
        img.len(),
        h * w * c,
        "blur_same: {} values for [{h}, {w}, {c}]",
        img.len()
    );
    let r = taps.len() / 2;
    let row = w * c;
    if row == 0 {
        return Vec::new();
    }
    // Horizontal pass: each row padded with r zero pixels on both sides. It writes
    // rows r..r + h of `tmp`, whose r zero rows above and below pad the vertical pass.
    let mut tmp = vec![T::zero(); (h + 2 * r) * row];
    tmp[r * row..(r + h) * row]
        .par_chunks_mut(ROWS_PER_TASK * row)
        .zip(img.par_chunks(ROWS_PER_TASK * row))
        .for_each(|(dst_rows, src_rows)| {
            let mut padded = vec![T::zero(); row + 2 * r * c];
            for (dst, src) in dst_rows.chunks_mut(row).zip(src_rows.chunks(row)) {
                padded[r * c..r * c + row].copy_from_slice(src);
                correlate(&padded, dst, taps, c);
            }
        });
    // Vertical pass over the padded rows.
    let mut out = vec![T::zero(); img.len()];
    out.par_chunks_mut(ROWS_PER_TASK * row)
        .enumerate()
        .for_each(|(block, dst_rows)| {
            let first = block * ROWS_PER_TASK * row;
            let src = &tmp[first..first + dst_rows.len() + 2 * r * row];
            correlate(src, dst_rows, taps, row);
        });
    out
}
