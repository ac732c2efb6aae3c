//! The fused multilayer perceptron `y = L_L(relu(... relu(L_1(x))))`, `L_l(a) = a W_l +
//! b_l`: one op for every layer, so a block of rows goes through the whole network
//! while it is in cache, and the tape holds one node instead of one per layer.
//!
//! Both passes walk the rows of `x` in the same fixed blocks of 1024 rows as
//! [`super::dense::Dense`], on rayon once the network has 2^20 multiply-adds. Each
//! block makes the same products in the same order as the chain of [`Dense`] layers
//! (bias rows plus `a W`, ReLU; backward `g' W^T`, `a^T g'`, column sums, one partial
//! weight gradient per block added in block order), so the results are bit-identical to
//! that chain and do not depend on the number of threads. The forward keeps the hidden
//! activations (post-ReLU) for the backward, whose ReLU masks are `a > 0`.
//!
//! Rows whose output cotangent is exactly zero (in training: Gaussians that reach no
//! pixel of the view, about a third of them on a D-NeRF view) contribute nothing to
//! any gradient, so the backward leaves them out of its products (their `dx` rows are
//! zero). With such rows the sums are the same terms in a different grouping, so the
//! results equal the chain's up to float rounding; without them, bit for bit.
//!
//! [`Dense`]: super::dense::Dense

use rayon::prelude::*;

use crate::float::{PARALLEL_MIN_MACS, ROW_BLOCK};
use crate::op::{BackwardCtx, Op};
use crate::{Float, MatMut, MatRef, Tensor, Var};

/// The fused MLP op: inputs `[x, W_1, b_1, ..., W_L, b_L]` with `x` [m, n_0], `W_l`
/// [n_{l-1}, n_l], `b_l` [n_l]; output `y` [m, n_L]. ReLU after every layer but the
/// last. Backward, from `g_L = dL/dy` down: `dW_l = a_{l-1}^T g_l`, `db_l = sum over
/// rows of g_l`, `g_{l-1} = (g_l W_l^T) [a_{l-1} > 0]`, `dx = g_1 W_1^T`, with
/// `a_0 = x` and `a_l` the hidden activations.
pub struct FusedMlp;

/// Hidden activations of every block, block after block; inside a block, layer 1's
/// `[rows, n_1]`, then layer 2's, and so on.
pub struct MlpSaved<T> {
    hidden: Vec<T>,
}

/// Layer widths `[n_0, ..., n_L]` of the inputs; panics naming the shapes when the
/// layers do not chain.
fn widths<T: Float>(inputs: &[&Tensor<T>]) -> Vec<usize> {
    let shapes: Vec<&[usize]> = inputs.iter().map(|t| t.shape()).collect();
    assert!(
        inputs.len() >= 3 && inputs.len() % 2 == 1 && shapes[0].len() == 2,
        "mlp: inputs must be x [m, n0] then (W, b) per layer, got shapes {shapes:?}"
    );
    let mut w = vec![shapes[0][1]];
    for pair in shapes[1..].chunks_exact(2) {
        let (sw, sb) = (pair[0], pair[1]);
        let last = *w.last().unwrap_or(&0);
        assert!(
            sw.len() == 2 && sw[0] == last && sb == [sw[1]],
            "mlp: layer {} has W {sw:?}, b {sb:?}, which do not follow a width of {last}",
            w.len()
        );
        w.push(sw[1]);
    }
    w
}

/// Splits `data` into consecutive per-block slices of `per_row` values per row for
/// `m` rows in blocks of [`ROW_BLOCK`] (empty slices when `per_row` is 0).
fn block_slices<T>(mut data: &mut [T], per_row: usize, m: usize) -> Vec<&mut [T]> {
    (0..m.div_ceil(ROW_BLOCK))
        .map(|i| {
            let rows = ROW_BLOCK.min(m - i * ROW_BLOCK);
            let (head, tail) = std::mem::take(&mut data).split_at_mut(rows * per_row);
            data = tail;
            head
        })
        .collect()
}

/// Runs `f` over the items, in parallel when `parallel`; returns results in order.
fn map_items<I: Send, R: Send>(
    items: Vec<I>,
    parallel: bool,
    f: impl Fn(usize, I) -> R + Sync + Send,
) -> Vec<R> {
    if parallel {
        items
            .into_par_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    } else {
        items
            .into_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    }
}

