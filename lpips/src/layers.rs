//! The two layer kinds AlexNet needs, on channels-last feature maps: a convolution
//! with fused bias and ReLU (im2col + one GEMM per band of output rows) and a
//! "valid" max-pool.

use maaf_autodiff::Float;
use rayon::prelude::*;

/// A feature map stored channels-last: value of channel `c` at row `y`, column `x` is
/// `data[(y * w + x) * c_count + c]`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FeatureMap {
    /// Rows.
    pub h: usize,
    /// Columns.
    pub w: usize,
    /// Channels.
    pub c: usize,
    /// `h * w * c` values.
    pub data: Vec<f32>,
}

/// Most im2col values built at once (16 M floats = 64 MB); larger layers are
/// processed in bands of output rows.
const MAX_COLUMNS: usize = 1 << 24;

/// A square 2D convolution followed by ReLU:
/// `y[oy, ox, o] = max(0, b[o] + sum_{ky, kx, i} x[oy s - p + ky, ox s - p + kx, i] W[ky, kx, i, o])`
/// with zeros outside the input (PyTorch `Conv2d` / flax `Conv` cross-correlation).
#[derive(Clone, Debug)]
pub(crate) struct ConvRelu {
    /// Kernel size `k` (k x k).
    pub k: usize,
    /// Stride `s`.
    pub stride: usize,
    /// Zero padding `p` on every side.
    pub pad: usize,
    /// Input channels.
    pub c_in: usize,
    /// Output channels.
    pub c_out: usize,
    /// `[k, k, c_in, c_out]` row-major (HWIO): the `[k k c_in, c_out]` GEMM operand.
    pub weight: Vec<f32>,
    /// `[c_out]`.
    pub bias: Vec<f32>,
}

impl ConvRelu {
    /// Output length along an axis of input length `n`: `(n + 2p - k) / s + 1`, or
    /// `None` when the kernel does not fit.
    pub fn out_len(&self, n: usize) -> Option<usize> {
        (n + 2 * self.pad)
            .checked_sub(self.k)
            .map(|v| v / self.stride + 1)
    }

    /// Applies the convolution and ReLU; `None` when the input is smaller than the
    /// kernel. Panics if `x.c != c_in` (a wiring bug, not user input).
    pub fn forward(&self, x: &FeatureMap) -> Option<FeatureMap> {
        assert_eq!(x.c, self.c_in, "conv input channels");
        let (ho, wo) = (self.out_len(x.h)?, self.out_len(x.w)?);
        let kk = self.k * self.k * self.c_in;
        let band_rows = (MAX_COLUMNS / (wo * kk)).clamp(1, ho);
        let mut out = vec![0.0f32; ho * wo * self.c_out];
        let mut cols = vec![0.0f32; band_rows * wo * kk];
        for (band, out_band) in out.chunks_mut(band_rows * wo * self.c_out).enumerate() {
            let rows = out_band.len() / (wo * self.c_out);
            let cols = &mut cols[..rows * wo * kk];
            cols.par_chunks_mut(wo * kk)
                .enumerate()
                .for_each(|(r, row)| self.im2col_row(x, band * band_rows + r, row));
            for px in out_band.chunks_exact_mut(self.c_out) {
                px.copy_from_slice(&self.bias);
            }
            let n = self.c_out as isize;
            f32::gemm(
                rows * wo,
                kk,
                self.c_out,
                1.0,
                cols,
                kk as isize,
                1,
                &self.weight,
                n,
                1,
                1.0,
                out_band,
                n,
                1,
            );
        }
        out.par_iter_mut().for_each(|v| *v = v.max(0.0));
        Some(FeatureMap {
            h: ho,
            w: wo,
            c: self.c_out,
            data: out,
        })
    }

