//! The fused dense layer `y = act(x W + b)`: one op instead of matmul, bias add and
//! activation, so neither the pre-activation nor the broadcast bias is ever stored.
//!
//! Both passes walk the rows of `x` in fixed blocks of 1024 rows, on rayon once the
//! product has 2^20 multiply-adds: the forward adds the product onto rows that start
//! as the bias and applies the activation while the block is in cache; the backward
//! masks one block of the cotangent into a block-sized scratch, multiplies it into
//! that block of `dx`, and keeps one partial `dW` and `db` per block, added in block
//! order. The blocks depend on the shapes only, so results do not depend on the
//! number of threads.

use super::blocks::{map_blocks, row_blocks, sum_in_order};
use crate::float::{PARALLEL_MIN_MACS, ROW_BLOCK};
use crate::op::{BackwardCtx, Op};
use crate::{Float, MatMut, MatRef, Tensor, Var};

/// The activation of a [`Dense`] layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Activation {
    /// `act(z) = z`.
    Identity,
    /// `act(z) = max(z, 0)`; the backward passes the cotangent where `y > 0`
    /// (the subgradient 0 at `z = 0`, as [`crate::ops::unary::UnaryKind::Relu`]).
    Relu,
}

/// `y = act(x W + b)` for `x` \[m, k\], `W` \[k, n\], `b` \[n\], `y` \[m, n\]. Backward with
/// `g' = g` (identity) or `g' = g [y > 0]` (ReLU): `dx = g' W^T`, `dW = x^T g'`,
/// `db = sum over rows of g'`.
pub struct Dense(pub Activation);

/// One block's partial weight and bias gradients (`None` when not needed).
type BlockGrads<T> = (Option<Vec<T>>, Option<Vec<T>>);

impl<T: Float> Op<T> for Dense {
    type Saved = ();

    fn name(&self) -> String {
        match self.0 {
            Activation::Identity => "dense".into(),
            Activation::Relu => "dense_relu".into(),
        }
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (x, w, b) = (inputs[0], inputs[1], inputs[2]);
        let (sx, sw, sb) = (x.shape(), w.shape(), b.shape());
        assert!(
            sx.len() == 2 && sw.len() == 2 && sx[1] == sw[0] && sb == [sw[1]],
            "dense: shapes x {sx:?}, W {sw:?}, b {sb:?} do not fit x [m, k], W [k, n], b [n]"
        );
        let (m, k, n) = (sx[0], sx[1], sw[1]);
        // Every row starts as the bias (one write pass); the product is added onto it.
        let mut y = Vec::with_capacity(m * n);
        for _ in 0..m {
            y.extend_from_slice(b.data());
        }
        if n > 0 {
            let (xv, wv) = (
                MatRef::row_major(x.data(), m, k),
                MatRef::row_major(w.data(), k, n),
            );
            let relu = self.0 == Activation::Relu;
            map_blocks(
                row_blocks(&mut y, n, m),
                m * k * n >= PARALLEL_MIN_MACS,
                |i, block| {
                    let rows = block.len() / n;
                    let xb = xv.rows(i * ROW_BLOCK, rows);
                    T::gemm_serial(
                        T::one(),
                        xb,
                        wv,
                        T::one(),
                        MatMut::row_major(block, rows, n),
                    );
                    if relu {
                        block.iter_mut().for_each(|v| *v = v.max(T::zero()));
                    }
                },
            );
        }
        (vec![Tensor::from_vec(y, &[m, n])], ())
    }

    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (x, w, y, g) = (c.inputs[0], c.inputs[1], c.outputs[0], &c.grad_outputs[0]);
        let (m, k, n) = (x.shape()[0], x.shape()[1], w.shape()[1]);
        let (need_dx, need_dw, need_db) = (c.needs_grad[0], c.needs_grad[1], c.needs_grad[2]);
        let xv = MatRef::row_major(x.data(), m, k);
        let wt = MatRef::row_major(w.data(), k, n).t();
        let blocks = m.div_ceil(ROW_BLOCK);
        let parallel = m * k * n >= PARALLEL_MIN_MACS;
        let relu = self.0 == Activation::Relu;
        // One block: its masked cotangent g' (borrowed when there is no mask), then
        // dx for its rows and its partial dW and db.
        let block = |i: usize, dx: Option<&mut [T]>| {
            let (start, rows) = (i * ROW_BLOCK, ROW_BLOCK.min(m - i * ROW_BLOCK));
            let gb = &g.data()[start * n..(start + rows) * n];
            let masked: Vec<T>;
            let gp = if relu {
                let yb = &y.data()[start * n..(start + rows) * n];
                masked = gb
                    .iter()
                    .zip(yb)
                    .map(|(&g, &y)| if y > T::zero() { g } else { T::zero() })
                    .collect();
                &masked[..]
            } else {
                gb
            };
            let gv = MatRef::row_major(gp, rows, n);
            if let Some(dx) = dx {
                T::gemm_serial(T::one(), gv, wt, T::zero(), MatMut::row_major(dx, rows, k));
            }
            let dw = need_dw.then(|| {
                let mut dw = vec![T::zero(); k * n];
                let xb = xv.rows(start, rows).t();
                T::gemm_serial(
                    T::one(),
                    xb,
                    gv,
                    T::zero(),
                    MatMut::row_major(&mut dw, k, n),
                );
                dw
            });
            let db = need_db.then(|| {
                let mut db = vec![T::zero(); n];
                for row in gp.chunks_exact(n) {
                    db.iter_mut().zip(row).for_each(|(d, &v)| *d += v);
                }
                db
            });
            (dw, db)
        };
        let mut dx = need_dx.then(|| vec![T::zero(); m * k]);
        let parts: Vec<BlockGrads<T>> = match dx.as_mut() {
            Some(dx) if k > 0 && n > 0 => {
                map_blocks(row_blocks(dx, k, m), parallel, |i, d| block(i, Some(d)))
            }
            _ if n > 0 => map_blocks((0..blocks).collect(), parallel, |i, _: usize| {
                block(i, None)
            }),
            _ => Vec::new(),
        };
        let (dws, dbs): (Vec<_>, Vec<_>) = parts.into_iter().unzip();
        let dw = need_dw.then(|| {
            let dw =
                sum_in_order(dws.into_iter().flatten()).unwrap_or_else(|| vec![T::zero(); k * n]);
            Tensor::from_vec(dw, &[k, n])
        });
        let db = need_db.then(|| {
            let db = sum_in_order(dbs.into_iter().flatten()).unwrap_or_else(|| vec![T::zero(); n]);
            Tensor::from_vec(db, &[n])
        });
        vec![dx.map(|d| Tensor::from_vec(d, &[m, k])), dw, db]
    }
}

