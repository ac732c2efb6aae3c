use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
use maaf_autodiff::nn::Linear;
use maaf_autodiff::{PerGaussian, Var};

use super::*;
use crate::KPlaneConfig;
use crate::kplane::PlaneSample;

mod cost_report;

fn tiny_config() -> SaroConfig {
    SaroConfig {
        field: KPlaneConfig {
            spatial_res: 4,
            time_res: 3,
            channels: 3,
            max_mip_level: 7,
        },
        hidden: 5,
        time_freqs: 2,
        sh_degree: 1,
        duration: Some(10.0),
        ..SaroConfig::default()
    }
}

fn tiny_model<T: Float>(n: usize, seed: u64) -> SaroModel<T> {
    let cloud = PointCloud::random_in_box(n, -1.0, 1.0, seed);
    let mut m = SaroModel::<T>::from_point_cloud(&cloud, tiny_config(), 2.0, seed);
    m.set_iteration(m.config.static_iterations + 1);
    m
}

fn randomise_planes<T: Float>(m: &mut SaroModel<T>, lo: f64, hi: f64, seed: u64) {
    for (p, id) in m.ids.planes.into_iter().enumerate() {
        let shape = m.params.value(id).shape().to_vec();
        *m.params.value_mut(id) = random_tensor(&shape, lo, hi, seed + p as u64);
    }
}

fn bind_tape<'t, T: Float>(m: &SaroModel<T>, tape: &'t Tape<T>) -> SaroBound<'t, T> {
    m.bind_saro(&m.params.bind(tape))
}

#[test]
fn zero_heads_give_the_canonical_scene_times_the_temporal_factor() {
    let mut model = tiny_model::<f32>(40, 1);
    // Random planes so that the field, the lifespans and the MLP hidden layers are
    // all non-trivial; only the zero output layers keep the residuals at zero.
    randomise_planes(&mut model, -1.0, 1.0, 7);
    let canon = model.params.canonical(model.canonical_ids());
    let lifespans = model.lifespans();
    let tape = Tape::new();
    let bound = bind_tape(&model, &tape);
    assert!(bound.l_sr().expect("dynamic").value().item() == 0.0);
    let sh_dc = model.params.value(model.ids.sh_dc).clone();
    let t_centre = model.params.value(model.ids.t_centre).clone();
    for time in [0.0, 0.37, 1.0] {
        let g = bound.deform(time);
        // Exactly: x + 0 = x, exp(s + 0) = exp(s), q + 0 = q, SH + 0 = SH.
        assert_eq!(*g.means.value(), canon.means);
        assert_eq!(*g.scales.value(), canon.scales);
        assert_eq!(*g.quats.value(), canon.quats);
        let sh = g.sh.value();
        assert_eq!(sh.shape(), &[40, 4, 3]);
        for i in 0..40 {
            assert_eq!(
                &sh.data()[i * 12..i * 12 + 3],
                &sh_dc.data()[i * 3..i * 3 + 3]
            );
            assert!(
                sh.data()[i * 12 + 3..(i + 1) * 12]
                    .iter()
                    .all(|&v| v == 0.0)
            );
        }
        let opacity = g.opacity.value();
        for (i, &l) in lifespans.iter().enumerate() {
            let dt = time - f64::from(t_centre.data()[i]);
            let w = (-4.0 * (dt / l).powi(2)).exp();
            let want = f64::from(canon.opacity.data()[i]) * w;
            // f32 products of an exp and a sigmoid: a few ulps of values <= 1.
            assert!(
                (f64::from(opacity.data()[i]) - want).abs() <= 1e-6,
                "{i}: {} vs {want}",
                opacity.data()[i]
            );
        }
        let m = model.config.min_lifespan();
        assert!(lifespans.iter().all(|&l| l >= m && l <= 1.0));
    }
    // The static stage is plain 3DGS: no temporal factor, no regulariser.
    model.set_iteration(1);
    let tape = Tape::new();
    let params = model.params.bind(&tape);
    let bound = model.bind(&params);
    let g = bound.deform(0.5);
    assert_eq!(*g.opacity.value(), canon.opacity);
    assert!(bound.regularisers().is_empty());
}

