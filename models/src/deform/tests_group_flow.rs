use glam::{DQuat, DVec3};
use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
use maaf_autodiff::{PerGaussian, Tape};

use super::group_flow::GroupFlow;
use super::tests::{all_outputs, busy_model, tiny_config};
use super::*;

/// Warm-up ends at 7 (tiny config); the groups are fitted at 9.
fn grouped_config() -> DeformConfig {
    DeformConfig {
        group_flow: GroupFlowConfig {
            groups: 3,
            at: 9,
            max_knots: 5,
            node_lr: 1e-5,
            rotate_gaussians: true,
        },
        ..tiny_config()
    }
}

/// A busy model just fitted (4 knots), before any change to its groups.
fn fitted_model(n: usize) -> DeformModel<f64> {
    let mut m = busy_model(grouped_config(), n);
    m.set_frames(4);
    m.set_iteration(9);
    m
}

/// A fitted model whose knots turn by large angles and whose nodes have trained
/// offsets, so no term of the motion is near identity or zero.
fn grouped_model(n: usize) -> DeformModel<f64> {
    let mut m = fitted_model(n);
    let mut g = m.grouped().expect("fitted").clone();
    let knots = g.flow.knots;
    for (j, (q, t)) in g
        .flow
        .rotations
        .iter_mut()
        .zip(g.flow.translations.iter_mut())
        .enumerate()
    {
        if j % knots == 0 {
            continue; // knot 0 stays the rest pose
        }
        let f = j as f64;
        let axis = DVec3::new(f.sin(), (1.3 * f).cos(), 0.4 + (0.7 * f).sin()).normalize();
        *q = DQuat::from_axis_angle(axis, 0.4 + 0.3 * f.sin().abs() * (j % knots) as f64);
        *t = DVec3::new(0.1 * f.cos(), -0.05 * f, 0.2);
    }
    m.grouped = Some(Arc::new(g));
    let id = m.ids.group_nodes.expect("groups on");
    *m.params.value_mut(id) = random_tensor(&[3, 3], -0.3, 0.3, 77);
    m
}

type M3 = [[f64; 3]; 3];

fn mat(q: DQuat) -> M3 {
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

fn mul(a: &M3, b: &M3) -> M3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

fn transpose(a: &M3) -> M3 {
    let mut t = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            t[i][j] = a[j][i];
        }
    }
    t
}

/// Matrix logarithm of a rotation as an axis-angle vector.
fn log_rot(r: &M3) -> [f64; 3] {
    let v = [r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]];
    let cos = ((r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0).clamp(-1.0, 1.0);
    let theta = cos.acos();
    let k = if theta < 1e-12 {
        0.5
    } else {
        theta / (2.0 * theta.sin())
    };
    v.map(|c| c * k)
}

/// Rodrigues' formula.
fn exp_rot(w: [f64; 3]) -> M3 {
    let theta = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if theta == 0.0 {
        return r;
    }
    let k = w.map(|c| c / theta);
    let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    let kx2 = mul(&kx, &kx);
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] += theta.sin() * kx[i][j] + (1.0 - theta.cos()) * kx2[i][j];
        }
    }
    r
}

/// Rotation matrix to a unit quaternion (w, x, y, z), up to sign (Shepperd's method).
fn quat_of(r: &M3) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let cands = [
        1.0 + tr,
        1.0 + r[0][0] - r[1][1] - r[2][2],
        1.0 - r[0][0] + r[1][1] - r[2][2],
        1.0 - r[0][0] - r[1][1] + r[2][2],
    ];
    let k = (0..4)
        .max_by(|&a, &b| cands[a].total_cmp(&cands[b]))
        .unwrap_or(0);
    let s = 2.0 * cands[k].sqrt();
    let (a, b, c) = (r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]);
    let (d, e, f) = (r[0][1] + r[1][0], r[0][2] + r[2][0], r[1][2] + r[2][1]);
    match k {
        0 => [s / 4.0, a / s, b / s, c / s],
        1 => [a / s, s / 4.0, d / s, e / s],
        2 => [b / s, d / s, s / 4.0, f / s],
        _ => [c / s, e / s, f / s, s / 4.0],
    }
}

/// Hamilton product of (w, x, y, z) quaternions.
fn hamilton(p: [f64; 4], q: [f64; 4]) -> [f64; 4] {
    let [a, b, c, d] = p;
    let [e, f, g, h] = q;
    [
        a * e - b * f - c * g - d * h,
        a * f + b * e + c * h - d * g,
        a * g - b * h + c * e + d * f,
        a * h + b * g - c * f + d * e,
    ]
}

