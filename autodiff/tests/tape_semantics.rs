//! Tape semantics: accumulation, constants, detach, unused outputs, skipped backwards,
//! validation and the checks the tape makes on every op.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use maaf_autodiff::check::{GradcheckConfig, check_vjp, compare, gradcheck};
use maaf_autodiff::{BackwardCtx, Op, Tape, TapeError, Tensor};

fn t(v: &[f64]) -> Tensor<f64> {
    Tensor::from_vec(v.to_vec(), &[v.len()])
}

#[test]
fn fan_out_accumulates_every_path() {
    // y = x*x + 3x + x: dy/dx = 2x + 4 (x used four times).
    let tape = Tape::new();
    let x = tape.param("x", t(&[1.0, -2.0]));
    let y = (x * x + x.scale(3.0) + x).sum();
    let g = tape.backward(y).expect("finite");
    assert_eq!(g.param("x").expect("grad").data(), &[6.0, 0.0]);
}

#[test]
fn constants_get_no_gradient_and_detach_stops_flow() {
    let tape = Tape::new();
    let x = tape.param("x", t(&[2.0]));
    let c = tape.constant(t(&[5.0]));
    let d = x.detach();
    assert!(!c.requires_grad() && !d.requires_grad() && x.requires_grad());
    // loss = x*c + x*d with d = detach(x) = 2: d is a constant, so dloss/dx = c + d = 7;
    // without the detach (x*c + x*x) it would be c + 2x = 9.
    let loss = (x * c + x * d).sum();
    let g = tape.backward(loss).expect("finite");
    assert_eq!(g.param("x").expect("grad").data(), &[7.0]);
    assert!(g.wrt(c).is_none() && g.wrt(d).is_none());
}

/// Cotangents an op saw, shared with the test.
type Seen = Arc<std::sync::Mutex<Vec<Vec<f64>>>>;

/// Two outputs: (2x, x^2). Records the cotangents it was given.
struct TwoOut {
    seen: Seen,
    calls: Arc<AtomicUsize>,
}