/// A tiny f64 model where nothing is trivially zero: random planes, random residual
/// heads, random SH bands and scales.
fn busy_model(n: usize) -> SaroModel<f64> {
    let mut m = tiny_model::<f64>(n, 5);
    randomise_planes(&mut m, -1.0, 1.0, 20);
    let mut heads = vec![m.ids.motion.last_layer(), m.ids.rot.last_layer()];
    heads.extend(m.ids.sh.as_ref().map(|h| h.last_layer()));
    for (k, (w, b)) in heads.into_iter().enumerate() {
        let (i, o) = {
            let s = m.params.value(w).shape();
            (s[0], s[1])
        };
        let layer = Linear::<f64>::new(i, o, 40 + k as u64);
        *m.params.value_mut(w) = layer.weight;
        *m.params.value_mut(b) = layer.bias;
    }
    let rest = m.ids.sh_rest.expect("degree 1");
    let shape = m.params.value(rest).shape().to_vec();
    *m.params.value_mut(rest) = random_tensor(&shape, -0.3, 0.3, 43);
    let shape = m.params.value(m.ids.log_scale).shape().to_vec();
    *m.params.value_mut(m.ids.log_scale) = random_tensor(&shape, -4.0, 0.0, 44);
    m
}

/// Every deformed output at two times plus L_SR, flattened into one vector.
fn all_outputs<'t>(m: &SaroModel<f64>, v: &[Var<'t, f64>]) -> Var<'t, f64> {
    let params = BoundParams::from_vars(&m.params, v);
    crate::flatten_outputs(&*m.bind(&params), &[0.2, 0.75])
}

#[test]
fn gradcheck_field_mlp_temporal_opacity_to_deformed_gaussians() {
    let model = busy_model(6);
    // The check covers the culled path: at one of its times some Gaussians are
    // absent (their residual MLPs are skipped) and some present.
    let counts: Vec<usize> = [0.2, 0.75]
        .map(|t| {
            let tape = Tape::new();
            let opacity = bind_tape(&model, &tape).deform(t).opacity.value().clone();
            super::bound::present_rows(&opacity).len()
        })
        .to_vec();
    assert!(
        counts.iter().any(|&c| c > 0 && c < 6),
        "present rows {counts:?}"
    );
    let inputs = model.params.tensors();
    // Stop-gradient inputs are read from the stored (unperturbed) values: the finite
    // differences then see exactly the function whose gradient the tape computes.
    // Smooth O(1) compositions of exp/sigmoid/matmul/bilinear taps: central
    // differences with eps 1e-6 are accurate to ~1e-9; atol 1e-6 / rtol 1e-5
    // still catch a wrong factor or a dropped tap by orders of magnitude.
    let cfg = GradcheckConfig::default().with_tol(1e-6, 1e-5);
    let report = gradcheck(|_, v| all_outputs(&model, v), &inputs, &cfg);
    report.assert_passed();
    assert!(report.checked > 500, "only {} coordinates", report.checked);

    let mut bad = model.clone();
    bad.corrupt_field_backward = true;
    let report = gradcheck(|_, v| all_outputs(&bad, v), &inputs, &cfg);
    assert!(
        !report.passed(),
        "negative control: a wrong field backward passed"
    );
    let names = model.params.names();
    assert!(
        report
            .failures()
            .iter()
            .all(|f| names[f.input].starts_with("field.")),
        "only the planes' gradients should be wrong"
    );
}

#[test]
fn norm2_gradcheck_and_zero_subgradient() {
    let x = random_tensor(&[4, 3], -1.0, 1.0, 9);
    gradcheck(|t, v| t.apply1(Norm2, v), &[x], &GradcheckConfig::default()).assert_passed();
    let tape = Tape::<f64>::new();
    let z = tape.var(Tensor::zeros(&[5, 3]));
    let n = tape.apply1(Norm2, &[z]);
    let grads = tape.backward(n).expect("finite");
    assert!(grads.wrt(z).expect("grad").data().iter().all(|&g| g == 0.0));
}