/// `out = act(a W + b)` for one block: `out` [rows, n] starts as the bias rows.
fn layer_forward<T: Float>(a: &[T], w: &Tensor<T>, b: &Tensor<T>, relu: bool, out: &mut [T]) {
    let (k, n) = (w.shape()[0], w.shape()[1]);
    if n == 0 {
        return;
    }
    let rows = out.len() / n;
    out.chunks_exact_mut(n)
        .for_each(|r| r.copy_from_slice(b.data()));
    if k > 0 {
        T::gemm_serial(
            T::one(),
            MatRef::row_major(a, rows, k),
            MatRef::row_major(w.data(), k, n),
            T::one(),
            MatMut::row_major(out, rows, n),
        );
    }
    if relu {
        out.iter_mut().for_each(|v| *v = v.max(T::zero()));
    }
}

impl<T: Float> Op<T> for FusedMlp {
    type Saved = MlpSaved<T>;

    fn name(&self) -> String {
        "mlp".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, MlpSaved<T>) {
        let n = widths(inputs);
        let (x, layers) = (inputs[0], inputs.len() / 2);
        let m = x.shape()[0];
        let (n0, out_w) = (n[0], n[layers]);
        let hidden_w: usize = n[1..layers].iter().sum();
        let macs: usize = n.windows(2).map(|p| p[0] * p[1]).sum();
        let mut y = vec![T::zero(); m * out_w];
        let mut hidden = vec![T::zero(); m * hidden_w];
        let items: Vec<_> = block_slices(&mut y, out_w, m)
            .into_iter()
            .zip(block_slices(&mut hidden, hidden_w, m))
            .collect();
        map_items(items, m * macs >= PARALLEL_MIN_MACS, |i, (yb, mut hb)| {
            let start = i * ROW_BLOCK;
            let rows = ROW_BLOCK.min(m - start);
            let mut a: &[T] = &x.data()[start * n0..(start + rows) * n0];
            for l in 0..layers {
                let (w, b) = (inputs[1 + 2 * l], inputs[2 + 2 * l]);
                if l + 1 == layers {
                    layer_forward(a, w, b, false, yb);
                    break;
                }
                let (out, rest) = std::mem::take(&mut hb).split_at_mut(rows * n[l + 1]);
                layer_forward(a, w, b, true, out);
                a = out;
                hb = rest;
            }
        });
        (vec![Tensor::from_vec(y, &[m, out_w])], MlpSaved { hidden })
    }

