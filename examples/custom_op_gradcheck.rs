//! Adding a differentiable op to maaf: a fused smooth-L1 (Huber) loss with a
//! hand-written backward, checked against finite differences and against the same
//! function built from tape primitives. A deliberately wrong backward is rejected.
//!
//! Run: `cargo run --release --example custom_op_gradcheck`

use maaf::autodiff::check::{GradcheckConfig, check_vjp, gradcheck, tests_support::random_tensor};
use maaf::autodiff::{BackwardCtx, Float, Op, Tape, Tensor, Var};

/// `smooth_l1(x) = 0.5 x^2 / beta` for `|x| < beta`, else `|x| - 0.5 beta`, elementwise.
/// Its derivative is `x / beta` inside the band and `sign(x)` outside.
struct SmoothL1 {
    beta: f64,
    /// When set, the backward forgets the 1/beta factor: the checker must reject it.
    wrong: bool,
}

impl<T: Float> Op<T> for SmoothL1 {
    type Saved = ();

    fn name(&self) -> String {
        "smooth_l1".into()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let beta = T::of(self.beta);
        let half = T::of(0.5);
        let y = x[0].map(|v| {
            if v.abs() < beta {
                half * v * v / beta
            } else {
                v.abs() - half * beta
            }
        });
        (vec![y], ())
    }

    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let beta = T::of(if self.wrong { 1.0 } else { self.beta });
        let band = T::of(self.beta);
        let dx = c.inputs[0].zip_map(&c.grad_outputs[0], |v, g| {
            if v.abs() < band {
                g * v / beta
            } else {
                g * v.signum()
            }
        });
        vec![Some(dx)]
    }
}

/// The same function from primitives: with `a = |x|` and `m = min(a, beta)`,
/// `smooth_l1 = m (a - m/2) / beta`, and `min(a, beta) = beta - relu(beta - a)`.
fn smooth_l1_reference<'t>(x: Var<'t, f64>, beta: f64) -> Var<'t, f64> {
    let a = x.abs();
    let m = (-a).add_scalar(beta).relu().scale(-1.0).add_scalar(beta);
    (m * (a - m.scale(0.5))).scale(1.0 / beta)
}

/// Runs both checks on a seeded input; returns (gradcheck, check_vjp) pass flags.
fn check(wrong: bool) -> (bool, bool) {
    let beta = 0.5;
    // Values in [-2, 2] straddle both branches; the kink at |x| = beta is measure zero
    // and the seeded draw keeps every sample at least 1e-3 away from it.
    let x = random_tensor(&[64], -2.0, 2.0, 11);
    assert!(x.data().iter().all(|v: &f64| (v.abs() - beta).abs() > 1e-3));
    let cfg = GradcheckConfig::default();
    let fd = gradcheck(
        |t, v| t.apply1(SmoothL1 { beta, wrong }, v),
        std::slice::from_ref(&x),
        &cfg,
    );
    let vjp = check_vjp(
        |t, v| vec![t.apply1(SmoothL1 { beta, wrong }, v)],
        |_, v| vec![smooth_l1_reference(v[0], beta)],
        &[x],
        4,
        &cfg,
    );
    if !fd.passed() {
        println!("{fd}");
    }
    (fd.passed(), vjp.passed())
}

fn main() {
    let tape = Tape::<f32>::new();
    let x = tape.param("x", Tensor::from_vec(vec![-1.0, 0.2, 3.0], &[3]));
    let loss = tape
        .apply1(
            SmoothL1 {
                beta: 0.5,
                wrong: false,
            },
            &[x],
        )
        .sum();
    let grads = tape.backward(loss).expect("finite");
    println!(
        "smooth_l1 sum = {}, d/dx = {:?}",
        loss.value().item(),
        grads.param("x").map(|g| g.data().to_vec())
    );

    let (fd, vjp) = check(false);
    println!(
        "correct backward: gradcheck {}, check_vjp {}",
        verdict(fd),
        verdict(vjp)
    );
    let (fd_bad, vjp_bad) = check(true);
    println!(
        "wrong backward (missing 1/beta): gradcheck {}, check_vjp {}",
        verdict(fd_bad),
        verdict(vjp_bad)
    );
    if !(fd && vjp) || fd_bad || vjp_bad {
        eprintln!("unexpected check outcome");
        std::process::exit(1);
    }
}

fn verdict(ok: bool) -> &'static str {
    if ok { "passed" } else { "FAILED" }
}

#[cfg(test)]
mod tests {
    #[test]
    fn correct_backward_passes_and_wrong_backward_is_rejected() {
        assert_eq!(super::check(false), (true, true));
        assert_eq!(super::check(true), (false, false));
    }
}
