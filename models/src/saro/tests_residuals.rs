//! The fused input and residual ops of SaRO against the chain of primitive ops they
//! replace (bit for bit in f32), and their gradients against finite differences.

use std::sync::Arc;

use maaf_autodiff::check::{GradcheckConfig, check_vjp, gradcheck, tests_support::random_tensor};
use maaf_autodiff::ops::concat;
use maaf_autodiff::{Float, Tape, Tensor, Var};

use super::residuals::{ApplyResiduals, SaroInput, saro_input};
use crate::encoding::positional_encoding;

const N: usize = 7;
const ROWS: [usize; 4] = [0, 2, 3, 6];
const DT: [f64; 4] = [-0.4, 0.0, 0.15, 0.9];
const FREQS: usize = 2;
/// SH coefficients per colour channel (degree 1).
const K: usize = 4;

fn input_op() -> SaroInput {
    SaroInput {
        rows: Arc::from(ROWS.as_slice()),
        dt: DT.to_vec(),
        freqs: FREQS,
    }
}

/// `[f[rows], PE(dt)]` as gather, constant encoding and concat.
fn input_chain<'t, T: Float>(tape: &'t Tape<T>, f: Var<'t, T>) -> Var<'t, T> {
    let pe = positional_encoding::<T>(&DT, 1, FREQS);
    concat(&[f.gather_rows(&ROWS), tape.constant(pe)], 1)
}

/// Inputs of [`ApplyResiduals`]: x, q0, log s, dx, r, SH0, dSH.
fn residual_inputs<T: Float>() -> Vec<Tensor<T>> {
    let p = ROWS.len();
    let shapes: [&[usize]; 7] = [
        &[N, 3],
        &[N, 4],
        &[N, 3],
        &[p, 3],
        &[p, 7],
        &[N, K, 3],
        &[p, 3 * K],
    ];
    shapes
        .iter()
        .enumerate()
        .map(|(i, s)| random_tensor(s, -1.0, 1.0, 70 + i as u64))
        .collect()
}

fn apply<'t, T: Float>(tape: &'t Tape<T>, v: &[Var<'t, T>]) -> Vec<Var<'t, T>> {
    tape.apply(
        ApplyResiduals {
            rows: Arc::from(ROWS.as_slice()),
        },
        v,
    )
}

/// The same deformation as scatter, slice, add, exp and reshape ops.
fn apply_chain<'t, T: Float>(v: &[Var<'t, T>]) -> Vec<Var<'t, T>> {
    let all = |r: Var<'t, T>| r.scatter_add_rows(&ROWS, N);
    let (dx, r) = (all(v[3]), all(v[4]));
    let mut out = vec![
        v[0] + dx,
        v[1] + r.slice(1, 0, 4),
        (v[2] + r.slice(1, 4, 7)).exp(),
    ];
    if v.len() == 7 {
        out.push(v[5] + all(v[6]).reshape(&[N, K, 3]));
    }
    out
}

/// Every output flattened and joined into one vector.
fn flat<'t>(outs: Vec<Var<'t, f64>>) -> Var<'t, f64> {
    let flat: Vec<_> = outs
        .into_iter()
        .map(|o| {
            let len = o.value().len();
            o.reshape(&[len])
        })
        .collect();
    concat(&flat, 0)
}

#[test]
fn fused_ops_equal_the_op_chain_bit_for_bit_in_f32() {
    let f = random_tensor::<f32>(&[N, 5], -1.0, 1.0, 3);
    let tape = Tape::new();
    let fv = tape.constant(f.clone());
    let (fused, chain) = (saro_input(fv, input_op()), input_chain(&tape, fv));
    assert_eq!(*fused.value(), *chain.value());
    let x = residual_inputs::<f32>();
    for count in [5, 7] {
        let tape = Tape::new();
        let v: Vec<_> = x[..count]
            .iter()
            .map(|t| tape.constant(t.clone()))
            .collect();
        let (fused, chain) = (apply(&tape, &v), apply_chain(&v));
        assert_eq!(fused.len(), chain.len());
        for (a, b) in fused.iter().zip(&chain) {
            assert_eq!(*a.value(), *b.value());
        }
    }
}

#[test]
fn fused_ops_backward_equals_the_op_chain() {
    // Tight: both sides gather and add the same cotangents.
    let cfg = GradcheckConfig::default().with_tol(1e-12, 1e-12);
    let f = random_tensor::<f64>(&[N, 5], -1.0, 1.0, 3);
    check_vjp(
        |_, v| vec![saro_input(v[0], input_op())],
        |t, v| vec![input_chain(t, v[0])],
        &[f],
        3,
        &cfg,
    )
    .assert_passed();
    let x = residual_inputs::<f64>();
    for count in [5, 7] {
        check_vjp(apply, |_, v| apply_chain(v), &x[..count], 3, &cfg).assert_passed();
    }
}

#[test]
fn fused_ops_gradcheck() {
    let cfg = GradcheckConfig::default().with_tol(1e-7, 1e-6);
    let f = random_tensor::<f64>(&[N, 5], -1.0, 1.0, 3);
    let report = gradcheck(|_, v| saro_input(v[0], input_op()), &[f], &cfg);
    report.assert_passed();
    let x = residual_inputs::<f64>();
    let report = gradcheck(|t, v| flat(apply(t, v)), &x, &cfg);
    report.assert_passed();
    assert_eq!(report.checked, x.iter().map(|t| t.len()).sum::<usize>());
}

#[test]
#[should_panic(expected = "rows must be distinct")]
fn repeated_rows_are_refused() {
    let tape = Tape::<f64>::new();
    let v: Vec<_> = residual_inputs::<f64>()[..5]
        .iter()
        .map(|t| tape.constant(t.clone()))
        .collect();
    let op = ApplyResiduals {
        rows: Arc::from([0, 0, 3, 6].as_slice()),
    };
    tape.apply(op, &v);
}
