//! Backward: every op and the whole chain against central finite differences in f64
//! (gradcheck) and against primitive-built references (check_vjp), plus a negative
//! control.
//!
//! Tolerances: gradcheck uses eps = 1e-6 in f64; for these smooth functions the
//! truncation error is ~eps^2 |f'''| and the rounding error ~1e-16 |f| / eps. The
//! chain maps world units to pixels (fx/z ~ 15-60) and goes through exp(-power), so
//! |f'''| can reach ~1e5 and |f| ~1e2 (depth-weighted sums): both errors stay below
//! ~1e-7 absolute. The tolerances are atol 1e-6 and rtol 1e-5: a wrong factor, sign or missing
//! term (the negative control) is off by >= 1e-2.
//!
//! AbsGS's statistic from the same backward is checked in `abs_means2d.rs`.
#![allow(clippy::unwrap_used)]

mod abs_means2d;
#[path = "../common/mod.rs"]
mod common;

use maaf_autodiff::check::{GradcheckConfig, check_vjp, gradcheck};
use maaf_autodiff::ops::concat;
use maaf_autodiff::{BackwardCtx, Op, Tape, Tensor, Var};
use maaf_splat::cov3d::quat_scale_to_cov;
use maaf_splat::project::project_ewa;
use maaf_splat::rasterize::{Rasterize, Rasterized, rasterize};
use maaf_splat::sh::sh_color;
use maaf_splat::{
    AlphaCutoff, Camera, Filter2d, GaussianVars, RenderSettings, Window, reference, render,
};

const W: u32 = 24;
const H: u32 = 20;

fn cfg() -> GradcheckConfig {
    GradcheckConfig::default().with_tol(1e-6, 1e-5)
}

fn flat<'t>(vs: &[Var<'t, f64>]) -> Var<'t, f64> {
    let parts: Vec<Var<'t, f64>> = vs
        .iter()
        .map(|v| {
            let n = v.value().len();
            v.reshape(&[n])
        })
        .collect();
    concat(&parts, 0)
}

fn cam() -> Camera {
    common::camera(W, H)
}

/// A small scene in view plus one Gaussian whose x/z is beyond the 1.3 tan(fov/2)
/// clamp (large enough to stay visible).
fn scene() -> common::Scene<f64> {
    let mut s = common::random_scene::<f64>(6, 3, 3);
    let extra = common::Scene {
        means: Tensor::from_vec(vec![2.7, 0.2, 0.3], &[1, 3]),
        scales: Tensor::from_vec(vec![0.9, 0.6, 0.7], &[1, 3]),
        quats: Tensor::from_vec(vec![0.9, 0.1, -0.2, 0.3], &[1, 4]),
        opacity: Tensor::from_vec(vec![0.6], &[1]),
        sh: common::random_scene::<f64>(1, 3, 99).sh,
    };
    s = s.extend(&extra);
    s
}

#[test]
fn quat_scale_to_cov_gradcheck_and_vjp() {
    let s = scene();
    let inputs = [s.quats.clone(), s.scales.clone()];
    gradcheck(|_, x| quat_scale_to_cov(x[0], x[1]), &inputs, &cfg()).assert_passed();
    check_vjp(
        |_, x| vec![quat_scale_to_cov(x[0], x[1])],
        |_, x| vec![reference::tape::quat_scale_to_cov(x[0], x[1])],
        &inputs,
        3,
        &cfg(),
    )
    .assert_passed();
}

fn cov6(s: &common::Scene<f64>) -> Tensor<f64> {
    let t = Tape::new();
    let c = quat_scale_to_cov(t.constant(s.quats.clone()), t.constant(s.scales.clone()));
    c.value().clone()
}

#[test]
fn project_gradcheck_and_vjp_both_filters() {
    let s = scene();
    let camera = cam();
    let inputs = [s.means.clone(), cov6(&s), s.opacity.clone()];
    {
        // The extra Gaussian is clamped in x (exercises the clamp branch).
        let t = Tape::new();
        let p = project_ewa(
            t.constant(inputs[0].clone()),
            t.constant(inputs[1].clone()),
            t.constant(inputs[2].clone()),
            &camera,
            Filter2d::Mip,
            0.2,
        );
        let r = p.radii.value();
        assert!(
            r.data().iter().all(|&r| r > 0.0),
            "all visible: {:?}",
            r.data()
        );
    }
    for filter in [Filter2d::Classic, Filter2d::Mip] {
        let camera = camera.clone();
        let c2 = camera.clone();
        let report = gradcheck(
            move |_, x| {
                let p = project_ewa(x[0], x[1], x[2], &camera, filter, 0.2);
                flat(&[p.means2d, p.conics, p.opacity, p.depths])
            },
            &inputs,
            &cfg(),
        );
        assert!(report.passed(), "{filter:?}: {report}");
        let c3 = c2.clone();
        let report = check_vjp(
            move |_, x| {
                let p = project_ewa(x[0], x[1], x[2], &c2, filter, 0.2);
                vec![p.means2d, p.conics, p.opacity, p.depths]
            },
            move |t, x| reference::tape::project(t, x[0], x[1], x[2], &c3, filter),
            &inputs,
            3,
            &cfg(),
        );
        assert!(report.passed(), "{filter:?}: {report}");
    }
}

