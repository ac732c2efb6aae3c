//! Integer box (area) downsampling and alpha compositing.
//!
//! The multi-scale ground truth of a straight-alpha RGBA image at integer factor `k` is
//!
//! 1. premultiply: `P = (r a, g a, b a, a)`;
//! 2. box-average `P` over each `k x k` block: `P'(i, j) = 1/k^2 sum_{dy, dx < k} P(k i + dy, k j + dx)`;
//! 3. composite on the background `bg`: `rgb = P'.rgb + bg (1 - P'.a)`.
//!
//! Because steps 2 and 3 are both linear in `P`, this equals compositing at the source
//! resolution and then averaging, for every background: it is the image a camera with
//! square pixels `k` times larger would record. Averaging *straight* RGBA (what
//! `cv2.resize(INTER_AREA)` does on D-NeRF's PNGs) instead lets the colour of
//! transparent pixels bleed into edges; a test pins the difference.

/// Multiplies the colour channels of straight RGBA (`[.., 4]`) by alpha, in place:
/// `(r, g, b, a) -> (r a, g a, b a, a)`.
pub fn premultiply(rgba: &mut [f32]) {
    for px in rgba.chunks_exact_mut(4) {
        let a = px[3];
        px[0] *= a;
        px[1] *= a;
        px[2] *= a;
    }
}

/// Box-downsamples a `[height, width, channels]` image by the integer factor `k`:
/// output pixel `(i, j)` channel `c` is the mean of the `k x k` source block
/// `rows k i .. k i + k`, `columns k j .. k j + k`, summed in f64 in raster order
/// (rows outer, columns inner) and divided by `k^2` once.
///
/// Returns `None` when `k == 0` or `k` does not divide both `width` and `height`
/// (callers turn that into an error naming the file). `k == 1` returns a copy.
pub fn box_downsample(
    src: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    k: usize,
) -> Option<Vec<f32>> {
    if k == 0
        || !width.is_multiple_of(k)
        || !height.is_multiple_of(k)
        || src.len() != width * height * channels
    {
        return None;
    }
    if k == 1 {
        return Some(src.to_vec());
    }
    let (ow, oh) = (width / k, height / k);
    let norm = 1.0 / (k * k) as f64;
    let mut out = vec![0.0f32; ow * oh * channels];
    let mut acc = vec![0.0f64; ow * channels];
    for oy in 0..oh {
        acc.iter_mut().for_each(|v| *v = 0.0);
        for dy in 0..k {
            let row = &src[(oy * k + dy) * width * channels..(oy * k + dy + 1) * width * channels];
            for ox in 0..ow {
                let a = &mut acc[ox * channels..(ox + 1) * channels];
                for dx in 0..k {
                    let p = &row[(ox * k + dx) * channels..(ox * k + dx + 1) * channels];
                    for (s, v) in a.iter_mut().zip(p) {
                        *s += *v as f64;
                    }
                }
            }
        }
        for (o, s) in out[oy * ow * channels..(oy + 1) * ow * channels]
            .iter_mut()
            .zip(&acc)
        {
            *o = (*s * norm) as f32;
        }
    }
    Some(out)
}

/// Composites premultiplied RGBA (`[.., 4]`) over a constant background:
/// `rgb = rgb_premultiplied + bg (1 - a)`, returning `[.., 3]`.
pub fn composite_premultiplied(rgba: &[f32], background: [f32; 3]) -> Vec<f32> {
    let mut out = Vec::with_capacity(rgba.len() / 4 * 3);
    for px in rgba.chunks_exact(4) {
        let t = 1.0 - px[3];
        out.push(px[0] + background[0] * t);
        out.push(px[1] + background[1] * t);
        out.push(px[2] + background[2] * t);
    }
    out
}