/// The group's rotation matrix and translation at `time` by the reference's formula
/// `R = R_k exp(r log(R_k^T R_k+1))`, `T = lerp`.
fn slow_rotation(f: &GroupFlow, l: usize, time: f64) -> (M3, DVec3) {
    let s = time.clamp(0.0, 1.0) * (f.knots - 1) as f64;
    let k = (s.floor() as usize).min(f.knots - 2);
    let r = s - k as f64;
    let (ra, rb) = (
        mat(f.rotations[l * f.knots + k]),
        mat(f.rotations[l * f.knots + k + 1]),
    );
    let rot = mul(
        &ra,
        &exp_rot(log_rot(&mul(&transpose(&ra), &rb)).map(|c| c * r)),
    );
    let (ta, tb) = (
        f.translations[l * f.knots + k],
        f.translations[l * f.knots + k + 1],
    );
    (rot, ta * (1.0 - r) + tb * r)
}

/// Quaternion of Gaussian i at `time`, one Gaussian at a time: the group's turn times
/// the knot-0 quaternion `q / |q| + dq_0`.
fn slow_quat(m: &DeformModel<f64>, i: usize, time: f64) -> [f64; 4] {
    let g = m.grouped().expect("grouped");
    let q = &m.params.value(m.ids.rotation).data()[4 * i..4 * i + 4];
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let q0: [f64; 4] = std::array::from_fn(|j| q[j] / norm + g.quat0[i][j]);
    let (rot, _) = slow_rotation(&g.flow, g.flow.labels[i], time);
    hamilton(quat_of(&rot), q0)
}

/// `mu(t)` of Gaussian i by the reference's formulas, one Gaussian at a time, with
/// rotation matrices: `R = R_k exp(r log(R_k^T R_k+1))`.
fn slow_centre(m: &DeformModel<f64>, i: usize, time: f64) -> [f64; 3] {
    let g = m.grouped().expect("grouped");
    let f = &g.flow;
    let l = f.labels[i];
    let (rot, tr) = slow_rotation(f, l, time);
    let delta = &m.params.value(m.ids.group_nodes.expect("on")).data()[3 * l..3 * l + 3];
    let node = f.nodes[l] + DVec3::from_slice(delta);
    let x = DVec3::from_slice(&m.params.value(m.ids.xyz).data()[3 * i..3 * i + 3]);
    let v = x + g.offset0[i] - node;
    let rv = DVec3::from_array(std::array::from_fn(|a| {
        (0..3).map(|b| rot[a][b] * v[b]).sum::<f64>()
    }));
    (rv + node + tr).to_array()
}

#[test]
fn grouped_gaussians_match_a_per_gaussian_loop() {
    let m = grouped_model(9);
    let tape = Tape::new();
    let bound = m.bind_deform(&m.params.bind(&tape));
    let canon = m.params.canonical(m.canonical_ids());
    for time in [0.0, 0.2, 0.5, 0.61, 0.97, 1.0] {
        let g = bound.deform(time);
        for i in 0..9 {
            let want = slow_centre(&m, i, time);
            for (a, w) in want.iter().enumerate() {
                let got = g.means.value().data()[3 * i + a];
                assert!((got - w).abs() < 1e-12, "row {i} t {time}: {got} vs {w}");
            }
        }
        let grouped = m.grouped().expect("grouped");
        for i in 0..9 {
            for a in 0..3 {
                let want = canon.scales.data()[3 * i + a] + grouped.scale0[i][a];
                assert!((g.scales.value().data()[3 * i + a] - want).abs() < 1e-12);
            }
            // A quaternion and its negative are the same turn.
            let want = slow_quat(&m, i, time);
            let got = g.quats.value().data()[4 * i..4 * i + 4].to_vec();
            let err = |sign: f64| {
                (0..4)
                    .map(|j| (got[j] - sign * want[j]).abs())
                    .fold(0.0, f64::max)
            };
            assert!(
                err(1.0).min(err(-1.0)) < 1e-12,
                "row {i} t {time}: {got:?} vs {want:?}"
            );
        }
        assert_eq!(*g.opacity.value(), canon.opacity);
    }
}

#[test]
fn at_the_fit_the_groups_continue_the_mlp_at_knot_zero() {
    let mut before = busy_model(grouped_config(), 12);
    before.set_frames(4);
    before.set_iteration(8);
    let mut after = before.clone();
    after.set_iteration(9);
    assert!(before.is_dynamic() && !after.is_dynamic());
    // Centre, scale and quaternion: the MLP's knot-0 residuals are kept.
    let at0 = |m: &DeformModel<f64>| {
        let tape = Tape::new();
        let g = m.bind_deform(&m.params.bind(&tape)).deform(0.0);
        [g.means, g.scales, g.quats].map(|v| v.value().clone())
    };
    for (mlp, grouped) in at0(&before).iter().zip(at0(&after)) {
        for (a, b) in mlp.data().iter().zip(grouped.data()) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
    }
    // A second call at the same iteration (a checkpoint load) keeps the fit.
    let fit = after.grouped.clone().expect("fitted");
    after.set_iteration(9);
    assert!(Arc::ptr_eq(&fit, after.grouped.as_ref().expect("kept")));
}