impl Op<f64> for TwoOut {
    type Saved = ();
    fn name(&self) -> String {
        "two_out".into()
    }
    fn forward(&self, x: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, ()) {
        (vec![x[0].map(|v| 2.0 * v), x[0].map(|v| v * v)], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, f64, ()>) -> Vec<Option<Tensor<f64>>> {
        self.calls.fetch_add(1, Ordering::SeqCst);
        let mut seen = self.seen.lock().expect("lock");
        for g in c.grad_outputs {
            seen.push(g.data().to_vec());
        }
        let x = c.inputs[0];
        let d: Vec<f64> = (0..x.len())
            .map(|i| {
                2.0 * c.grad_outputs[0].data()[i] + 2.0 * x.data()[i] * c.grad_outputs[1].data()[i]
            })
            .collect();
        vec![Some(Tensor::from_vec(d, x.shape()))]
    }
}

fn two_out() -> (TwoOut, Seen, Arc<AtomicUsize>) {
    let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
    let calls = Arc::new(AtomicUsize::new(0));
    (
        TwoOut {
            seen: seen.clone(),
            calls: calls.clone(),
        },
        seen,
        calls,
    )
}

#[test]
fn unused_outputs_get_zero_cotangents() {
    let (op, seen, _) = two_out();
    let tape = Tape::new();
    let x = tape.param("x", t(&[3.0, 4.0]));
    let outs = tape.apply(op, &[x]);
    let g = tape.backward(outs[1].sum()).expect("finite");
    assert_eq!(
        seen.lock().expect("lock").as_slice(),
        &[vec![0.0, 0.0], vec![1.0, 1.0]]
    );
    assert_eq!(g.param("x").expect("grad").data(), &[6.0, 8.0]);
}

#[test]
fn backward_is_skipped_when_no_input_needs_it() {
    let (op, _, calls) = two_out();
    let tape = Tape::new();
    let c = tape.constant(t(&[1.0]));
    let p = tape.param("p", t(&[2.0]));
    let outs = tape.apply(op, &[c]);
    let loss = (outs[0] * p + outs[1]).sum();
    let g = tape.backward(loss).expect("finite");
    assert_eq!(
        calls.load(Ordering::SeqCst),
        0,
        "backward of an op on constants must not run"
    );
    assert_eq!(g.param("p").expect("grad").data(), &[2.0]);
}

#[test]
fn validate_names_the_op_and_index_of_the_first_nan() {
    let tape = Tape::new();
    tape.set_validate(true);
    let x = tape.param("x", t(&[1.0, -1.0, 2.0]));
    let y = x.ln().exp().sum();
    let err = tape.backward(y).expect_err("ln(-1) is NaN");
    assert!(
        matches!(err, TapeError::Forward { ref op, output: 0, index: 1, value } if op == "ln" && value.is_nan()),
        "{err}"
    );
    let msg = err.to_string();
    assert!(msg.contains("`ln`") && msg.contains("index 1"), "{msg}");
}

#[test]
fn validate_catches_non_finite_cotangents() {
    // sqrt at 0 is finite forward but its derivative 1/(2*0) is infinite.
    let tape = Tape::new();
    tape.set_validate(true);
    let x = tape.param("x", t(&[0.0, 1.0]));
    let err = tape
        .backward(x.sqrt().sum())
        .expect_err("infinite cotangent");
    assert!(
        matches!(err, TapeError::Backward { ref op, index: 0, .. } if op == "sqrt"),
        "{err}"
    );
}

struct WrongCount;
impl Op<f64> for WrongCount {
    type Saved = ();
    fn name(&self) -> String {
        "wrong_count".into()
    }
    fn forward(&self, x: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, ()) {
        (vec![x[0].clone()], ())
    }
    fn backward(&self, _: &BackwardCtx<'_, f64, ()>) -> Vec<Option<Tensor<f64>>> {
        vec![]
    }
}

#[test]
#[should_panic(expected = "backward of op `wrong_count` returned 0 gradients for 1 inputs")]
fn a_backward_with_the_wrong_gradient_count_panics_naming_the_op() {
    let tape = Tape::new();
    let x = tape.param("x", t(&[1.0]));
    let _ = tape.backward(tape.apply1(WrongCount, &[x]).sum());
}

#[test]
#[should_panic(expected = "parameter `w` registered twice")]
fn duplicate_parameter_names_are_refused() {
    let tape = Tape::<f32>::new();
    tape.param("w", Tensor::zeros(&[1]));
    tape.param("w", Tensor::zeros(&[1]));
}

#[test]
fn check_vjp_accepts_a_correct_op_and_rejects_a_wrong_one() {
    let (op, _, _) = two_out();
    let op = Arc::new(op);
    let x = t(&[0.5, -1.5, 2.0]);
    let shared = op.clone();
    let good = check_vjp(
        move |tape, v| {
            let op = TwoOut {
                seen: shared.seen.clone(),
                calls: shared.calls.clone(),
            };
            tape.apply(op, v)
        },
        |_, v| vec![v[0].scale(2.0), v[0].square()],
        std::slice::from_ref(&x),
        3,
        &GradcheckConfig::default(),
    );
    good.assert_passed();
    // Negative control: the reference of a different function (x^3 instead of x^2)
    // differs in the second output's VJP, so the check must fail.
    let bad = check_vjp(
        move |tape, v| {
            let op = TwoOut {
                seen: op.seen.clone(),
                calls: op.calls.clone(),
            };
            tape.apply(op, v)
        },
        |_, v| vec![v[0].scale(2.0), v[0].powf(3.0)],
        &[x],
        3,
        &GradcheckConfig::default(),
    );
    assert!(!bad.passed());
}

#[test]
fn gradcheck_samples_large_inputs_and_reports_the_seed() {
    let x = maaf_autodiff::check::tests_support::random_tensor(&[1000], -1.0, 1.0, 9);
    let cfg = GradcheckConfig {
        max_coords: 50,
        seed: 42,
        ..GradcheckConfig::default()
    };
    let report = gradcheck(|_, v| v[0].sin(), &[x], &cfg);
    assert_eq!(report.checked, 50);
    assert!(report.to_string().contains("seed 42"));
    report.assert_passed();
}

#[test]
fn compare_counts_mismatches_and_treats_nan_as_mismatch() {
    let a = t(&[1.0, 2.0, f64::NAN]);
    let b = t(&[1.0, 2.1, 0.0]);
    let c = compare(&a, &b, 1e-3, 0.0);
    assert_eq!(c.mismatches, 2);
    assert!(!c.passed());
    assert!(
        compare(
            &a.map(|v| if v.is_nan() { 0.0 } else { v }),
            &t(&[1.0, 2.0, 0.0]),
            0.0,
            0.0
        )
        .passed()
    );
}

#[test]
fn profile_mode_counts_every_op_by_name_and_is_off_by_default() {
    let tape = Tape::<f64>::new();
    assert!(tape.op_profile().is_none());
    tape.set_profile(true);
    let x = tape.param("x", Tensor::from_vec(vec![1.0, 2.0, 3.0], &[3]));
    let loss = (x.square() + x.square()).sum();
    tape.backward(loss).expect("finite");
    let profile = tape.op_profile().expect("profile mode is on");
    let square = profile.ops.get("square").expect("square recorded");
    assert_eq!(square.calls, 2);
    assert!(square.forward >= 0.0 && square.backward > 0.0);
    assert_eq!(profile.ops.get("sum").map(|t| t.calls), Some(1));
    let (f, b) = profile.seconds_where(|n| n == "square");
    assert_eq!((f, b), (square.forward, square.backward));
}
