//! The NeRF positional encoding (Mildenhall et al. 2020, Eq. 4; the `get_embedder` of
//! NeRF, Deformable-3DGS and SaRO-GS with `include_input` and log sampling).

use maaf_autodiff::{Float, Tensor};

/// `gamma(p) = [p, sin(2^0 p), cos(2^0 p), ..., sin(2^(F-1) p), cos(2^(F-1) p)]` per
/// row of `values` (`rows x cols`, row-major), each block `cols` wide, as a constant
/// `[rows, cols (1 + 2F)]` tensor (computed in f64, then cast).
pub fn positional_encoding<T: Float>(values: &[f64], cols: usize, freqs: usize) -> Tensor<T> {
    assert!(
        cols > 0 && values.len().is_multiple_of(cols),
        "positional_encoding: {} values are not rows of {cols}",
        values.len()
    );
    let rows = values.len() / cols;
    let width = cols * (1 + 2 * freqs);
    let mut out = vec![T::zero(); rows * width];
    for (row, o) in values.chunks_exact(cols).zip(out.chunks_exact_mut(width)) {
        encode_row(row, freqs, o);
    }
    Tensor::from_vec(out, &[rows, width])
}

/// `gamma(p)` of one row `p` into `out` (`len(p) (1 + 2F)` values, the layout of
/// [`positional_encoding`]), computed in f64, then cast.
pub fn encode_row<T: Float>(p: &[f64], freqs: usize, out: &mut [T]) {
    let c = p.len();
    for (o, &v) in out[..c].iter_mut().zip(p) {
        *o = T::of(v);
    }
    for k in 0..freqs {
        let f = (1u64 << k) as f64;
        let (sin, cos) = out[c * (1 + 2 * k)..c * (3 + 2 * k)].split_at_mut(c);
        for ((s, co), &v) in sin.iter_mut().zip(cos).zip(p) {
            *s = T::of((f * v).sin());
            *co = T::of((f * v).cos());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_input_then_sin_cos_per_octave() {
        let e = positional_encoding::<f64>(&[0.5, -1.0, 0.25, 1.0, 2.0, 3.0], 3, 2);
        assert_eq!(e.shape(), &[2, 15]);
        let r = &e.data()[..15];
        assert_eq!(&r[..3], &[0.5, -1.0, 0.25]);
        assert_eq!(r[3], 0.5f64.sin());
        assert_eq!(r[5], 0.25f64.sin());
        assert_eq!(r[6], 0.5f64.cos());
        assert_eq!(r[9], 1.0f64.sin());
        assert_eq!(r[14], 0.5f64.cos());
        assert_eq!(e.data()[15 + 13], 4.0f64.cos());
    }
}