/// Moves an image composited on `from` onto the background `to`, given its coverage
/// `a` (`[.., 1]`, the premultiplied alpha the colour was composited with):
/// `rgb' = rgb + (1 - a) (to - from)`, which equals `P.rgb + to (1 - a)` (step 3 above
/// with `to`). Training on a random background per step composites the ground truth
/// this way (nerfstudio's `background_color = "random"`, 3DGS's `--random_background`).
pub fn recomposite(rgb: &[f32], coverage: &[f32], from: [f32; 3], to: [f32; 3]) -> Vec<f32> {
    let shift = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
    rgb.chunks_exact(3)
        .zip(coverage)
        .flat_map(|(px, &a)| {
            let t = 1.0 - a;
            [
                px[0] + shift[0] * t,
                px[1] + shift[1] * t,
                px[2] + shift[2] * t,
            ]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direct area average: for each output pixel, loop over its block and divide.
    fn direct(src: &[f32], w: usize, h: usize, c: usize, k: usize) -> Vec<f32> {
        let mut out = Vec::new();
        for oy in 0..h / k {
            for ox in 0..w / k {
                for ch in 0..c {
                    let mut s = 0.0f64;
                    for dy in 0..k {
                        for dx in 0..k {
                            s += src[((oy * k + dy) * w + ox * k + dx) * c + ch] as f64;
                        }
                    }
                    out.push((s * (1.0 / (k * k) as f64)) as f32);
                }
            }
        }
        out
    }

    fn pseudo_random(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 40) as f32) / (1u64 << 24) as f32
            })
            .collect()
    }

    #[test]
    fn matches_direct_area_average_exactly() {
        for &(w, h, c, k) in &[(12, 8, 4, 2), (12, 8, 3, 4), (9, 6, 4, 3), (5, 5, 1, 5)] {
            let src = pseudo_random(w * h * c, (w * 31 + k) as u64);
            let fast = box_downsample(&src, w, h, c, k).expect("divides");
            assert_eq!(fast, direct(&src, w, h, c, k), "w{w} h{h} c{c} k{k}");
        }
    }

    #[test]
    fn two_by_two_ones_and_zeros_is_half() {
        let src = [1.0, 0.0, 0.0, 1.0];
        assert_eq!(box_downsample(&src, 2, 2, 1, 2), Some(vec![0.5]));
        let src = [1.0, 1.0, 0.0, 0.0];
        assert_eq!(box_downsample(&src, 2, 2, 1, 2), Some(vec![0.5]));
    }

    #[test]
    fn refuses_factors_that_do_not_divide() {
        assert!(box_downsample(&[0.0; 6 * 4], 6, 4, 1, 4).is_none());
        assert!(box_downsample(&[0.0; 6 * 4], 6, 4, 1, 0).is_none());
        assert_eq!(box_downsample(&[0.25; 4], 2, 2, 1, 1), Some(vec![0.25; 4]));
    }

    /// Pins the compositing order: premultiply, average, then composite, which equals
    /// composite-then-average for any background, and differs from averaging straight
    /// RGBA when a transparent pixel carries a colour.
    #[test]
    fn compositing_order_is_premultiplied_average_then_composite() {
        // Block: opaque blue, and a fully transparent pixel whose stored colour is red.
        let straight = [0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
        let bg = [1.0, 1.0, 1.0];
        let mut p = straight.to_vec();
        premultiply(&mut p);
        // The 2x1 block is made a 2x2 block by repeating the row.
        let mut two_rows = p.clone();
        two_rows.extend_from_slice(&p);
        let avg = box_downsample(&two_rows, 2, 2, 4, 2);
        let ours = composite_premultiplied(&avg.expect("divides"), bg);
        // Half blue, half white background: (0.5, 0.5, 1.0).
        assert_eq!(ours, vec![0.5, 0.5, 1.0]);
        // Composite first, then average: same answer.
        let comp = composite_premultiplied(&p, bg);
        let mut two_rows = comp.clone();
        two_rows.extend_from_slice(&comp);
        assert_eq!(
            box_downsample(&two_rows, 2, 2, 3, 2),
            Some(vec![0.5, 0.5, 1.0])
        );
        // Straight-alpha averaging would give (0.5, 0, 0.5) * 0.5 + 0.5 = (0.75, 0.5, 0.75).
        let mut two_rows = straight.to_vec();
        two_rows.extend_from_slice(&straight);
        let s = box_downsample(&two_rows, 2, 2, 4, 2).expect("divides");
        let cv2_style: Vec<f32> = (0..3).map(|c| s[c] * s[3] + bg[c] * (1.0 - s[3])).collect();
        assert_eq!(cv2_style, vec![0.75, 0.5, 0.75]);
        assert_ne!(cv2_style, ours);
    }

    #[test]
    fn recomposite_equals_compositing_on_the_new_background() {
        let mut p = pseudo_random(6 * 5 * 4, 11);
        premultiply(&mut p);
        let coverage: Vec<f32> = p.chunks_exact(4).map(|px| px[3]).collect();
        let (from, to) = ([0.0, 0.0, 0.0], [0.9, 0.3, 0.6]);
        let moved = recomposite(&composite_premultiplied(&p, from), &coverage, from, to);
        let direct = composite_premultiplied(&p, to);
        assert_eq!(moved.len(), direct.len());
        for (x, y) in moved.iter().zip(&direct) {
            assert!((x - y).abs() < 1e-6, "{x} vs {y}");
        }
        // An opaque pixel keeps its colour; a fully transparent one becomes `to`.
        let rgb = [0.25, 0.5, 0.75, 0.0, 0.0, 0.0];
        let out = recomposite(&rgb, &[1.0, 0.0], from, to);
        assert_eq!(out, vec![0.25, 0.5, 0.75, 0.9, 0.3, 0.6]);
    }

    #[test]
    fn composite_then_downsample_equals_downsample_then_composite_on_random_data() {
        let (w, h, k) = (8, 8, 4);
        let mut p = pseudo_random(w * h * 4, 7);
        premultiply(&mut p);
        for bg in [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.2, 0.5, 0.9]] {
            let a = composite_premultiplied(&box_downsample(&p, w, h, 4, k).expect("k"), bg);
            let b = box_downsample(&composite_premultiplied(&p, bg), w, h, 3, k).expect("k");
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() < 1e-6, "{x} vs {y}");
            }
        }
    }
}
