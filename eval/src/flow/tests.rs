//! Tests of model flow: exact flow of a translation, compositing weights, and the
//! depth-consistency validity (occlusion and its negative control).

use super::*;

/// `g` with its centres replaced by `means` (the same Gaussians a time step later).
fn moved(g: &[Tensor<f32>; 5], means: Vec<f32>) -> [Tensor<f32>; 5] {
    let mut out = g.clone();
    out[0] = Tensor::from_vec(means, g[0].shape());
    out
}

/// The rows of `a` followed by those of `b`.
fn cat(a: &[Tensor<f32>; 5], b: &[Tensor<f32>; 5]) -> [Tensor<f32>; 5] {
    std::array::from_fn(|i| {
        let mut shape = a[i].shape().to_vec();
        shape[0] += b[i].shape()[0];
        Tensor::from_vec([a[i].data(), b[i].data()].concat(), &shape)
    })
}

/// A flat, nearly opaque Gaussian (scale `s x s x 1e-4`, opacity 0.99) at `(x, y, z)`.
fn flat(x: f32, y: f32, z: f32, s: f32) -> [Tensor<f32>; 5] {
    let mut g = flat_gaussian(x, y, z);
    g[1] = Tensor::from_vec(vec![s, s, 1e-4], &[1, 3]);
    g
}

/// A camera at the origin looking down +z (OpenCV axes), `size x size` pixels.
fn camera(size: u32) -> Camera {
    let f = size as f64;
    let eye = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let c = f / 2.0;
    Camera::new(size, size, f, f, c, c, eye).expect("camera")
}

/// One flat, wide, nearly opaque Gaussian at depth `z` in the image-plane-parallel
/// plane (scale 0.6 x 0.6 x 1e-4, opacity 0.99), grey colour.
fn flat_gaussian(x: f32, y: f32, z: f32) -> [Tensor<f32>; 5] {
    [
        Tensor::from_vec(vec![x, y, z], &[1, 3]),
        Tensor::from_vec(vec![0.6, 0.6, 1e-4], &[1, 3]),
        Tensor::from_vec(vec![1.0, 0.0, 0.0, 0.0], &[1, 4]),
        Tensor::from_vec(vec![0.99], &[1]),
        Tensor::from_vec(vec![0.0; 3], &[1, 1, 3]),
    ]
}

/// A plane translating parallel to the image at depth `z` by `(dx, dy)` in world
/// units moves every point it images by exactly `(f dx / z, f dy / z)` pixels: the
/// model flow must equal that wherever the Gaussian covers the pixel, and be valid
/// there (nothing covers the plane).
#[test]
fn a_translating_plane_gives_its_exact_flow() {
    let cam = camera(48);
    let (z, dx, dy) = (4.0f32, 0.05f32, -0.03f32);
    let now = flat_gaussian(0.1, -0.05, z);
    let next = moved(&now, vec![0.1 + dx, -0.05 + dy, z]);
    let settings = RenderSettings::default();
    let flow = model_flow(&now, &next, &cam, &settings);
    let want = [48.0 * dx / z, 48.0 * dy / z];
    let alpha = render_tensors(&now[0], &now[1], &now[2], &now[3], &now[4], &cam, &settings).alpha;
    let mut covered = 0;
    for (i, px) in flow.data().chunks_exact(3).enumerate() {
        if alpha.data()[i] > 0.5 {
            covered += 1;
            assert_eq!(px[2], 1.0, "pixel {i}: the translating plane stays visible");
            assert!(
                (px[0] - want[0]).abs() < 1e-4,
                "dx {} vs {}",
                px[0],
                want[0]
            );
            assert!(
                (px[1] - want[1]).abs() < 1e-4,
                "dy {} vs {}",
                px[1],
                want[1]
            );
        } else if alpha.data()[i] < MIN_ALPHA {
            assert_eq!((px[0], px[1]), (0.0, 0.0), "background moves");
        }
    }
    assert!(covered > 200, "the Gaussian covers only {covered} pixels");
}

/// Two overlapping Gaussians moving in opposite directions: where both cover a
/// pixel the flow is the weighted mean of their displacements, the front one's
/// weight `a1` and the back one's `(1 - a1) a2` (written out per pixel here from
/// the two single-Gaussian alpha maps, independently of the two-render encoding).
/// Negative control: the unweighted mean of the displacements is far from it.
#[test]
fn overlapping_gaussians_composite_with_the_colour_weights() {
    let cam = camera(40);
    let settings = RenderSettings::default();
    let front = flat_gaussian(0.0, 0.0, 3.0);
    let back = flat_gaussian(0.2, 0.1, 5.0);
    let both = cat(&front, &back);
    let next = moved(&both, vec![0.03, 0.0, 3.0, 0.15, 0.14, 5.0]);
    let flow = model_flow(&both, &next, &cam, &settings);
    let d = screen_displacements(&cam, &both[0], &next[0]);
    let single = |g: &[Tensor<f32>; 5]| {
        render_tensors(&g[0], &g[1], &g[2], &g[3], &g[4], &cam, &settings).alpha
    };
    let (a1, a2) = (single(&front), single(&back));
    let (mut checked, mut unweighted_off) = (0, 0.0f64);
    for i in 0..40 * 40 {
        let w1 = f64::from(a1.data()[i]);
        let w2 = (1.0 - w1) * f64::from(a2.data()[i]);
        if w1 + w2 < 0.05 {
            continue;
        }
        checked += 1;
        for (c, (d0, d1)) in d[0].iter().zip(&d[1]).enumerate() {
            let want = (w1 * d0 + w2 * d1) / (w1 + w2);
            let got = f64::from(flow.data()[3 * i + c]);
            assert!(
                (got - want).abs() < 2e-4,
                "pixel {i} channel {c}: {got} vs {want}"
            );
            if w1 > 0.05 && w2 > 0.05 {
                // Negative control: ignoring the weights would be caught.
                let plain = (d0 + d1) / 2.0;
                unweighted_off = unweighted_off.max((got - plain).abs());
            }
        }
    }
    assert!(checked > 300, "only {checked} pixels checked");
    assert!(
        unweighted_off > 0.05,
        "the scene cannot tell weighted from plain means"
    );
}