#[test]
fn sh_color_gradcheck_and_vjp_every_degree() {
    let campos = {
        let c = cam().center();
        [c.x, c.y, c.z]
    };
    for deg in 0..=3 {
        let s = common::random_scene::<f64>(8, deg, 20 + deg as u64);
        let inputs = [s.means.clone(), s.sh.clone()];
        gradcheck(|_, x| sh_color(x[0], x[1], campos, deg), &inputs, &cfg()).assert_passed();
        check_vjp(
            |_, x| vec![sh_color(x[0], x[1], campos, deg)],
            |t, x| vec![reference::tape::sh_color(t, x[0], x[1], campos, deg)],
            &inputs,
            3,
            &cfg(),
        )
        .assert_passed();
    }
}

/// Projected rasterizer inputs of [`scene`]: means2d, conics, colours, opacity,
/// depths, radii.
fn raster_inputs(filter: Filter2d) -> Vec<Tensor<f64>> {
    let s = scene();
    let camera = cam();
    let t = Tape::new();
    let means = t.constant(s.means.clone());
    let cov = quat_scale_to_cov(t.constant(s.quats.clone()), t.constant(s.scales.clone()));
    let p = project_ewa(
        means,
        cov,
        t.constant(s.opacity.clone()),
        &camera,
        filter,
        0.2,
    );
    let c = camera.center();
    let colors = sh_color(means, t.constant(s.sh.clone()), [c.x, c.y, c.z], 3);
    [p.means2d, p.conics, colors, p.opacity, p.depths, p.radii]
        .iter()
        .map(|v| v.value().clone())
        .collect()
}

fn rasterized<'t>(
    x: &[Var<'t, f64>],
    radii: &Tensor<f64>,
    cut: AlphaCutoff,
) -> Rasterized<'t, f64> {
    let radii = x[0].tape().constant(radii.clone());
    rasterize(
        x[0],
        x[1],
        x[2],
        x[3],
        x[4],
        radii,
        W,
        H,
        [0.1, 0.4, 0.8],
        cut,
    )
}

/// The primitive-built reference compositor (smooth cutoff) on the same image.
fn reference_raster<'t>(t: &'t Tape<f64>, x: &[Var<'t, f64>]) -> Vec<Var<'t, f64>> {
    reference::tape::rasterize_smooth(
        t,
        x[0],
        x[1],
        x[2],
        x[3],
        x[4],
        W as usize,
        H as usize,
        [0.1, 0.4, 0.8],
    )
}

fn raster<'t>(x: &[Var<'t, f64>], radii: &Tensor<f64>, cut: AlphaCutoff) -> Vec<Var<'t, f64>> {
    let r = rasterized(x, radii, cut);
    vec![r.image, r.alpha, r.depth]
}

#[test]
fn rasterize_gradcheck_smooth_and_hard() {
    let inputs = raster_inputs(Filter2d::Mip);
    for cut in [AlphaCutoff::Smooth, AlphaCutoff::Hard] {
        // Hard: piecewise smooth; with eps = 1e-6 no sampled coordinate moves a pixel
        // across the 1/255 (support edge), 0.99 or T-floor thresholds for this seed.
        let report = gradcheck(
            |_, x| flat(&raster(x, &inputs[5], cut)),
            &inputs[..5],
            &cfg(),
        );
        assert!(report.passed(), "{cut:?}: {report}");
    }
}

#[test]
fn rasterize_vjp_against_primitive_composition() {
    let inputs = raster_inputs(Filter2d::Mip);
    let radii = inputs[5].clone();
    let report = check_vjp(
        |t, x| {
            let r = t.constant(radii.clone());
            let o = rasterize(
                x[0],
                x[1],
                x[2],
                x[3],
                x[4],
                r,
                W,
                H,
                [0.1, 0.4, 0.8],
                AlphaCutoff::Smooth,
            );
            vec![o.image, o.alpha, o.depth]
        },
        reference_raster,
        &inputs[..5],
        3,
        &cfg(),
    );
    report.assert_passed();
}

fn settings(filter2d: Filter2d, alpha_cutoff: AlphaCutoff) -> RenderSettings {
    RenderSettings {
        background: [0.3, 0.2, 0.1],
        filter2d,
        sh_degree: 3,
        alpha_cutoff,
        ..RenderSettings::default()
    }
}

