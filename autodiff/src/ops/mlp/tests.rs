//! Tests of [`super::FusedMlp`]: f64 gradchecks, bit-identity with the chain of dense
//! layers, skipped zero-cotangent rows, edge shapes and a negative control.

use super::*;
use crate::Tape;
use crate::check::{
    GradcheckConfig, gradcheck,
    tests_support::{random_tensor, with_threads},
};
use crate::ops::dense::Activation;

/// `x` then `(W, b)` per layer for `widths`, seeded; biases in [-0.5, 0.5].
fn inputs(m: usize, widths: &[usize], seed: u64) -> Vec<Tensor<f64>> {
    let mut v = vec![random_tensor(&[m, widths[0]], -1.0, 1.0, seed)];
    for (l, p) in widths.windows(2).enumerate() {
        let s = seed + 2 * l as u64 + 1;
        v.push(random_tensor(&[p[0], p[1]], -1.0, 1.0, s));
        v.push(random_tensor(&[p[1]], -0.5, 0.5, s + 1));
    }
    v
}

fn pairs<'t>(v: &[Var<'t, f64>]) -> Vec<(Var<'t, f64>, Var<'t, f64>)> {
    v[1..].chunks_exact(2).map(|p| (p[0], p[1])).collect()
}

#[test]
fn passes_gradcheck_in_f64_with_some_relus_cut() {
    let widths = [4, 6, 5, 3];
    let v = inputs(7, &widths, 11);
    // Both hidden layers must cut some entries and pass others.
    let t = Tape::new();
    let x = t.constant(v[0].clone());
    let h1 = x.dense(
        t.constant(v[1].clone()),
        t.constant(v[2].clone()),
        Activation::Relu,
    );
    let h2 = h1.dense(
        t.constant(v[3].clone()),
        t.constant(v[4].clone()),
        Activation::Relu,
    );
    for h in [h1, h2] {
        let h = h.value();
        assert!(h.data().contains(&0.0) && h.data().iter().any(|&a| a > 0.0));
    }
    let report = gradcheck(
        |_, x| x[0].mlp(&pairs(x)).square().sum(),
        &v,
        &GradcheckConfig::default(),
    );
    report.assert_passed();
    assert_eq!(report.checked, 7 * 4 + 4 * 6 + 6 + 6 * 5 + 5 + 5 * 3 + 3);
}

/// The fused op's value and every gradient, then the chain of [`Dense`] layers',
/// for `x` constant and variable, under a pool of `threads` threads.
///
/// [`Dense`]: crate::ops::dense::Dense
fn fused_and_chain(
    threads: usize,
    v: &[Tensor<f32>],
    rows: Option<&Tensor<f32>>,
) -> [Vec<Vec<f32>>; 2] {
    with_threads(threads, || {
        [true, false].map(|fused| {
            let mut out = Vec::new();
            for x_is_var in [false, true] {
                let t = Tape::new();
                let x = if x_is_var {
                    t.var(v[0].clone())
                } else {
                    t.constant(v[0].clone())
                };
                let params: Vec<_> = v[1..].iter().map(|p| t.var(p.clone())).collect();
                let layers: Vec<_> = params.chunks_exact(2).map(|p| (p[0], p[1])).collect();
                let y = if fused {
                    x.mlp(&layers)
                } else {
                    let last = layers.len() - 1;
                    layers.iter().enumerate().fold(x, |h, (l, &(w, b))| {
                        let act = if l < last {
                            Activation::Relu
                        } else {
                            Activation::Identity
                        };
                        h.dense(w, b, act)
                    })
                };
                // `rows` [m, 1] scales each output row: a zero row has a zero cotangent.
                let loss = match rows {
                    Some(r) => (y * t.constant(r.clone())).square().sum(),
                    None => y.square().sum(),
                };
                let grads = t.backward(loss).expect("finite");
                out.push(y.value().data().to_vec());
                for p in &params {
                    out.push(grads.wrt(*p).expect("parameter gradient").data().to_vec());
                }
                assert_eq!(grads.wrt(x).is_some(), x_is_var);
                if let Some(dx) = grads.wrt(x) {
                    out.push(dx.data().to_vec());
                }
            }
            out
        })
    })
}

/// `m` rows through `24 -> 32 -> 16 -> 3` (a narrow head), in f32.
fn f32_net(m: usize, seed: u64) -> Vec<Tensor<f32>> {
    inputs(m, &[24, 32, 16, 3], seed)
        .iter()
        .map(Tensor::cast)
        .collect()
}

#[test]
fn equals_the_chain_of_dense_layers_bit_for_bit_at_any_thread_count() {
    // Three blocks (the last partial), enough work for rayon, a narrow head.
    let m = 2 * ROW_BLOCK + 37;
    let v = f32_net(m, 21);
    let [fused, chain] = fused_and_chain(1, &v, None);
    assert_eq!(fused, chain);
    assert_eq!(fused_and_chain(2, &v, None)[0], fused);
    assert_eq!(fused_and_chain(3, &v, None)[0], fused);
}

/// Every third row, and all of the middle block, with a zero cotangent.
fn some_dead_rows(m: usize) -> Tensor<f32> {
    let dead = |r: usize| r.is_multiple_of(3) || (ROW_BLOCK..2 * ROW_BLOCK).contains(&r);
    let v = (0..m).map(|r| if dead(r) { 0.0 } else { 1.0 }).collect();
    Tensor::from_vec(v, &[m, 1])
}

