use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
use maaf_autodiff::nn::Linear;
use maaf_autodiff::{Tape, Var};

use super::*;

pub(super) fn tiny_config() -> DeformConfig {
    DeformConfig {
        depth: 4,
        width: 5,
        x_freqs: 2,
        t_freqs: 2,
        time_width: 4,
        time_out: 3,
        sh_degree: 1,
        warm_up: 7,
        ..DeformConfig::default()
    }
}

fn tiny_model<T: Float>(config: DeformConfig, n: usize, seed: u64) -> DeformModel<T> {
    let cloud = PointCloud::random_in_box(n, -1.0, 1.0, seed);
    let mut m = DeformModel::<T>::from_point_cloud(&cloud, config, seed);
    m.set_iteration(m.config.warm_up);
    m
}

/// Nothing trivially zero or unit: a random head, random higher SH bands, scales and
/// unnormalised quaternions.
pub(super) fn busy_model(config: DeformConfig, n: usize) -> DeformModel<f64> {
    let mut m = tiny_model::<f64>(config, n, 5);
    let head = m
        .ids
        .after_skip
        .as_ref()
        .unwrap_or(&m.ids.trunk)
        .last_layer();
    let (i, o) = {
        let s = m.params.value(head.0).shape();
        (s[0], s[1])
    };
    let layer = Linear::<f64>::new(i, o, 40);
    *m.params.value_mut(head.0) = layer.weight;
    *m.params.value_mut(head.1) = layer.bias;
    let randomise = |m: &mut DeformModel<f64>, id: ParamId, lo, hi, seed| {
        let shape = m.params.value(id).shape().to_vec();
        *m.params.value_mut(id) = random_tensor(&shape, lo, hi, seed);
    };
    let ids = m.ids.clone();
    randomise(&mut m, ids.sh_rest.expect("degree 1"), -0.3, 0.3, 43);
    randomise(&mut m, ids.log_scale, -4.0, 0.0, 44);
    randomise(&mut m, ids.rotation, 0.3, 1.5, 45);
    m
}

/// `y = W^T x + b` for one row, `W` [in, out] row-major.
fn affine(x: &[f64], w: &Tensor<f64>, b: &Tensor<f64>) -> Vec<f64> {
    let out = b.len();
    (0..out)
        .map(|j| {
            b.data()[j]
                + (0..x.len())
                    .map(|i| x[i] * w.data()[i * out + j])
                    .sum::<f64>()
        })
        .collect()
}

fn relu(v: Vec<f64>) -> Vec<f64> {
    v.into_iter().map(|x| x.max(0.0)).collect()
}

/// `[p, sin p, cos p, sin 2p, cos 2p, ...]` blockwise, written out again.
fn encode(p: &[f64], freqs: usize) -> Vec<f64> {
    let mut out = p.to_vec();
    let mut f = 1.0;
    for _ in 0..freqs {
        out.extend(p.iter().map(|v| (f * v).sin()));
        out.extend(p.iter().map(|v| (f * v).cos()));
        f *= 2.0;
    }
    out
}

/// The deformation of Gaussian `i` at `time`, one Gaussian at a time with plain
/// loops, following the reference's `DeformNetwork.forward` layer by layer (weights
/// looked up by name).
fn slow_residuals(m: &DeformModel<f64>, i: usize, time: f64) -> Vec<f64> {
    let c = &m.config;
    let layer = |name: &str| {
        let w = m.params.id(&format!("{name}.weight")).expect(name);
        let b = m.params.id(&format!("{name}.bias")).expect(name);
        (m.params.value(w).clone(), m.params.value(b).clone())
    };
    let x = &m.params.value(m.ids.xyz).data()[3 * i..3 * i + 3];
    let mut t = encode(&[time], c.t_freqs);
    if c.time_width > 0 {
        let (w0, b0) = layer("time_net.0");
        let (w1, b1) = layer("time_net.1");
        t = affine(&relu(affine(&t, &w0, &b0)), &w1, &b1);
    }
    let input: Vec<f64> = encode(x, c.x_freqs).into_iter().chain(t).collect();
    // The reference's `linear[0..depth]` then the heads, in maaf's parameter names.
    let mut names: Vec<String> = Vec::new();
    if c.skip {
        let before = c.depth / 2 + 1;
        names.extend((0..before).map(|l| format!("deform_trunk.{l}")));
        names.extend((0..=c.depth - before).map(|l| format!("deform_head.{l}")));
    } else {
        names.extend((0..=c.depth).map(|l| format!("deform.{l}")));
    }
    let mut h = input.clone();
    for (l, name) in names.iter().enumerate() {
        let (w, b) = layer(name);
        h = affine(&h, &w, &b);
        if l == c.depth {
            break;
        }
        h = relu(h);
        if c.skip && l == c.depth / 2 {
            h = input.iter().copied().chain(h).collect();
        }
    }
    h
}

