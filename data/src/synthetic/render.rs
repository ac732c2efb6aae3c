//! Supersampled ray casting of the analytic scene and its exact forward flow.
//!
//! A pixel `(x, y)` covers `[x, x + 1) x [y, y + 1)` in pixel coordinates (centre at
//! `x + 0.5`). It is sampled by `n x n` jittered samples, one uniformly placed in each of
//! the `n x n` strata; its straight RGBA is `a = covered / n^2` and
//! `rgb = (sum of shaded colours of covered samples) / covered`. Box-downsampling by `k`
//! then averages `(k n)^2` samples per pixel. Rays are only tested against the objects
//! whose projected bounding box overlaps the pixel's 16x16 tile.

use glam::{DMat3, DVec3};
use maaf_splat::Camera;
use rayon::prelude::*;

use super::scene::{Hit, Posed, Scene, hash01};
use crate::image::Image;

const TILE: usize = 16;

/// World-space ray `(origin, unit direction)` through the point `(px, py)` in pixel
/// coordinates: camera-space direction `((px - cx) / fx, (py - cy) / fy, 1)`.
pub fn pixel_ray(cam: &Camera, px: f64, py: f64) -> (DVec3, DVec3) {
    let r_t: DMat3 = cam.rotation().transpose();
    let d = DVec3::new((px - cam.cx) / cam.fx, (py - cam.cy) / cam.fy, 1.0);
    (cam.center(), (r_t * d).normalize())
}

/// Precomputed ray generation for one camera.
struct RayGen {
    origin: DVec3,
    r_t: DMat3,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

impl RayGen {
    fn new(cam: &Camera) -> Self {
        RayGen {
            origin: cam.center(),
            r_t: cam.rotation().transpose(),
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
        }
    }

    fn dir(&self, px: f64, py: f64) -> DVec3 {
        (self.r_t * DVec3::new((px - self.cx) / self.fx, (py - self.cy) / self.fy, 1.0)).normalize()
    }
}

/// Per 16x16 tile, the objects whose projected (conservative) bounding box overlaps it.
fn tile_lists(posed: &Posed, cam: &Camera) -> (usize, Vec<Vec<u16>>) {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let mut lists = vec![Vec::new(); tw * th];
    for i in 0..posed.poses.len() {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let mut everywhere = false;
        for c in posed.corners(i) {
            let p = cam.to_camera(c);
            if p.z <= 1e-6 {
                everywhere = true;
                break;
            }
            let u = cam.fx * p.x / p.z + cam.cx;
            let v = cam.fy * p.y / p.z + cam.cy;
            lo = [lo[0].min(u), lo[1].min(v)];
            hi = [hi[0].max(u), hi[1].max(v)];
        }
        let (x0, x1, y0, y1) = if everywhere {
            (0, tw, 0, th)
        } else {
            let clampt = |v: f64, n: usize| ((v / TILE as f64).floor().max(0.0) as usize).min(n);
            (
                clampt(lo[0] - 1.0, tw),
                clampt(hi[0] + 1.0, tw - 1) + 1,
                clampt(lo[1] - 1.0, th),
                clampt(hi[1] + 1.0, th - 1) + 1,
            )
        };
        if !everywhere
            && (hi[0] < -1.0 || hi[1] < -1.0 || lo[0] > w as f64 + 1.0 || lo[1] > h as f64 + 1.0)
        {
            continue;
        }
        for ty in y0..y1 {
            for tx in x0..x1 {
                lists[ty * tw + tx].push(i as u16);
            }
        }
    }
    (tw, lists)
}

/// Colour range (max - min over samples, any channel) above which a pixel is refined
/// (half an 8-bit step would be 1/510; 1/128 catches every texture edge of the scene).
const REFINE_RANGE: f64 = 1.0 / 128.0;

/// Result of sampling one pixel: sums over covered samples and a "needs more" flag.
#[derive(Clone, Copy, Default)]
struct PixelSamples {
    sum: [f64; 3],
    covered: u32,
    moving: u32,
    total: u32,
    busy: bool,
}

impl PixelSamples {
    fn rgba(&self) -> [f32; 4] {
        if self.covered == 0 {
            return [0.0; 4];
        }
        let c = self.covered as f64;
        [
            (self.sum[0] / c).clamp(0.0, 1.0) as f32,
            (self.sum[1] / c).clamp(0.0, 1.0) as f32,
            (self.sum[2] / c).clamp(0.0, 1.0) as f32,
            (c / self.total as f64) as f32,
        ]
    }