/// A wide static Gaussian at depth 5 (screen sigma 19 px, centre pixel (40, 32)) and a
/// small one at depth `z` (screen sigma 4.3 px) that enters the 64 x 64 image from far
/// left at `t` to end centred on pixel (38, 32) at `t + 1`. Returns the model flow and
/// the single-Gaussian alpha maps: static at `t`, mover at `t + 1`.
fn passing(z: f32) -> (Tensor<f32>, Tensor<f32>, Tensor<f32>) {
    let cam = camera(64);
    let settings = RenderSettings::default();
    let world = |u: f32, depth: f32| (u - 32.0) * depth / 64.0;
    let still = flat(world(40.0, 5.0), 0.0, 5.0, 1.5);
    let start = flat(world(-30.0, z), 0.0, z, 0.2 * z / 3.0);
    let end = moved(&start, vec![world(38.0, z), 0.0, z]);
    let flow = model_flow(&cat(&still, &start), &cat(&still, &end), &cam, &settings);
    let alpha = |g: &[Tensor<f32>; 5]| {
        render_tensors(&g[0], &g[1], &g[2], &g[3], &g[4], &cam, &settings).alpha
    };
    assert!(
        alpha(&start).data().iter().all(|&a| a == 0.0),
        "mover in view at t"
    );
    (flow, alpha(&still), alpha(&end))
}

/// Occlusion: a Gaussian at depth 3 passes in front of the static one at depth 5.
/// The static surface's pixels that the mover covers at `t + 1` (mover alpha > 0.5,
/// static alpha > 0.5, so the composited depth there is at most 3.75 against the
/// predicted 5) are invalid; those it stays clear of (mover alpha 0) are valid.
#[test]
fn a_gaussian_passing_in_front_invalidates_the_pixels_it_covers() {
    let (flow, still, mover) = passing(3.0);
    let (mut covered, mut clear) = (0, 0);
    for (i, px) in flow.data().chunks_exact(3).enumerate() {
        if still.data()[i] <= 0.5 {
            continue;
        }
        assert_eq!(
            (px[0], px[1]),
            (0.0, 0.0),
            "pixel {i}: the static surface moves"
        );
        if mover.data()[i] > 0.5 {
            covered += 1;
            assert_eq!(px[2], 0.0, "pixel {i} is covered at t + 1 but valid");
        } else if mover.data()[i] == 0.0 {
            clear += 1;
            assert_eq!(px[2], 1.0, "pixel {i} stays visible but is invalid");
        }
    }
    assert!(covered > 40, "only {covered} covered pixels");
    assert!(clear > 40, "only {clear} clear pixels");
}

/// Negative control: the same motion with the mover at depth 7, behind the static
/// Gaussian. Where the static one is nearly opaque (alpha > 0.95) it still hides the
/// mover, its composited depth stays within 5 % of 5 and every such pixel is valid,
/// although the mover's own alpha there is above 0.5 as in the occlusion test.
#[test]
fn a_gaussian_passing_behind_leaves_the_front_surface_valid() {
    let (flow, still, mover) = passing(7.0);
    let mut behind = 0;
    for (i, px) in flow.data().chunks_exact(3).enumerate() {
        if still.data()[i] > 0.95 && mover.data()[i] > 0.5 {
            behind += 1;
            assert_eq!(px[2], 1.0, "pixel {i}: a surface behind invalidated it");
        }
    }
    assert!(behind > 20, "only {behind} pixels with the mover behind");
}

/// Out of view and appearing: a plane that leaves the image is invalid where its
/// flow lands outside, and background pixels that it covers at `t + 1` are invalid
/// while background pixels that stay empty are valid (the exact flow's rules).
#[test]
fn leaving_the_image_and_newly_covered_background_are_invalid() {
    let cam = camera(48);
    let settings = RenderSettings::default();
    // Centred on pixel column 28 at t and 50 (outside the 48 px image) at t + 1.
    let world = |u: f32| (u - 24.0) * 4.0 / 48.0;
    let now = flat(world(28.0), 0.0, 4.0, 0.25);
    let next = moved(&now, vec![world(50.0), 0.0, 4.0]);
    let flow = model_flow(&now, &next, &cam, &settings);
    let alpha = |g: &[Tensor<f32>; 5]| {
        render_tensors(&g[0], &g[1], &g[2], &g[3], &g[4], &cam, &settings).alpha
    };
    let (a0, a1) = (alpha(&now), alpha(&next));
    let (mut left, mut appeared, mut empty) = (0, 0, 0);
    for (i, px) in flow.data().chunks_exact(3).enumerate() {
        let x = (i % 48) as f32 + 0.5;
        if a0.data()[i] > 0.5 && x + px[0] >= 48.0 {
            left += 1;
            assert_eq!(px[2], 0.0, "pixel {i} lands outside but is valid");
        } else if a0.data()[i] < MIN_ALPHA {
            if a1.data()[i] >= MIN_ALPHA {
                appeared += 1;
                assert_eq!(px[2], 0.0, "pixel {i} is covered at t + 1 but valid");
            } else {
                empty += 1;
                assert_eq!(px[2], 1.0, "empty pixel {i} is invalid");
            }
        }
    }
    assert!(
        left > 10 && appeared > 10 && empty > 100,
        "{left} {appeared} {empty}"
    );
}