fn chain<'t>(t: &'t Tape<f64>, x: &[Var<'t, f64>], s: &RenderSettings) -> Vec<Var<'t, f64>> {
    let g = GaussianVars {
        means: x[0],
        scales: x[1],
        quats: x[2],
        opacity: x[3],
        sh: x[4],
    };
    let out = render(t, &g, &cam(), s);
    vec![out.image, out.alpha, out.depth]
}

#[test]
fn whole_chain_gradcheck() {
    let s = scene();
    let inputs = s.tensors();
    for filter in [Filter2d::Classic, Filter2d::Mip] {
        for cut in [AlphaCutoff::Smooth, AlphaCutoff::Hard] {
            let st = settings(filter, cut);
            let report = gradcheck(|t, x| flat(&chain(t, x, &st)), &inputs, &cfg().with_seed(7));
            assert!(report.passed(), "{filter:?} {cut:?}: {report}");
        }
    }
}

/// A window of the image: its render's gradient is the whole chain's through the
/// screen-mean shift (the window's pixels only).
#[test]
fn windowed_chain_gradcheck() {
    let s = scene();
    let inputs = s.tensors();
    let st = RenderSettings {
        window: Some(Window {
            x0: 3,
            y0: 2,
            width: 15,
            height: 11,
        }),
        ..settings(Filter2d::Mip, AlphaCutoff::Smooth)
    };
    let report = gradcheck(
        |t, x| flat(&chain(t, x, &st)),
        &inputs,
        &cfg().with_seed(11),
    );
    assert!(report.passed(), "{report}");
}

#[test]
fn whole_chain_vjp_against_reference_composition() {
    let s = scene();
    let inputs = s.tensors();
    let camera = cam();
    let c = camera.center();
    for filter in [Filter2d::Classic, Filter2d::Mip] {
        let st = settings(filter, AlphaCutoff::Smooth);
        let report = check_vjp(
            |t, x| chain(t, x, &st),
            |t, x| {
                let cov = reference::tape::quat_scale_to_cov(x[2], x[1]);
                let p = reference::tape::project(t, x[0], cov, x[3], &camera, filter);
                let col = reference::tape::sh_color(t, x[0], x[4], [c.x, c.y, c.z], 3);
                reference::tape::rasterize_smooth(
                    t,
                    p[0],
                    p[1],
                    col,
                    p[2],
                    p[3],
                    W as usize,
                    H as usize,
                    st.background,
                )
            },
            &inputs,
            2,
            &cfg(),
        );
        assert!(report.passed(), "{filter:?}: {report}");
    }
}

/// The rasterizer with a deliberately wrong backward: the means2d gradient is scaled
/// by 1.05 (a typical "forgot a factor" bug).
struct WrongRaster(Rasterize<f64>);

impl Op<f64> for WrongRaster {
    type Saved = <Rasterize<f64> as Op<f64>>::Saved;
    fn name(&self) -> String {
        "wrong_rasterize".into()
    }
    fn forward(&self, x: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, Self::Saved) {
        self.0.forward(x)
    }
    fn backward(&self, c: &BackwardCtx<'_, f64, Self::Saved>) -> Vec<Option<Tensor<f64>>> {
        let mut g = self.0.backward(c);
        if let Some(m) = g[0].as_mut() {
            for v in m.data_mut() {
                *v *= 1.05;
            }
        }
        g
    }
}

#[test]
fn negative_control_wrong_backward_is_rejected() {
    let inputs = raster_inputs(Filter2d::Mip);
    let radii = inputs[5].clone();
    let report = gradcheck(
        |t, x| {
            let r = t.constant(radii.clone());
            let out = t.apply(
                WrongRaster(Rasterize {
                    width: W,
                    height: H,
                    background: [0.1, 0.4, 0.8],
                    cutoff: AlphaCutoff::Smooth,
                    abs_means2d: Default::default(),
                }),
                &[x[0], x[1], x[2], x[3], x[4], r],
            );
            flat(&out)
        },
        &inputs[..5],
        &cfg(),
    );
    assert!(!report.passed(), "a 5% error in d/dmeans2d must be caught");
    assert!(report.failures().iter().all(|f| f.input == 0), "{report}");
}

#[test]
fn means2d_gradient_is_readable() {
    let s = scene();
    let t = Tape::<f64>::new();
    let g = GaussianVars {
        means: t.param("means", s.means.clone()),
        scales: t.constant(s.scales.clone()),
        quats: t.constant(s.quats.clone()),
        opacity: t.constant(s.opacity.clone()),
        sh: t.constant(s.sh.clone()),
    };
    let out = render(&t, &g, &cam(), &settings(Filter2d::Mip, AlphaCutoff::Hard));
    let loss = out.image.sum();
    let grads = t.backward(loss).unwrap();
    let g2 = grads.wrt(out.means2d).expect("means2d is a tape node");
    assert_eq!(g2.shape(), &[s.n(), 2]);
    assert!(g2.data().iter().any(|&v| v != 0.0));
    assert!(grads.param("means").is_some());
}