#[test]
fn select_rows_resizes_every_per_gaussian_parameter_in_lock_step() {
    let mut model = busy_model(5);
    let before = model.clone();
    // Prune 1 and 3, clone 2, split 4 into two rows.
    let index = [0, 2, 2, 4, 4];
    (&mut model as &mut dyn Representation<_>).select_rows(&index);
    assert_eq!(model.params.gaussians(), Some(5));
    for (new, old) in model.params.iter().zip(before.params.iter()) {
        if new.rows == Rows::Shared {
            assert_eq!(new.value, old.value, "{} must not change", new.name);
            continue;
        }
        assert_eq!(new.value.rows(), index.len(), "{}", new.name);
        let w = old.value.row_len();
        for (new_row, &old_row) in index.iter().enumerate() {
            assert_eq!(
                &new.value.data()[new_row * w..(new_row + 1) * w],
                &old.value.data()[old_row * w..(old_row + 1) * w],
                "{} row {new_row}",
                new.name
            );
        }
    }
    // A split then moves the two halves: only those rows change.
    let means = Tensor::from_vec(vec![0.1, 0.2, 0.3, -0.1, -0.2, -0.3], &[2, 3]);
    let scales = Tensor::from_vec(vec![0.01, 0.02, 0.03, 0.04, 0.05, 0.06], &[2, 3]);
    let kept = model.clone();
    let ids = model.canonical_ids();
    model
        .params
        .set_canonical_rows(ids, &[3, 4], &means, &scales);
    let c = model.params.canonical(ids);
    assert_eq!(&c.means.data()[9..15], means.data());
    for (a, b) in c.scales.data()[9..15].iter().zip(scales.data()) {
        assert!((a - b).abs() <= 1e-15 * b, "exp(ln s) round trip");
    }
    let xyz = kept.params.value(kept.ids.xyz);
    assert_eq!(&c.means.data()[..9], &xyz.data()[..9]);
    assert_eq!(c.quats, *kept.params.value(kept.ids.rotation));
    // The resized model still binds and deforms with consistent shapes.
    let tape = Tape::new();
    let g = bind_tape(&model, &tape).deform(0.5);
    assert_eq!(g.means.shape().as_slice(), &[5, 3]);
    assert_eq!(g.opacity.shape().as_slice(), &[5]);
    assert_eq!(g.sh.shape().as_slice(), &[5, 4, 3]);
}

#[test]
fn temporal_integral_matches_quadrature_and_flags_short_lived() {
    let mut model = tiny_model::<f64>(8, 3);
    let integral = model.temporal_integral();
    let lifespans = model.lifespans();
    let t_centre = model.params.value(model.ids.t_centre).clone();
    for i in 0..8 {
        let (mu, l) = (t_centre.data()[i], lifespans[i]);
        // Midpoint rule with 20 000 cells: error ~1e-9 for these smooth integrands;
        // the logistic CDF approximation itself is good to ~1e-4 (SaRO-GS Eq 22).
        let steps = 20_000;
        let quad: f64 = (0..steps)
            .map(|k| {
                let t = (k as f64 + 0.5) / steps as f64;
                (-4.0 * ((t - mu) / l).powi(2)).exp() / steps as f64
            })
            .sum();
        assert!(
            (integral[i] - quad).abs() < 1e-3 * l,
            "{i}: {} vs {quad}",
            integral[i]
        );
    }
    // Move Gaussian 2 far outside [0, 1] in time: its integral vanishes.
    let id = model.ids.t_centre;
    model.params.value_mut(id).data_mut()[2] = 5.0;
    assert_eq!(model.short_lived(), vec![2]);
    model.set_iteration(1);
    assert!(
        model.short_lived().is_empty(),
        "no temporal pruning in the static stage"
    );
}