#[test]
fn rows_with_a_zero_cotangent_are_skipped_without_changing_the_gradients() {
    let m = 3 * ROW_BLOCK + 37;
    let v = f32_net(m, 23);
    let mask = some_dead_rows(m);
    let [fused, chain] = fused_and_chain(1, &v, Some(&mask));
    assert_eq!(fused.len(), chain.len());
    for (k, (f, c)) in fused.iter().zip(&chain).enumerate() {
        let scale = c.iter().fold(1.0f32, |a, &b| a.max(b.abs()));
        for (i, (&a, &b)) in f.iter().zip(c).enumerate() {
            assert!(
                (a - b).abs() <= 2e-6 * scale,
                "output {k} at {i}: {a} vs {b}"
            );
        }
    }
    // The skipped rows' dx is exactly zero; the result is thread-count independent.
    let dx = fused.last().expect("dx");
    assert!(
        (0..m)
            .filter(|r| r.is_multiple_of(3))
            .all(|r| dx[r * 24..(r + 1) * 24].iter().all(|&d| d == 0.0))
    );
    assert_eq!(fused_and_chain(3, &v, Some(&mask))[0], fused);
}

#[test]
fn passes_gradcheck_in_f64_with_rows_of_zero_cotangent() {
    let v = inputs(9, &[4, 6, 5, 3], 13);
    let keep = Tensor::from_vec((0..9).map(|r| f64::from(r % 2 == 1)).collect(), &[9, 1]);
    let report = gradcheck(
        |t, x| {
            (x[0].mlp(&pairs(x)) * t.constant(keep.clone()))
                .square()
                .sum()
        },
        &v,
        &GradcheckConfig::default(),
    );
    report.assert_passed();
}

#[test]
fn one_layer_and_empty_shapes() {
    for (m, widths) in [(5, vec![3, 2]), (0, vec![3, 4, 2]), (4, vec![0, 3, 2])] {
        let v: Vec<Tensor<f32>> = inputs(m, &widths, 3).iter().map(Tensor::cast).collect();
        let [fused, chain] = fused_and_chain(1, &v, None);
        assert_eq!(fused, chain, "{m} rows, widths {widths:?}");
    }
}

#[test]
fn negative_control_a_backward_reading_pre_relu_like_activations_is_rejected() {
    // Same forward; the backward sees every hidden activation shifted positive (as
    // if it had kept values the ReLU never cut), so no cotangent is masked and the
    // weight gradients read wrong inputs: gradcheck must flag it.
    struct Unmasked;
    impl Op<f64> for Unmasked {
        type Saved = MlpSaved<f64>;
        fn name(&self) -> String {
            "unmasked_mlp".into()
        }
        fn forward(&self, x: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, MlpSaved<f64>) {
            let (y, saved) = FusedMlp.forward(x);
            let shift = |block: &Vec<f64>| block.iter().map(|a| a.abs() + 1.0).collect();
            let hidden = saved.hidden.iter().map(shift).collect();
            (y, MlpSaved { hidden })
        }
        fn backward(&self, c: &BackwardCtx<'_, f64, MlpSaved<f64>>) -> Vec<Option<Tensor<f64>>> {
            FusedMlp.backward(c)
        }
    }
    let report = gradcheck(
        |t, x| t.apply1(Unmasked, x).square().sum(),
        &inputs(7, &[4, 6, 5, 3], 11),
        &GradcheckConfig::default(),
    );
    assert!(!report.passed());
    assert!(report.failures().len() > 5, "{report}");
}

#[test]
fn bias_rows_by_doubling_equal_one_copy_per_row() {
    let b1 = Tensor::from_vec(vec![1.0f32, 2.0, 3.0], &[3]);
    let b2 = Tensor::from_vec(vec![-4.0f32, 5.0], &[2]);
    for rows in [0, 1, 2, 3, 5, 8, 1000, ROW_BLOCK] {
        let mut naive = Vec::new();
        for b in [&b1, &b2] {
            for _ in 0..rows {
                naive.extend_from_slice(b.data());
            }
        }
        assert_eq!(bias_rows(&[&b1, &b2], rows), naive, "rows {rows}");
    }
}

#[test]
fn gathering_runs_of_rows_equals_one_copy_per_row() {
    let w = 3;
    let src: Vec<u32> = (0..30 * w as u32).collect();
    for rows in [
        vec![],
        vec![4],
        vec![0, 1, 2, 9, 10, 20, 29],
        (0..30).collect(),
    ] {
        let mut out = vec![7];
        gather_rows(&src, w, &rows, &mut out);
        let mut naive = vec![7];
        for &r in &rows {
            naive.extend_from_slice(&src[r * w..(r + 1) * w]);
        }
        assert_eq!(out, naive, "rows {rows:?}");
        let runs: Vec<_> = row_runs(&rows).collect();
        assert_eq!(runs.iter().map(|r| r.1).sum::<usize>(), rows.len());
    }
    assert_eq!(
        row_runs(&[0, 1, 2, 9, 10, 20]).collect::<Vec<_>>(),
        [(0, 3), (9, 2), (20, 1)]
    );
}