#[test]
fn deformed_gaussians_match_a_per_gaussian_loop_for_every_network_shape() {
    let shapes = [
        tiny_config(),
        DeformConfig {
            skip: false,
            ..tiny_config()
        },
        DeformConfig {
            time_width: 0,
            depth: 2,
            ..tiny_config()
        },
    ];
    for config in shapes {
        let m = busy_model(config.clone(), 7);
        let tape = Tape::new();
        let bound = m.bind_deform(&m.params.bind(&tape));
        for time in [0.0, 0.41, 1.0] {
            let g = bound.deform(time);
            for i in 0..7 {
                let d = slow_residuals(&m, i, time);
                assert_eq!(d.len(), 10);
                let get =
                    |id: ParamId, w: usize| m.params.value(id).data()[w * i..w * i + w].to_vec();
                let (x, ls, q) = (
                    get(m.ids.xyz, 3),
                    get(m.ids.log_scale, 3),
                    get(m.ids.rotation, 4),
                );
                let qn = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                for a in 0..3 {
                    let close = |got: f64, want: f64| {
                        assert!(
                            (got - want).abs() < 1e-12,
                            "{config:?} row {i} t {time}: {got} vs {want}"
                        )
                    };
                    close(g.means.value().data()[3 * i + a], x[a] + d[a]);
                    close(g.scales.value().data()[3 * i + a], ls[a].exp() + d[7 + a]);
                }
                for a in 0..4 {
                    let got = g.quats.value().data()[4 * i + a];
                    assert!((got - (q[a] / qn + d[3 + a])).abs() < 1e-12);
                }
            }
        }
    }
}

#[test]
fn zero_head_and_warm_up_render_the_canonical_gaussians() {
    let mut m = tiny_model::<f32>(tiny_config(), 30, 1);
    let canon = m.params.canonical(m.canonical_ids());
    for dynamic in [false, true] {
        m.set_iteration(if dynamic { 7 } else { 6 });
        assert_eq!(m.is_dynamic(), dynamic);
        let tape = Tape::new();
        let g = m.bind_deform(&m.params.bind(&tape)).deform(0.63);
        assert_eq!(*g.means.value(), canon.means);
        assert_eq!(*g.scales.value(), canon.scales);
        // Identity rotations are already unit quaternions.
        assert_eq!(*g.quats.value(), canon.quats);
        assert_eq!(*g.opacity.value(), canon.opacity);
    }
}

/// Every deformed output at two times, flattened into one vector.
pub(super) fn all_outputs<'t>(m: &DeformModel<f64>, v: &[Var<'t, f64>]) -> Var<'t, f64> {
    let params = BoundParams::from_vars(&m.params, v);
    crate::flatten_outputs(&*m.bind(&params), &[0.2, 0.75])
}

#[test]
fn gradcheck_network_and_canonical_parameters_to_deformed_gaussians() {
    let model = busy_model(tiny_config(), 6);
    let inputs = model.params.tensors();
    // Smooth compositions of exp/sigmoid/matmul/sqrt plus ReLUs away from their kink:
    // central differences at eps 1e-6 are accurate to ~1e-9, so atol 1e-6 / rtol 1e-5
    // catch a wrong factor or a dropped term by orders of magnitude.
    let cfg = GradcheckConfig::default().with_tol(1e-6, 1e-5);
    let report = gradcheck(|_, v| all_outputs(&model, v), &inputs, &cfg);
    report.assert_passed();
    assert!(report.checked > 300, "only {} coordinates", report.checked);

    // Negative control: drop the gradient through the quaternion's norm.
    let mut bad = model.clone();
    bad.detach_norm = true;
    let report = gradcheck(|_, v| all_outputs(&bad, v), &inputs, &cfg);
    assert!(!report.passed(), "a missing normalisation term passed");
    let names = model.params.names();
    assert!(
        report
            .failures()
            .iter()
            .all(|f| names[f.input] == "rotation"),
        "only the quaternions' gradients should be wrong"
    );
}

#[test]
fn the_reference_network_has_the_reference_parameter_count_and_rates() {
    // DeformNetwork(D=8, W=256, is_blender=True): time net 13-256-30, linear[0] 93-256,
    // six 256-256, the skip layer 349-256, heads 256-3, 256-4, 256-3.
    let m = tiny_model::<f32>(DeformConfig::reference(), 4, 0);
    let expected = (13 * 256 + 256 + 256 * 30 + 30)
        + (93 * 256 + 256)
        + 6 * (256 * 256 + 256)
        + (349 * 256 + 256)
        + (256 * 10 + 10);
    assert_eq!(m.network_params(), expected);
    let rate = |id: ParamId| m.params.param(id).lr.at(0);
    assert!((rate(m.ids.xyz) - 1.6e-4 * 5.0).abs() < 1e-15);
    let head = m.ids.after_skip.as_ref().expect("skip").last_layer();
    assert!((rate(head.0) - 8e-4).abs() < 1e-15);
    assert_eq!(rate(m.ids.log_scale), 1e-3);
    let model: Box<dyn Representation<f32>> = Box::new(m);
    assert_eq!(model.name(), "deform");
    assert!(model.regularisers().is_empty());
}

#[test]
fn validate_names_the_field() {
    let bad = DeformConfig {
        depth: 1,
        ..DeformConfig::default()
    };
    assert!(
        bad.validate()
            .expect_err("skip at depth 1")
            .contains("model.depth")
    );
    let bad = DeformConfig {
        width: 0,
        ..DeformConfig::default()
    };
    assert!(
        bad.validate()
            .expect_err("width")
            .contains("model.width = 0")
    );
    assert!(DeformConfig::default().validate().is_ok());
    assert!(DeformConfig::reference().validate().is_ok());
}
