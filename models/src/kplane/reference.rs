//! The slow, independently written oracle of [`super::PlaneSample`]'s forward.

use maaf_autodiff::Tensor;

use super::sample::lookup;
use super::{FieldQuery, KPlaneField};

/// Slow oracle of [`super::PlaneSample`]'s forward, built independently: a level-l texel is
/// the mean of the `2^l x 2^l` block of level-0 texels it covers, and bilinear
/// interpolation is a sum of hat functions `max(0, 1 - |i - x|)` over every texel at
/// the coordinate clamped to the texel-centre range (which equals clamp-to-edge).
pub fn reference_sample(
    field: &KPlaneField,
    planes: &[Tensor<f64>],
    query: &FieldQuery,
) -> Tensor<f64> {
    let c = field.config.channels;
    let n = query.coords.len();
    let mut out = vec![0.0; n * c];
    for (p, plane) in planes.iter().enumerate() {
        let g = field.geom(p);
        let texel = |l: usize, ix: usize, iy: usize, k: usize| -> f64 {
            let b = 1usize << l;
            let (mut sum, mut cnt) = (0.0, 0.0);
            for y in iy * b..((iy + 1) * b).min(g.height) {
                for x in ix * b..((ix + 1) * b).min(g.width) {
                    sum += plane.data()[(y * g.width + x) * c + k];
                    cnt += 1.0;
                }
            }
            sum / cnt
        };
        let bilinear = |l: usize, u: f64, v: f64, k: usize| -> f64 {
            let (w, h) = g.dims(l);
            let x = (u * w as f64 - 0.5).clamp(0.0, (w - 1) as f64);
            let y = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
            let mut s = 0.0;
            for iy in 0..h {
                let wy = (1.0 - (iy as f64 - y).abs()).max(0.0);
                for ix in 0..w {
                    let wx = (1.0 - (ix as f64 - x).abs()).max(0.0);
                    if wx * wy > 0.0 {
                        s += wx * wy * texel(l, ix, iy, k);
                    }
                }
            }
            s
        };
        for i in 0..n {
            let (u, v, level) = lookup(query, i, p);
            let level = level.clamp(0.0, (g.levels - 1) as f64);
            let l0 = level.floor() as usize;
            let f = level - l0 as f64;
            for k in 0..c {
                let mut val = (1.0 - f) * bilinear(l0, u, v, k);
                if f > 0.0 {
                    val += f * bilinear(l0 + 1, u, v, k);
                }
                out[i * c + k] += val;
            }
        }
    }
    Tensor::from_vec(out, &[n, c])
}