    /// Fills the im2col rows of output row `oy`: for each output column a patch of
    /// `k k c_in` values ordered `(ky, kx, i)`, zero where the window leaves the input.
    fn im2col_row(&self, x: &FeatureMap, oy: usize, row: &mut [f32]) {
        let (k, c) = (self.k, self.c_in);
        for (ox, patch) in row.chunks_exact_mut(k * k * c).enumerate() {
            patch.fill(0.0);
            let x0 = (ox * self.stride) as isize - self.pad as isize;
            // Columns kx whose input column x0 + kx is inside [0, w).
            let kx_lo = (-x0).clamp(0, k as isize) as usize;
            let kx_hi = (x.w as isize - x0).clamp(0, k as isize) as usize;
            if kx_lo >= kx_hi {
                continue;
            }
            for ky in 0..k {
                let iy = (oy * self.stride + ky) as isize - self.pad as isize;
                if iy < 0 || iy >= x.h as isize {
                    continue;
                }
                let src = (iy as usize * x.w + (x0 + kx_lo as isize) as usize) * c;
                let len = (kx_hi - kx_lo) * c;
                let dst = (ky * k + kx_lo) * c;
                patch[dst..dst + len].copy_from_slice(&x.data[src..src + len]);
            }
        }
    }
}

/// Max-pool with a `k x k` window and stride `s`, no padding ("valid", PyTorch
/// `MaxPool2d(k, s)` without `ceil_mode`): output length `(n - k) / s + 1`.
/// `None` when the input is smaller than the window.
pub(crate) fn max_pool(x: &FeatureMap, k: usize, s: usize) -> Option<FeatureMap> {
    let ho = x.h.checked_sub(k)? / s + 1;
    let wo = x.w.checked_sub(k)? / s + 1;
    let c = x.c;
    let mut data = vec![f32::NEG_INFINITY; ho * wo * c];
    data.par_chunks_mut(wo * c)
        .enumerate()
        .for_each(|(oy, row)| {
            for (ox, px) in row.chunks_exact_mut(c).enumerate() {
                for ky in 0..k {
                    for kx in 0..k {
                        let i = ((oy * s + ky) * x.w + ox * s + kx) * c;
                        for (m, &v) in px.iter_mut().zip(&x.data[i..i + c]) {
                            *m = m.max(v);
                        }
                    }
                }
            }
        });
    Some(FeatureMap {
        h: ho,
        w: wo,
        c,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random values on [-1, 1] (an LCG; no RNG dependency).
    fn values(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
            })
            .collect()
    }

    fn map(h: usize, w: usize, c: usize, seed: u64) -> FeatureMap {
        FeatureMap {
            h,
            w,
            c,
            data: values(h * w * c, seed),
        }
    }

    /// The convolution written as the textbook sum, one output value at a time, in f64.
    fn conv_reference(conv: &ConvRelu, x: &FeatureMap) -> Vec<f64> {
        let (ho, wo) = (
            conv.out_len(x.h).unwrap_or(0),
            conv.out_len(x.w).unwrap_or(0),
        );
        let mut out = Vec::new();
        for oy in 0..ho {
            for ox in 0..wo {
                for o in 0..conv.c_out {
                    let mut acc = conv.bias[o] as f64;
                    for ky in 0..conv.k {
                        for kx in 0..conv.k {
                            let iy = (oy * conv.stride + ky) as i64 - conv.pad as i64;
                            let ix = (ox * conv.stride + kx) as i64 - conv.pad as i64;
                            if iy < 0 || ix < 0 || iy >= x.h as i64 || ix >= x.w as i64 {
                                continue;
                            }
                            for i in 0..conv.c_in {
                                let xv = x.data[((iy as usize * x.w) + ix as usize) * x.c + i];
                                let wv = conv.weight
                                    [((ky * conv.k + kx) * conv.c_in + i) * conv.c_out + o];
                                acc += xv as f64 * wv as f64;
                            }
                        }
                    }
                    out.push(acc.max(0.0));
                }
            }
        }
        out
    }

    fn conv(k: usize, stride: usize, pad: usize, c_in: usize, c_out: usize) -> ConvRelu {
        ConvRelu {
            k,
            stride,
            pad,
            c_in,
            c_out,
            weight: values(k * k * c_in * c_out, 7),
            bias: values(c_out, 8),
        }
    }

    #[test]
    fn conv_matches_the_per_pixel_sum_for_alexnet_like_shapes() {
        for (k, s, p, ci, co, h, w) in [
            (11, 4, 2, 3, 5, 35, 27),
            (5, 1, 2, 4, 6, 9, 7),
            (3, 1, 1, 5, 3, 6, 11),
            (3, 2, 0, 2, 2, 8, 5),
        ] {
            let c = conv(k, s, p, ci, co);
            let x = map(h, w, ci, (k * 31 + h) as u64);
            let fast = c.forward(&x).expect("fits");
            let slow = conv_reference(&c, &x);
            assert_eq!(
                (fast.h, fast.w, fast.c),
                (c.out_len(h).expect("fits"), c.out_len(w).expect("fits"), co)
            );
            assert_eq!(fast.data.len(), slow.len());
            let worst = fast
                .data
                .iter()
                .zip(&slow)
                .map(|(&a, &b)| (a as f64 - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-4, "k={k}: worst |fast - slow| = {worst}");
            assert!(
                slow.iter().any(|&v| v > 0.1),
                "ReLU must not zero everything"
            );
        }
    }

    #[test]
    fn conv_bands_give_the_same_result_as_one_band() {
        // 1200 x 400 output pixels of 3x3x40 patches: more than MAX_COLUMNS, so bands.
        let c = conv(3, 1, 1, 40, 2);
        let x = map(1200, 400, 40, 3);
        let kk = 3 * 3 * 40;
        assert!(
            1200 * 400 * kk > MAX_COLUMNS,
            "the test must exercise banding"
        );
        let fast = c.forward(&x).expect("fits");
        // Spot-check rows at and across band boundaries against the reference.
        let band_rows = MAX_COLUMNS / (400 * kk);
        for oy in [0, band_rows - 1, band_rows, band_rows + 1, 1199] {
            let sub = FeatureMap {
                h: 3,
                w: 400,
                c: 40,
                data: (0..3)
                    .flat_map(|dy| {
                        let iy = oy as i64 - 1 + dy;
                        if !(0..1200).contains(&iy) {
                            vec![0.0; 400 * 40]
                        } else {
                            let i = iy as usize * 400 * 40;
                            x.data[i..i + 400 * 40].to_vec()
                        }
                    })
                    .collect(),
            };
            let slow = conv_reference(&c, &sub);
            // Row 1 of the 3-row sub-map is output row `oy`.
            let slow_row = &slow[400 * 2..400 * 2 * 2];
            let fast_row = &fast.data[oy * 400 * 2..(oy + 1) * 400 * 2];
            for (a, b) in fast_row.iter().zip(slow_row) {
                assert!((*a as f64 - b).abs() < 1e-4, "row {oy}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn conv_refuses_an_input_smaller_than_the_kernel() {
        assert!(conv(11, 4, 2, 3, 2).forward(&map(6, 20, 3, 1)).is_none());
    }

    #[test]
    fn max_pool_matches_a_direct_window_maximum() {
        let x = map(9, 12, 3, 5);
        let y = max_pool(&x, 3, 2).expect("fits");
        assert_eq!((y.h, y.w, y.c), (4, 5, 3));
        for oy in 0..y.h {
            for ox in 0..y.w {
                for c in 0..3 {
                    let mut m = f32::NEG_INFINITY;
                    for iy in 2 * oy..2 * oy + 3 {
                        for ix in 2 * ox..2 * ox + 3 {
                            m = m.max(x.data[(iy * 12 + ix) * 3 + c]);
                        }
                    }
                    assert_eq!(y.data[(oy * y.w + ox) * 3 + c], m);
                }
            }
        }
        assert!(max_pool(&map(2, 9, 1, 1), 3, 2).is_none());
    }
}
