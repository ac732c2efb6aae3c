//! AbsGS's densification statistic from the rasterizer's backward: the sum over pixels
//! of the absolute per-pixel gradients of the screen means, filled only when requested.

use super::*;

/// Cotangents of (image, alpha, depth) that are zero except at pixel `only` (all
/// pixels when `None`): fixed pseudo-random values of both signs.
fn pixel_seeds(only: Option<usize>) -> [Tensor<f64>; 3] {
    let (w, h) = (W as usize, H as usize);
    let val = |p: usize, k: usize| {
        let on = only.is_none_or(|q| q == p);
        if on {
            ((p * 7 + k * 13) % 11) as f64 / 5.0 - 1.0
        } else {
            0.0
        }
    };
    [
        Tensor::from_vec(
            (0..h * w * 3).map(|i| val(i / 3, i % 3)).collect(),
            &[h, w, 3],
        ),
        Tensor::from_vec((0..h * w).map(|p| val(p, 3)).collect(), &[h, w]),
        Tensor::from_vec((0..h * w).map(|p| 0.1 * val(p, 4)).collect(), &[h, w]),
    ]
}

/// `dL/d means2d` of the loss seeded by `seeds` through `outputs`.
fn seeded_grad<'t>(
    t: &'t Tape<f64>,
    outputs: &[Var<'t, f64>],
    means2d: Var<'t, f64>,
    seeds: [Tensor<f64>; 3],
) -> Vec<f64> {
    let pairs: Vec<_> = outputs.iter().copied().zip(seeds).collect();
    let g = t.backward_from(&pairs).unwrap();
    g.wrt(means2d).unwrap().data().to_vec()
}

/// The first five of `inputs` (all but the radii) as variables on `t`.
fn raster_vars<'t>(t: &'t Tape<f64>, inputs: &[Tensor<f64>]) -> Vec<Var<'t, f64>> {
    inputs[..5].iter().map(|v| t.var(v.clone())).collect()
}

/// AbsGS's statistic from the rasterizer's backward equals the sum over pixels of
/// the absolute per-pixel gradients `|dL_p/d means2d|`, each computed on its own:
/// with the smooth cutoff by the primitive-built reference compositor, with the hard
/// cutoff by the op itself seeded one pixel at a time (its gradient is checked above).
/// It is at least `|dL/d means2d|` and, with both signs in play, larger somewhere.
#[test]
fn abs_means2d_is_the_sum_of_absolute_per_pixel_gradients() {
    let inputs = raster_inputs(Filter2d::Mip);
    let n = inputs[3].len();
    let np = (W * H) as usize;
    for cut in [AlphaCutoff::Smooth, AlphaCutoff::Hard] {
        let t = Tape::new();
        let x = raster_vars(&t, &inputs);
        let r = rasterized(&x, &inputs[5], cut);
        r.abs_means2d.request();
        assert!(r.abs_means2d.take().is_none(), "filled before the backward");
        let outputs = [r.image, r.alpha, r.depth];
        let plain = seeded_grad(&t, &outputs, x[0], pixel_seeds(None));
        let fast = r.abs_means2d.take().expect("requested statistic");
        assert_eq!(fast.shape(), &[n, 2]);

        let mut want = vec![0.0; 2 * n];
        for p in 0..np {
            let t = Tape::new();
            let x = raster_vars(&t, &inputs);
            let outs = match cut {
                AlphaCutoff::Smooth => reference_raster(&t, &x),
                AlphaCutoff::Hard => raster(&x, &inputs[5], cut),
            };
            let g = seeded_grad(&t, &outs, x[0], pixel_seeds(Some(p)));
            for (w, v) in want.iter_mut().zip(g) {
                *w += v.abs();
            }
        }
        let mut larger = 0;
        for i in 0..2 * n {
            let got = fast.data()[i];
            assert!(
                (got - want[i]).abs() <= 1e-9 * (1.0 + want[i]),
                "{cut:?} entry {i}: {got} vs per-pixel {}",
                want[i]
            );
            assert!(
                got >= plain[i].abs() - 1e-12,
                "{cut:?} entry {i} below |grad|"
            );
            if got > plain[i].abs() * 1.01 + 1e-9 {
                larger += 1;
            }
        }
        assert!(larger > 0, "{cut:?}: no entry where pulls cancel");
    }
}

#[test]
fn abs_means2d_is_left_empty_unless_requested() {
    let inputs = raster_inputs(Filter2d::Mip);
    let t = Tape::new();
    let x = raster_vars(&t, &inputs);
    let r = rasterized(&x, &inputs[5], AlphaCutoff::Hard);
    seeded_grad(&t, &[r.image, r.alpha, r.depth], x[0], pixel_seeds(None));
    assert!(r.abs_means2d.take().is_none());
}