    /// Fraction of the pixel's samples that see a moving object.
    fn moving_fraction(&self) -> f32 {
        (self.moving as f64 / self.total as f64) as f32
    }
}

/// Renders straight RGBA `[H, W, 4]` of the scene at time `t` seen by `cam`, with up to
/// `n x n` jittered samples per pixel (jitter hashed from `seed` and the pixel, so the
/// result does not depend on the thread count).
///
/// Sampling is adaptive: every pixel first gets `2 x 2` jittered samples; a pixel whose
/// samples disagree (different objects, partial coverage, or a colour range above 1/128)
/// is re-rendered with the full `n x n` samples. Flat pixels (inside a checker square,
/// on plain paper, or empty) keep their 4-sample mean, which is exact there; edges, thin
/// bars and sub-pixel texture get all `n^2` samples. A feature thin enough to slip
/// between all 4 coarse samples covers little of that pixel, so the error this leaves is
/// small and unstructured (noise, not aliasing); `n = 2` or less disables refinement.
pub fn render_rgba(scene: &Scene, cam: &Camera, t: f64, n: u32, seed: u64) -> Image {
    render_layers(scene, cam, t, n, seed).0
}

/// [`render_rgba`] plus the moving-object coverage of every pixel from the same samples:
/// a `[H, W, 1]` image whose value is the fraction of the pixel's samples that hit an
/// object whose motion is not static (`Motion::is_static`); rays that hit nothing count
/// as static. It is `0` on static pixels, `1` inside a moving object and in between on
/// its silhouette, and box-downsamples to the coverage of the larger pixel.
pub fn render_layers(scene: &Scene, cam: &Camera, t: f64, n: u32, seed: u64) -> (Image, Image) {
    let posed = scene.at(t);
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (tw, lists) = tile_lists(&posed, cam);
    let rays = RayGen::new(cam);
    let org = posed.from_origin(rays.origin);
    let moves: Vec<bool> = scene
        .objects
        .iter()
        .map(|o| !o.motion.is_static())
        .collect();
    let n = n.max(1) as usize;
    let salt = seed as i64;
    let sample_pixel = |x: usize, y: usize, m: usize, pass: i64| -> PixelSamples {
        let list = &lists[(y / TILE) * tw + x / TILE];
        let mut out = PixelSamples {
            total: (m * m) as u32,
            ..Default::default()
        };
        if list.is_empty() {
            return out;
        }
        let inv = 1.0 / m as f64;
        let mut rng = (hash01((y * w + x) as i64, pass, salt) * (1u64 << 53) as f64) as u64 | 1;
        let mut next = || {
            // xorshift64*: uniform in [0, 1) from the top 53 bits.
            rng ^= rng >> 12;
            rng ^= rng << 25;
            rng ^= rng >> 27;
            (rng.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut first_obj: Option<usize> = None;
        let mut mixed = false;
        for j in 0..m {
            for i in 0..m {
                let px = x as f64 + (i as f64 + next()) * inv;
                let py = y as f64 + (j as f64 + next()) * inv;
                match posed.trace_from(&org, rays.dir(px, py), list) {
                    Some(hit) => {
                        let c = posed.shade(&hit);
                        for k in 0..3 {
                            out.sum[k] += c[k];
                            lo[k] = lo[k].min(c[k]);
                            hi[k] = hi[k].max(c[k]);
                        }
                        out.covered += 1;
                        out.moving += u32::from(moves[hit.object]);
                        match first_obj {
                            None => first_obj = Some(hit.object),
                            Some(o) if o != hit.object => mixed = true,
                            _ => {}
                        }
                    }
                    None => mixed |= first_obj.is_some(),
                }
            }
        }
        let range = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        out.busy = mixed || (out.covered > 0 && out.covered < out.total) || range > REFINE_RANGE;
        out
    };

    let coarse = n.min(2);
    let mut first = vec![PixelSamples::default(); w * h];
    first.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, px) in row.iter_mut().enumerate() {
            *px = sample_pixel(x, y, coarse, 0);
        }
    });
    let mut data = vec![0.0f32; w * h * 4];
    let mut mask = vec![0.0f32; w * h];
    data.par_chunks_mut(w * 4)
        .zip(mask.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (row, mrow))| {
            for x in 0..w {
                let s = if n > coarse && first[y * w + x].busy {
                    sample_pixel(x, y, n, 1)
                } else {
                    first[y * w + x]
                };
                row[x * 4..x * 4 + 4].copy_from_slice(&s.rgba());
                mrow[x] = s.moving_fraction();
            }
        });
    let image = |channels, data| Image {
        width: cam.width,
        height: cam.height,
        channels,
        data,
    };
    (image(4, data), image(1, mask))
}

