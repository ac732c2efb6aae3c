//! Which pixels of a training view the objective sees (`loss_region`): all of them,
//! the background by the view's foreground mask (what a background layer is fitted
//! on), or a rectangle around the foreground (the foreground focus: the view is
//! rendered on that rectangle only).

use maaf_autodiff::Tensor;
use maaf_data::{Dataset, Image, Split};
use maaf_splat::Window;
use maaf_splat::compositing::TILE;

use crate::Error;

/// The smallest rectangle holding every pixel of `mask` (`[H, W, 1]` coverage) whose
/// coverage is at least one half, grown by `margin` pixels on each side, then outward
/// to the renderer's tile grid ([`TILE`]) and clipped to the image; `None` when no
/// pixel is. On the tile grid the window's render is exactly those pixels of the
/// whole view's ([`Window`]).
pub fn window_around(mask: &Image, margin: u32) -> Option<Window> {
    let (w, h) = (mask.width, mask.height);
    let (mut x_lo, mut y_lo, mut x_hi, mut y_hi) = (u32::MAX, u32::MAX, 0, 0);
    for y in 0..h {
        for x in 0..w {
            if mask.pixel(x, y)[0] >= 0.5 {
                x_lo = x_lo.min(x);
                y_lo = y_lo.min(y);
                x_hi = x_hi.max(x);
                y_hi = y_hi.max(y);
            }
        }
    }
    if x_lo > x_hi {
        return None;
    }
    let tile = TILE as u32;
    let down = |v: u32| v.saturating_sub(margin) / tile * tile;
    let up = |v: u32, end: u32| {
        (v + margin + 1)
            .div_ceil(tile)
            .saturating_mul(tile)
            .min(end)
    };
    let (x0, y0) = (down(x_lo), down(y_lo));
    Some(Window {
        x0,
        y0,
        width: up(x_hi, w) - x0,
        height: up(y_hi, h) - y0,
    })
}

/// The `window` of an `[H, W, C]` tensor.
pub fn crop(t: &Tensor<f32>, window: &Window) -> Tensor<f32> {
    let (w, c) = (t.shape()[1], t.shape()[2]);
    let (x0, y0) = (window.x0 as usize, window.y0 as usize);
    let (cw, ch) = (window.width as usize, window.height as usize);
    let mut out = Vec::with_capacity(cw * ch * c);
    for y in y0..y0 + ch {
        let row = (y * w + x0) * c;
        out.extend_from_slice(&t.data()[row..row + cw * c]);
    }
    Tensor::from_vec(out, &[ch, cw, c])
}

/// Share of a `width x height` view's pixels `window` holds.
pub fn share(window: &Window, width: u32, height: u32) -> f64 {
    f64::from(window.width) * f64::from(window.height) / (f64::from(width) * f64::from(height))
}

/// The target of a background fit: `(1 - m) gt + m render` per pixel, with `m` the
/// view's foreground coverage `[H, W, 1]`, so the objective's error vanishes where
/// the mask is foreground and is weighted by the background share elsewhere (the
/// render is the step's own value, a constant of the objective).
pub fn background_target(gt: &Tensor<f32>, render: &Tensor<f32>, mask: &Image) -> Tensor<f32> {
    let c = gt.shape()[2];
    let data = gt
        .data()
        .iter()
        .zip(render.data())
        .enumerate()
        .map(|(i, (&g, &r))| {
            let m = mask.data[i / c];
            (1.0 - m) * g + m * r
        })
        .collect();
    Tensor::from_vec(data, gt.shape())
}

/// Every training view's foreground coverage at `scale` ([`Dataset::train_foreground`]);
/// an error names the first view without a mask (a loss region needs them all).
pub fn training_masks(data: &Dataset, scale: f64) -> Result<Vec<Image>, Error> {
    (0..data.len(Split::Train))
        .map(|i| {
            data.train_foreground(i, scale)
                .map_err(|e| Error::Input(e.to_string()))?
                .ok_or_else(|| {
                    Error::Input(format!(
                        "{}: training view {i} has no foreground mask, which loss_region = background / foreground and a background layer need (the Dynamic 3D Gaussians layout's seg/)",
                        data.root().display()
                    ))
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mask(w: u32, h: u32, on: &[(u32, u32)]) -> Image {
        let mut m = Image::filled(w, h, 1, 0.0);
        for &(x, y) in on {
            m.data[(y * w + x) as usize] = 1.0;
        }
        m
    }

    #[test]
    fn window_holds_the_mask_grown_by_the_margin_on_the_tile_grid() {
        // Pixels x in 21..=25, y in 18..=20 grown by 2: x 19..=27, y 16..=22, then
        // out to the 16-pixel tiles: x 16..32, y 16..32 (clipped to 40 x 30: ..30).
        let m = mask(40, 30, &[(21, 18), (25, 20)]);
        let c = window_around(&m, 2).expect("mask has pixels");
        assert_eq!((c.x0, c.y0, c.width, c.height), (16, 16, 16, 14));
        let edge = mask(20, 10, &[(0, 0), (19, 9)]);
        let c = window_around(&edge, 4).expect("mask has pixels");
        assert_eq!((c.x0, c.y0, c.width, c.height), (0, 0, 20, 10));
        assert_eq!(window_around(&mask(4, 4, &[]), 3), None);
    }

    #[test]
    fn crop_of_a_tensor_matches_a_pixel_loop() {
        let t = Tensor::from_vec((0..6 * 5 * 2).map(|v| v as f32).collect(), &[5, 6, 2]);
        let c = Window {
            x0: 2,
            y0: 1,
            width: 3,
            height: 2,
        };
        let out = crop(&t, &c);
        assert_eq!(out.shape(), [2, 3, 2]);
        for y in 0..2 {
            for x in 0..3 {
                for ch in 0..2 {
                    let want = t.data()[((y + 1) * 6 + x + 2) * 2 + ch];
                    assert_eq!(out.data()[(y * 3 + x) * 2 + ch], want);
                }
            }
        }
    }

    #[test]
    fn background_target_keeps_background_and_takes_the_render_on_the_foreground() {
        let gt = Tensor::from_vec(vec![0.2f32; 2 * 2 * 3], &[2, 2, 3]);
        let render = Tensor::from_vec(vec![0.8f32; 2 * 2 * 3], &[2, 2, 3]);
        let mut m = Image::filled(2, 2, 1, 0.0);
        m.data = vec![0.0, 1.0, 0.5, 0.0];
        let t = background_target(&gt, &render, &m);
        let px = |i: usize| t.data()[3 * i];
        assert!((px(0) - 0.2).abs() < 1e-7 && (px(1) - 0.8).abs() < 1e-7);
        assert!((px(2) - 0.5).abs() < 1e-7 && (px(3) - 0.2).abs() < 1e-7);
    }
}