#[test]
fn adaptive_scale_is_the_longest_integral_over_each_and_follows_the_schedule() {
    let mut model = tiny_model::<f64>(8, 3);
    model.config.adaptive_every = 50;
    randomise_planes(&mut model, -1.0, 1.0, 5);
    // Gaussian 5 lives outside [0, 1]: its integral is below the prune threshold.
    let id = model.ids.t_centre;
    model.params.value_mut(id).data_mut()[5] = 4.0;
    let integral = model.temporal_integral();
    let scale = model.adaptive_scale();
    let floor = model.config.min_integral;
    let longest = integral.iter().copied().fold(0.0, f64::max);
    for (i, (&s, &integ)) in scale.iter().zip(&integral).enumerate() {
        let want = longest / integ.max(floor);
        assert!((s - want).abs() <= 1e-12 * want, "{i}: {s} vs {want}");
        assert!(
            s >= 1.0,
            "{i}: the longest-lived Gaussian has the smallest scale, 1"
        );
    }
    assert!(
        (scale[5] - longest / floor).abs() < 1e-9 * scale[5],
        "floored"
    );
    assert_eq!(scale.iter().copied().fold(f64::INFINITY, f64::min), 1.0);

    // Refreshed at multiples of `adaptive_every` in the dynamic stage only.
    let every = model.config.adaptive_every;
    let start = model.config.static_iterations;
    let first = (start / every + 1) * every;
    model.set_iteration(first - 1);
    assert!(
        model.densify_grad_scale().is_none(),
        "not before the first refresh"
    );
    model.set_iteration(first);
    let got = model.densify_grad_scale().expect("refreshed");
    assert_eq!(&got[..], &scale[..]);
    // Kept between refreshes even when the parameters move.
    model.params.value_mut(id).data_mut()[0] = 0.9;
    model.set_iteration(first + 1);
    assert_eq!(&model.densify_grad_scale().expect("kept")[..], &scale[..]);
    // Which rates it scales: the D-NeRF rule (no scaling after densification).
    for (name, while_densifying, after) in [
        ("xyz", true, false),
        ("opacity", true, false),
        ("t_centre", true, false),
        ("rotation", true, false),
        ("sh_dc", true, false),
        ("log_scale", true, false),
        ("sh_rest", false, false),
        ("motion_mlp.0.weight", false, false),
        ("field.xy", false, false),
    ] {
        assert_eq!(
            model.lr_row_scale(name, true).is_some(),
            while_densifying,
            "{name}"
        );
        assert_eq!(model.lr_row_scale(name, false).is_some(), after, "{name}");
    }
    model.config.adaptive_after_densify = true;
    assert!(model.lr_row_scale("xyz", false).is_some());
    assert!(model.lr_row_scale("log_scale", false).is_none());
    model.config.adaptive_log_scale = false;
    assert!(model.lr_row_scale("log_scale", true).is_none());
    assert!(model.lr_row_scale("xyz", true).is_some());
    // Densification carries each row's scale to its clones; a checkpoint buffer
    // restores it; the static stage and `adaptive_every = 0` turn it off.
    (&mut model as &mut dyn Representation<_>).select_rows(&[7, 0, 0]);
    assert_eq!(
        &model.densify_grad_scale().expect("resized")[..],
        &[scale[7], scale[0], scale[0]]
    );
    let buffers = model.buffers();
    let mut other = model.clone();
    other.set_iteration(1);
    assert!(other.buffers().is_empty());
    other.set_iteration(first + 1);
    for (name, value) in buffers {
        other.load_buffer(&name, value).expect("load");
    }
    assert_eq!(other.densify_grad_scale(), model.densify_grad_scale());
    assert!(other.load_buffer("nope", Tensor::zeros(&[3])).is_err());
    assert!(
        other
            .load_buffer(super::ADAPTIVE, Tensor::zeros(&[4]))
            .is_err()
    );
    model.config.adaptive_every = 0;
    model.set_iteration(first);
    assert!(model.densify_grad_scale().is_none());
}