/// The surface seen through the centre of pixel `(x, y)` at time `t`, if any.
pub fn trace_pixel(scene: &Scene, cam: &Camera, t: f64, x: u32, y: u32) -> Option<Hit> {
    let (o, d) = pixel_ray(cam, x as f64 + 0.5, y as f64 + 0.5);
    scene.at(t).trace_all(o, d)
}

/// Exact forward flow from time `t0` to `t1` for a fixed camera, `[H, W, 3]` (see
/// [`crate::flow`]): the surface point `x_local` seen at the centre of each pixel at
/// `t0` is moved rigidly with its object, `X1 = R(t1) x_local + p(t1)`, and projected;
/// flow = projection - pixel centre. Valid (`1`) when the ray through that projection at
/// `t1` hits the same object at the same local point (within `1e-6`), i.e. the point is
/// neither occluded nor outside the image; pixels seeing nothing at `t0` have flow 0 and
/// are valid when they still see nothing at `t1`.
pub fn forward_flow(scene: &Scene, cam: &Camera, t0: f64, t1: f64) -> Image {
    let (p0, p1) = (scene.at(t0), scene.at(t1));
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (tw0, lists0) = tile_lists(&p0, cam);
    let (tw1, lists1) = tile_lists(&p1, cam);
    let rays = RayGen::new(cam);
    let (o0, o1) = (p0.from_origin(rays.origin), p1.from_origin(rays.origin));
    let mut data = vec![0.0f32; w * h * 3];
    data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            let list0 = &lists0[(y / TILE) * tw0 + x / TILE];
            let out = &mut row[x * 3..x * 3 + 3];
            let Some(hit) = p0.trace_from(&o0, rays.dir(cx, cy), list0) else {
                let list1 = &lists1[(y / TILE) * tw1 + x / TILE];
                let still_empty = p1.trace_from(&o1, rays.dir(cx, cy), list1).is_none();
                out[2] = if still_empty { 1.0 } else { 0.0 };
                continue;
            };
            let world1 = p1.poses[hit.object].to_world(hit.local);
            let Some((u, v, _)) = cam.project(world1) else {
                continue; // behind the camera: invalid, flow 0
            };
            out[0] = (u - cx) as f32;
            out[1] = (v - cy) as f32;
            if u < 0.0 || v < 0.0 || u >= w as f64 || v >= h as f64 {
                continue;
            }
            let list1 = &lists1[(v as usize / TILE) * tw1 + u as usize / TILE];
            let seen = p1.trace_from(&o1, rays.dir(u, v), list1);
            let same = seen
                .is_some_and(|s| s.object == hit.object && (s.local - hit.local).length() < 1e-6);
            out[2] = if same { 1.0 } else { 0.0 };
        }
    });
    Image {
        width: cam.width,
        height: cam.height,
        channels: 3,
        data,
    }
}