#[test]
fn gradcheck_grouped_parameters_to_deformed_gaussians() {
    let model = grouped_model(6);
    let inputs = model.params.tensors();
    // Products of constants with the parameters and the canonical activations:
    // central differences at eps 1e-6 are accurate to ~1e-9.
    let cfg = GradcheckConfig::default().with_tol(1e-6, 1e-5);
    let report = gradcheck(|_, v| all_outputs(&model, v), &inputs, &cfg);
    report.assert_passed();
    // The node offsets enter through `I - R`: with every non-rest knot turned by
    // 0.4 rad or more, a transposed `R` changes their gradients by O(1).
    let g = model.grouped().expect("grouped");
    let turned = g.flow.rotations.iter().enumerate();
    assert!(
        turned
            .filter(|(j, _)| j % g.flow.knots != 0)
            .all(|(_, q)| q.w.abs() < 0.98)
    );
}

#[test]
fn buffers_restore_the_stage_bit_for_bit_and_bad_ones_are_named() {
    let m = grouped_model(8);
    let buffers = m.buffers();
    let names: Vec<&str> = buffers.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, Grouped::BUFFERS);
    let buffer_scalars: usize = buffers.iter().map(|(_, t)| t.len()).sum();
    assert_eq!(m.state_scalars(), buffer_scalars, "the tables' size");
    let mut fresh = busy_model(grouped_config(), 8);
    *fresh.params.value_mut(fresh.ids.xyz) = m.params.value(m.ids.xyz).clone();
    for (j, (name, value)) in buffers.iter().enumerate() {
        assert!(fresh.grouped().is_none(), "restored after {j} of 7 buffers");
        fresh.load_buffer(name, value.clone()).expect("load");
    }
    assert_eq!(fresh.grouped(), m.grouped());

    let err = fresh
        .load_buffer("nope", Tensor::zeros(&[3]))
        .expect_err("an unknown buffer is refused");
    assert!(err.contains("nope"), "{err}");
    let mut short = busy_model(grouped_config(), 8);
    for (name, value) in &buffers {
        let value = if name == "group_flow/labels" {
            Tensor::zeros(&[7])
        } else {
            value.clone()
        };
        let r = short.load_buffer(name, value);
        if name == "group_flow/translations" {
            let e = r.expect_err("labels of the wrong length are refused");
            assert!(e.contains("group_flow/labels") && e.contains("[7]"), "{e}");
        }
    }
}

#[test]
fn selected_rows_keep_their_group_and_offset() {
    let mut m = grouped_model(5);
    let tape = Tape::new();
    let old = m
        .bind_deform(&m.params.bind(&tape))
        .deform(0.37)
        .means
        .value()
        .clone();
    (&mut m as &mut dyn Representation<_>).select_rows(&[4, 4, 1]);
    let tape = Tape::new();
    let new = m
        .bind_deform(&m.params.bind(&tape))
        .deform(0.37)
        .means
        .value()
        .clone();
    for (row, from) in [(0, 4), (1, 4), (2, 1)] {
        assert_eq!(
            new.data()[3 * row..3 * row + 3],
            old.data()[3 * from..3 * from + 3]
        );
    }
}

#[test]
fn validate_names_the_group_flow_field() {
    let mut c = grouped_config();
    c.group_flow.at = 3;
    let e = c.validate().expect_err("fit before the warm-up ends");
    assert!(e.contains("group_flow.at") && e.contains("warm_up"), "{e}");
    c.group_flow.at = 9;
    c.group_flow.max_knots = 1;
    let e = c.validate().expect_err("one knot");
    assert!(e.contains("group_flow.max_knots"), "{e}");
}

#[test]
fn eval_and_report_tell_a_groupflow_model_from_a_plain_one() {
    let plain = busy_model(tiny_config(), 4);
    let grouped = busy_model(grouped_config(), 4);
    assert_eq!(Representation::<f64>::label(&plain), "deform");
    assert_eq!(
        Representation::<f64>::label(&grouped),
        "deform + GroupFlow (3 groups)"
    );
    // Checkpoints keep recording the representation name.
    assert_eq!(Representation::<f64>::name(&grouped), "deform");
}