#[test]
fn parameters_are_named_as_bound_and_scaled_by_extent() {
    let model = tiny_model::<f32>(4, 1);
    let names = model.params.names();
    let tape = Tape::new();
    let bound = bind_tape(&model, &tape);
    let loss = {
        let g = bound.deform(0.5);
        let mut l = g.means.sum() + g.scales.sum() + g.quats.sum() + g.opacity.sum() + g.sh.sum();
        for (_, r) in bound.regularisers() {
            l = l + r;
        }
        l
    };
    let grads = tape.backward(loss).expect("finite");
    let mut tape_names = grads.param_names();
    tape_names.sort_unstable();
    let mut sorted = names.clone();
    sorted.sort_unstable();
    assert_eq!(
        tape_names,
        sorted.iter().map(String::as_str).collect::<Vec<_>>()
    );
    let xyz = model.params.param(model.ids.xyz);
    assert_eq!(xyz.name, "xyz");
    // Extent 2.0 in tiny_model: 1.6e-4 * 2.
    assert!((xyz.lr.at(0) - 3.2e-4).abs() < 1e-12);
    assert_eq!(model.params.per_gaussian_names().len(), 7);
    // SaRO-GS's Adam L2 of 8e-7 on MLPs and planes, none on per-Gaussian tensors.
    for p in model.params.iter() {
        let want = if p.rows == Rows::Shared { 8e-7 } else { 0.0 };
        assert_eq!(p.weight_decay, want, "{}", p.name);
    }
}

#[test]
fn centres_at_times_equal_the_deformed_means_of_present_gaussians() {
    let mut model = busy_model(40);
    let times = [0.0, 0.3, 0.9];
    let fast = model.centres_at_times(&times);
    let xyz = model.params.value(model.ids.xyz).clone();
    let (mut absent, mut present) = (0, 0);
    for (&t, c) in times.iter().zip(&fast) {
        let tape = Tape::new();
        let g = bind_tape(&model, &tape).deform(t);
        let (means, opacity) = (g.means.value().clone(), g.opacity.value().clone());
        let rows = super::bound::present_rows(&opacity);
        for n in 0..40 {
            let row = |x: &Tensor<f64>| x.data()[3 * n..3 * n + 3].to_vec();
            if rows.contains(&n) {
                // The motion MLP on the present rows only: the same values as on all
                // rows up to the GEMM's rounding.
                for (a, b) in row(&means).iter().zip(row(c)) {
                    assert!((a - b).abs() < 1e-12, "row {n} at {t}: {a} vs {b}");
                }
                present += 1;
            } else {
                // An absent Gaussian keeps its canonical centre (no residual).
                assert_eq!(row(&means), row(&xyz), "row {n} at {t}");
                assert!(255.0 * opacity.data()[n] <= 1.0);
                absent += 1;
            }
        }
    }
    assert!(
        absent > 5 && present > 5,
        "{absent} absent, {present} present"
    );
    model.set_iteration(1);
    assert_eq!(
        model.centres_at_times(&[0.5])[0],
        *model.params.value(model.ids.xyz)
    );
}

#[test]
fn the_trainer_can_hold_any_representation_as_a_trait_object() {
    let model: Box<dyn Representation<f32>> = Box::new(tiny_model::<f32>(3, 2));
    assert_eq!(model.name(), "saro");
    assert_eq!(model.rows(), 3);
    assert!(model.hooks().is_some());
    assert_eq!(model.regularisers(), vec![("l_sr".to_string(), 8e-6)]);
    let tape = Tape::new();
    let params = model.params().bind(&tape);
    let bound = model.bind(&params);
    assert_eq!(bound.deform(0.1).quats.shape().as_slice(), &[3, 4]);
    assert_eq!(bound.regularisers()[0].0, "l_sr");
}
