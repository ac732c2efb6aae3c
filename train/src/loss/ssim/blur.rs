//! The separable Gaussian window of SSIM: its taps and the zero-padded "same" blur
//! (self-adjoint, so the SSIM backward reuses it as its own transpose).

use maaf_autodiff::Float;

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

/// Separable blur of an interleaved `[h, w, c]` image with symmetric odd-length taps
/// and zero-padded "same" borders:
/// `out[i, j] = sum_{a, b} taps[a] taps[b] img[i + a - r, j + b - r]`, out-of-range
/// samples read as 0 (weights are not renormalised at the border). Because `taps` is
/// symmetric this linear map is self-adjoint, so it also computes its own transpose.
pub fn blur_same<T: Float>(img: &[T], h: usize, w: usize, c: usize, taps: &[T]) -> Vec<T> {
    assert_eq!(
        img.len(),
        h * w * c,
        "blur_same: {} values for [{h}, {w}, {c}]",
        img.len()
    );
    let r = taps.len() / 2;
    let row = w * c;
    // Horizontal pass, one tap at a time: for tap `k` (offset `k - r`), every output
    // pixel `j` whose source `j + k - r` is in range gets `taps[k] * src[j + k - r]`;
    // both ranges are contiguous in the interleaved row, so this is a plain axpy.
    let mut tmp = vec![T::zero(); img.len()];
    for i in 0..h {
        let src = &img[i * row..(i + 1) * row];
        let dst = &mut tmp[i * row..(i + 1) * row];
        for (k, &wt) in taps.iter().enumerate() {
            // Output pixels j in [j0, j1) read source pixels j + k - r in [0, w).
            let j0 = r.saturating_sub(k);
            let j1 = (w + r).saturating_sub(k).min(w);
            if j0 >= j1 {
                continue;
            }
            let s0 = j0 + k - r;
            let len = (j1 - j0) * c;
            for (d, &v) in dst[j0 * c..j0 * c + len]
                .iter_mut()
                .zip(&src[s0 * c..s0 * c + len])
            {
                *d += wt * v;
            }
        }
    }
    // Vertical pass: whole rows at a time, contiguous in memory.
    let mut out = vec![T::zero(); img.len()];
    for i in 0..h {
        let lo = i.saturating_sub(r);
        let hi = (i + r).min(h - 1);
        let dst = &mut out[i * row..(i + 1) * row];
        for ii in lo..=hi {
            let wt = taps[ii + r - i];
            for (d, &v) in dst.iter_mut().zip(&tmp[ii * row..(ii + 1) * row]) {
                *d += wt * v;
            }
        }
    }
    out
}
