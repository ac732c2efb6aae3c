//! Forward: the tiled fast path equals the per-pixel reference (reference.rs).
#![allow(clippy::unwrap_used)]

mod common;

use maaf_autodiff::Tensor;
use maaf_autodiff::check::compare;
use maaf_splat::{AlphaCutoff, Filter2d, RenderSettings, reference, render_tensors};

fn settings(filter2d: Filter2d, alpha_cutoff: AlphaCutoff, sh_degree: usize) -> RenderSettings {
    RenderSettings {
        background: [0.2, 0.5, 0.9],
        filter2d,
        sh_degree,
        alpha_cutoff,
        ..RenderSettings::default()
    }
}

fn check_scene(scene: &common::Scene<f32>, w: u32, h: u32, s: &RenderSettings, what: &str) {
    let cam = common::camera(w, h);
    let fast = render_tensors(
        &scene.means,
        &scene.scales,
        &scene.quats,
        &scene.opacity,
        &scene.sh,
        &cam,
        s,
    );
    let (img, alpha, depth) = reference::render(
        &scene.means,
        &scene.scales,
        &scene.quats,
        &scene.opacity,
        &scene.sh,
        &cam,
        s,
    );
    // Both run in f32 with differently ordered arithmetic (different covariance,
    // projection and power formulas); colours and alphas are O(1), so 1e-5 absolute
    // (~100 f32 ulps at 1.0) leaves room only for rounding. Depth
    // is O(5) world units, so it gets 5x the bound.
    for (name, a, b, tol) in [
        ("image", &fast.image, &img, 1e-5),
        ("alpha", &fast.alpha, &alpha, 1e-5),
        ("depth", &fast.depth, &depth, 5e-5),
    ] {
        let c = compare::<f32>(a, b, tol, 0.0);
        assert!(
            c.passed(),
            "{what}: {name} differs: max abs err {:.3e} at flat index {} ({} mismatches)",
            c.max_abs_err,
            c.worst_index,
            c.mismatches
        );
    }
    // The scene must actually draw something.
    assert!(
        fast.alpha.data().iter().any(|&a| a > 0.1),
        "{what}: empty image"
    );
}

#[test]
fn fast_path_matches_reference_on_random_scenes() {
    for seed in 0..4u64 {
        let deg = (seed % 4) as usize;
        let scene = common::random_scene::<f32>(60, deg, seed);
        for filter in [Filter2d::Classic, Filter2d::Mip] {
            for cut in [AlphaCutoff::Hard, AlphaCutoff::Smooth] {
                let s = settings(filter, cut, deg);
                check_scene(
                    &scene,
                    53,
                    41,
                    &s,
                    &format!("seed {seed} {filter:?} {cut:?}"),
                );
            }
        }
    }
}

#[test]
fn fast_path_matches_reference_on_hard_cases() {
    let scene = common::random_scene::<f32>(30, 3, 11).extend(&common::hard_cases(3));
    for filter in [Filter2d::Classic, Filter2d::Mip] {
        for cut in [AlphaCutoff::Hard, AlphaCutoff::Smooth] {
            let s = settings(filter, cut, 3);
            check_scene(
                &scene,
                64,
                48,
                &s,
                &format!("hard cases {filter:?} {cut:?}"),
            );
        }
    }
}

#[test]
fn many_layers_reach_the_transmittance_floor() {
    // 300 opaque Gaussians in a small image: most pixels stop early at T < 1e-4.
    let mut scene = common::random_scene::<f32>(300, 1, 5);
    scene.opacity = Tensor::full(&[300], 0.95);
    let s = settings(Filter2d::Mip, AlphaCutoff::Hard, 1);
    check_scene(&scene, 32, 32, &s, "dense");
}

#[test]
fn culled_gaussians_have_zero_radius() {
    let scene = common::hard_cases::<f32>(0);
    let cam = common::camera(64, 48);
    let f = render_tensors(
        &scene.means,
        &scene.scales,
        &scene.quats,
        &scene.opacity,
        &scene.sh,
        &cam,
        &RenderSettings::default(),
    );
    assert_eq!(f.radii[0], 0, "behind the camera");
    assert_eq!(f.radii[6], 0, "off-screen");
    assert!(f.radii[1] > 0 && f.radii[4] > 0 && f.radii[7] > 0);
}

/// A window on the tile grid renders exactly those pixels of the whole image (the
/// same Gaussians are binned to every tile), also for Gaussians whose centres lie
/// outside the window; a window off the grid differs only where tiles' lists differ.
#[test]
fn a_window_on_the_tile_grid_is_those_pixels_of_the_whole_render() {
    let scene = common::random_scene::<f32>(60, 3, 8);
    let (w, h) = (70, 52);
    let cam = common::camera(w, h);
    let whole_settings = settings(Filter2d::Mip, AlphaCutoff::Hard, 3);
    let render = |s: &RenderSettings| {
        render_tensors(
            &scene.means,
            &scene.scales,
            &scene.quats,
            &scene.opacity,
            &scene.sh,
            &cam,
            s,
        )
    };
    let whole = render(&whole_settings);
    let window = maaf_splat::Window {
        x0: 16,
        y0: 16,
        width: 40,
        height: 36,
    };
    let part = render(&RenderSettings {
        window: Some(window),
        ..whole_settings.clone()
    });
    assert_eq!(part.image.shape(), [36, 40, 3]);
    for y in 0..36 {
        for x in 0..40 {
            for c in 0..3 {
                let got = part.image.data()[(y * 40 + x) * 3 + c];
                let want = whole.image.data()[((y + 16) * w as usize + x + 16) * 3 + c];
                assert_eq!(got, want, "pixel ({x}, {y}) channel {c}");
            }
            let got = part.alpha.data()[y * 40 + x];
            assert_eq!(got, whole.alpha.data()[(y + 16) * w as usize + x + 16]);
        }
    }
}