impl<'t, T: Float> Var<'t, T> {
    /// The fused dense layer `act(self W + b)` (see [`Dense`]) for `self` [m, k],
    /// `weight` \[k, n\], `bias` \[n\].
    pub fn dense(self, weight: Var<'t, T>, bias: Var<'t, T>, act: Activation) -> Var<'t, T> {
        self.tape().apply1(Dense(act), &[self, weight, bias])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Tape;
    use crate::check::{
        GradcheckConfig, check_vjp, gradcheck,
        tests_support::{random_tensor, with_threads},
    };

    /// `act(x W + b)` by a triple loop.
    fn reference(x: &Tensor<f64>, w: &Tensor<f64>, b: &Tensor<f64>, act: Activation) -> Vec<f64> {
        let (m, k, n) = (x.shape()[0], x.shape()[1], w.shape()[1]);
        let mut y = Vec::with_capacity(m * n);
        for i in 0..m {
            for j in 0..n {
                let z: f64 = b.data()[j]
                    + (0..k)
                        .map(|p| x.data()[i * k + p] * w.data()[p * n + j])
                        .sum::<f64>();
                y.push(match act {
                    Activation::Identity => z,
                    Activation::Relu => z.max(0.0),
                });
            }
        }
        y
    }

    fn inputs(m: usize, k: usize, n: usize, seed: u64) -> Vec<Tensor<f64>> {
        vec![
            random_tensor(&[m, k], -1.0, 1.0, seed),
            random_tensor(&[k, n], -1.0, 1.0, seed + 1),
            random_tensor(&[n], -0.5, 0.5, seed + 2),
        ]
    }

    /// Rows spanning three blocks, the last partial, and enough work to run on rayon.
    const BIG: (usize, usize, usize) = (2 * ROW_BLOCK + 37, 24, 24);