    fn backward(&self, c: &BackwardCtx<'_, T, MlpSaved<T>>) -> Vec<Option<Tensor<T>>> {
        let n = widths(c.inputs);
        let (x, layers) = (c.inputs[0], c.inputs.len() / 2);
        let m = x.shape()[0];
        let (n0, out_w) = (n[0], n[layers]);
        let hidden_w: usize = n[1..layers].iter().sum();
        let macs: usize = n.windows(2).map(|p| p[0] * p[1]).sum();
        // Offsets of each layer's dW and db in one block's partial gradient vector.
        let mut offsets = Vec::with_capacity(layers);
        let mut len = 0;
        for l in 0..layers {
            offsets.push(len);
            len += n[l] * n[l + 1] + n[l + 1];
        }
        let need = c.needs_grad;
        let g = c.grad_outputs[0].data();
        let hidden = &c.saved.hidden;
        // One block's rows: x rows `xb`, hidden activations `hb` (layer after layer),
        // cotangent `gb`; writes dx rows into `dx`, returns the partial dW and db.
        let rows_backward = |rows: usize, xb: &[T], hb: &[T], gb: &[T], dx: &mut [T]| -> Vec<T> {
            // Layer l's input activations in this block (x for the first layer).
            let input = |l: usize| -> &[T] {
                if l == 0 {
                    xb
                } else {
                    let off: usize = rows * n[1..l].iter().sum::<usize>();
                    &hb[off..off + rows * n[l]]
                }
            };
            let mut part = vec![T::zero(); len];
            let mut gl = gb.to_vec();
            let mut below = Vec::new();
            for l in (0..layers).rev() {
                let (k, nl) = (n[l], n[l + 1]);
                let w = c.inputs[1 + 2 * l];
                let a = input(l);
                let (dw, db) = part[offsets[l]..offsets[l] + k * nl + nl].split_at_mut(k * nl);
                if need[1 + 2 * l] && k > 0 && nl > 0 {
                    T::gemm_serial(
                        T::one(),
                        MatRef::row_major(a, rows, k).t(),
                        MatRef::row_major(&gl, rows, nl),
                        T::zero(),
                        MatMut::row_major(dw, k, nl),
                    );
                }
                if need[2 + 2 * l] && nl > 0 {
                    for row in gl.chunks_exact(nl) {
                        db.iter_mut().zip(row).for_each(|(d, &v)| *d += v);
                    }
                }
                if l == 0 {
                    if need[0] && k > 0 && nl > 0 {
                        T::gemm_serial(
                            T::one(),
                            MatRef::row_major(&gl, rows, nl),
                            MatRef::row_major(w.data(), k, nl).t(),
                            T::zero(),
                            MatMut::row_major(dx, rows, k),
                        );
                    }
                    break;
                }
                // g_{l-1} = (g_l W_l^T) [a_{l-1} > 0], into the other buffer.
                below.clear();
                below.resize(rows * k, T::zero());
                if nl > 0 {
                    T::gemm_serial(
                        T::one(),
                        MatRef::row_major(&gl, rows, nl),
                        MatRef::row_major(w.data(), k, nl).t(),
                        T::zero(),
                        MatMut::row_major(&mut below, rows, k),
                    );
                }
                below.iter_mut().zip(a).for_each(|(v, &act)| {
                    *v = if act > T::zero() { *v } else { T::zero() };
                });
                std::mem::swap(&mut gl, &mut below);
            }
            part
        };
        // Rows whose cotangent is zero (a Gaussian that reaches no pixel) add exactly
        // nothing to any gradient: they are left out of the block's products.
        let block = |i: usize, dx: &mut [T]| -> Vec<T> {
            let start = i * ROW_BLOCK;
            let rows = ROW_BLOCK.min(m - start);
            let xb = &x.data()[start * n0..(start + rows) * n0];
            let hb = &hidden[start * hidden_w..(start + rows) * hidden_w];
            let gb = &g[start * out_w..(start + rows) * out_w];
            let keep: Vec<usize> = if out_w == 0 {
                Vec::new()
            } else {
                let live = |r: &[T]| r.iter().any(|&v| v != T::zero());
                (0..rows)
                    .filter(|&r| live(&gb[r * out_w..(r + 1) * out_w]))
                    .collect()
            };
            if keep.len() == rows {
                return rows_backward(rows, xb, hb, gb, dx);
            }
            let take = |src: &[T], w: usize| -> Vec<T> {
                keep.iter()
                    .flat_map(|&r| src[r * w..(r + 1) * w].iter().copied())
                    .collect()
            };
            let mut hk = Vec::with_capacity(keep.len() * hidden_w);
            let mut off = 0;
            for &w in &n[1..layers] {
                hk.extend(take(&hb[off..off + rows * w], w));
                off += rows * w;
            }
            let mut dxk = vec![T::zero(); if need[0] { keep.len() * n0 } else { 0 }];
            let part = rows_backward(keep.len(), &take(xb, n0), &hk, &take(gb, out_w), &mut dxk);
            if need[0] {
                for (j, &r) in keep.iter().enumerate() {
                    dx[r * n0..(r + 1) * n0].copy_from_slice(&dxk[j * n0..(j + 1) * n0]);
                }
            }
            part
        };
        let mut dx = vec![T::zero(); if need[0] { m * n0 } else { 0 }];
        let per_row = if need[0] { n0 } else { 0 };
        let parts = map_items(
            block_slices(&mut dx, per_row, m),
            m * macs >= PARALLEL_MIN_MACS,
            block,
        );
        let total = parts.into_iter().reduce(|mut acc, p| {
            acc.iter_mut().zip(&p).for_each(|(a, &b)| *a += b);
            acc
        });
        let mut out = vec![need[0].then(|| Tensor::from_vec(dx, &[m, n0]))];
        for l in 0..layers {
            let (k, nl, off) = (n[l], n[l + 1], offsets[l]);
            let slot = |from: usize, count: usize, shape: &[usize]| {
                let v = match &total {
                    Some(t) => t[from..from + count].to_vec(),
                    None => vec![T::zero(); count],
                };
                Tensor::from_vec(v, shape)
            };
            out.push(need[1 + 2 * l].then(|| slot(off, k * nl, &[k, nl])));
            out.push(need[2 + 2 * l].then(|| slot(off + k * nl, nl, &[nl])));
        }
        out
    }
}

impl<'t, T: Float> Var<'t, T> {
    /// The fused MLP (see [`FusedMlp`]) of `self` [m, n_0] through `layers`, each a
    /// `(W [n_{l-1}, n_l], b [n_l])` pair; ReLU after every layer but the last.
    pub fn mlp(self, layers: &[(Var<'t, T>, Var<'t, T>)]) -> Var<'t, T> {
        let mut inputs = vec![self];
        for &(w, b) in layers {
            inputs.push(w);
            inputs.push(b);
        }
        self.tape().apply1(FusedMlp, &inputs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Tape;
    use crate::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
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
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| {
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
                let hidden = saved.hidden.iter().map(|a| a.abs() + 1.0).collect();
                (y, MlpSaved { hidden })
            }
            fn backward(
                &self,
                c: &BackwardCtx<'_, f64, MlpSaved<f64>>,
            ) -> Vec<Option<Tensor<f64>>> {
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
}