    #[test]
    fn forward_matches_a_triple_loop_across_blocks() {
        for (m, k, n) in [(5, 3, 4), BIG, (3, 0, 2), (0, 3, 2)] {
            let v = inputs(m, k, n, 1);
            for act in [Activation::Identity, Activation::Relu] {
                let t = Tape::new();
                let y = t.constant(v[0].clone()).dense(
                    t.constant(v[1].clone()),
                    t.constant(v[2].clone()),
                    act,
                );
                let want = reference(&v[0], &v[1], &v[2], act);
                assert_eq!(y.shape().as_slice(), &[m, n]);
                let got = y.value();
                for (i, (&g, &r)) in got.data().iter().zip(&want).enumerate() {
                    assert!(
                        (g - r).abs() < 1e-12,
                        "{act:?} {m}x{k}x{n} at {i}: {g} vs {r}"
                    );
                }
            }
        }
    }

    #[test]
    fn dense_passes_gradcheck_in_f64() {
        for act in [Activation::Identity, Activation::Relu] {
            let v = inputs(6, 4, 5, 3);
            let y = reference(&v[0], &v[1], &v[2], Activation::Relu);
            // The ReLU mask must cut some entries and pass others.
            assert!(y.contains(&0.0) && y.iter().any(|&z| z > 0.0));
            let report = gradcheck(
                |_, x| x[0].dense(x[1], x[2], act),
                &v,
                &GradcheckConfig::default(),
            );
            assert!(report.passed(), "{act:?}: {report}");
            assert_eq!(report.checked, 6 * 4 + 4 * 5 + 5);
        }
    }

    #[test]
    fn dense_matches_the_unfused_composition_across_blocks() {
        let (m, k, n) = BIG;
        let v = inputs(m, k, n, 5);
        for act in [Activation::Identity, Activation::Relu] {
            let cfg = GradcheckConfig::default()
                .with_tol(1e-11, 1e-11)
                .with_seed(2);
            let report = check_vjp(
                |_, x| vec![x[0].dense(x[1], x[2], act)],
                |_, x| {
                    let z = x[0].matmul(x[1]) + x[2];
                    vec![if act == Activation::Relu { z.relu() } else { z }]
                },
                &v,
                2,
                &cfg,
            );
            assert!(report.passed(), "{act:?}: {report}");
        }
    }

    #[test]
    fn negative_control_relu_without_its_mask_is_rejected() {
        // ReLU forward with the identity backward: gradcheck must flag the cut entries.
        struct Unmasked;
        impl Op<f64> for Unmasked {
            type Saved = ();
            fn name(&self) -> String {
                "unmasked_dense_relu".into()
            }
            fn forward(&self, x: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, ()) {
                Dense(Activation::Relu).forward(x)
            }
            fn backward(&self, c: &BackwardCtx<'_, f64, ()>) -> Vec<Option<Tensor<f64>>> {
                Dense(Activation::Identity).backward(c)
            }
        }
        let report = gradcheck(
            |t, x| t.apply1(Unmasked, x),
            &inputs(6, 4, 5, 3),
            &GradcheckConfig::default(),
        );
        assert!(!report.passed());
        assert!(report.failures().len() > 5, "{report}");
    }

    /// Forward value and the gradients of W and b (x constant, so no dx is built),
    /// plus dx with x a variable, under a pool of `threads` threads.
    fn run_f32(threads: usize, v: &[Tensor<f32>]) -> Vec<Vec<f32>> {
        with_threads(threads, || {
            let mut out = Vec::new();
            for x_is_var in [false, true] {
                let t = Tape::new();
                let x = if x_is_var {
                    t.var(v[0].clone())
                } else {
                    t.constant(v[0].clone())
                };
                let (w, b) = (t.var(v[1].clone()), t.var(v[2].clone()));
                let y = x.dense(w, b, Activation::Relu);
                let loss = y.square().sum();
                let grads = t.backward(loss).expect("finite");
                out.push(y.value().data().to_vec());
                out.push(grads.wrt(w).expect("dW").data().to_vec());
                out.push(grads.wrt(b).expect("db").data().to_vec());
                assert_eq!(grads.wrt(x).is_some(), x_is_var);
                if let Some(dx) = grads.wrt(x) {
                    out.push(dx.data().to_vec());
                }
            }
            out
        })
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count() {
        let (m, k, n) = BIG;
        let v: Vec<Tensor<f32>> = inputs(m, k, n, 9).iter().map(Tensor::cast).collect();
        let one = run_f32(1, &v);
        assert_eq!(one, run_f32(2, &v));
        assert_eq!(one, run_f32(3, &v));
        // The constant-input run gives the same dW and db as the variable-input run.
        assert_eq!(one[1..3], one[4..6]);
    }
}
