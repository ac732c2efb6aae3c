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

use super::blocks::{map_blocks, row_blocks, sum_in_order};
use crate::float::{PARALLEL_MIN_MACS, ROW_BLOCK};
use crate::op::{BackwardCtx, Op};
use crate::{Float, MatMut, MatRef, Tensor, Var};

/// The fused MLP op: inputs `[x, W_1, b_1, ..., W_L, b_L]` with `x` \[m, n_0\], `W_l`
/// \[n_{l-1}, n_l\], `b_l` \[n_l\]; output `y` \[m, n_L\]. ReLU after every layer but the
/// last. Backward, from `g_L = dL/dy` down: `dW_l = a_{l-1}^T g_l`, `db_l = sum over
/// rows of g_l`, `g_{l-1} = (g_l W_l^T) [a_{l-1} > 0]`, `dx = g_1 W_1^T`, with
/// `a_0 = x` and `a_l` the hidden activations.
pub struct FusedMlp;

/// Hidden activations, one buffer per block of rows; inside a block, layer 1's
/// `[rows, n_1]`, then layer 2's, and so on. Each block's buffer starts as its bias
/// rows (no zeroing pass over the largest buffer of the op).
pub struct MlpSaved<T> {
    hidden: Vec<Vec<T>>,
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

/// What both passes read off the inputs: widths `n` = `[n_0, ..., n_L]`, `layers` =
/// L, rows `m`, and whether the work is worth rayon.
struct Dims {
    n: Vec<usize>,
    layers: usize,
    m: usize,
    parallel: bool,
}

impl Dims {
    fn of<T: Float>(inputs: &[&Tensor<T>]) -> Self {
        let n = widths(inputs);
        let (layers, m) = (inputs.len() / 2, inputs[0].shape()[0]);
        let macs: usize = n.windows(2).map(|p| p[0] * p[1]).sum();
        Dims {
            parallel: m * macs >= PARALLEL_MIN_MACS,
            n,
            layers,
            m,
        }
    }
}

/// Runs of consecutive row indices in `rows` (ascending), each as `(first row, count)`:
/// the gather and the scatter below copy a run in one `memcpy` instead of one per row
/// (a row is as short as 3 values, and about two thirds of the rows are kept).
fn row_runs(rows: &[usize]) -> impl Iterator<Item = (usize, usize)> + '_ {
    rows.chunk_by(|a, b| *b == a + 1)
        .map(|run| (run[0], run.len()))
}

/// Appends rows `rows` (ascending) of `src` (`w` values per row) to `out`.
fn gather_rows<T: Copy>(src: &[T], w: usize, rows: &[usize], out: &mut Vec<T>) {
    out.reserve(rows.len() * w);
    for (r, count) in row_runs(rows) {
        out.extend_from_slice(&src[r * w..(r + count) * w]);
    }
}

/// `out = act(a W + b)` for one block: `out` [rows, n] starts as the bias rows.
fn layer_forward<T: Float>(a: &[T], w: &Tensor<T>, relu: bool, out: &mut [T]) {
    let (k, n) = (w.shape()[0], w.shape()[1]);
    if n == 0 {
        return;
    }
    let rows = out.len() / n;
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

/// `rows` copies of each bias in `biases`, layer after layer: a block's hidden buffer,
/// or the whole output, before its products are added. Each layer's copies are made
/// by doubling (one row, then the rows written so far copied after themselves), so a
/// block of 1024 rows takes 11 copies per layer rather than 1024 calls of a short
/// `memcpy`.
fn bias_rows<T: Float>(biases: &[&Tensor<T>], rows: usize) -> Vec<T> {
    let len: usize = biases.iter().map(|b| b.len()).sum();
    let mut out = Vec::with_capacity(rows * len);
    for b in biases {
        let (start, end) = (out.len(), out.len() + rows * b.len());
        if rows > 0 {
            out.extend_from_slice(b.data());
        }
        while out.len() < end {
            let copy = (out.len() - start).min(end - out.len());
            out.extend_from_within(start..start + copy);
        }
    }
    out
}

impl<T: Float> Op<T> for FusedMlp {
    type Saved = MlpSaved<T>;

    fn name(&self) -> String {
        "mlp".into()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, MlpSaved<T>) {
        let Dims {
            n,
            layers,
            m,
            parallel,
        } = Dims::of(inputs);
        let (x, n0, out_w) = (inputs[0], n[0], n[layers]);
        let mut y = bias_rows(&[inputs[2 * layers]], m);
        let hidden_biases: Vec<&Tensor<T>> = (0..layers - 1).map(|l| inputs[2 + 2 * l]).collect();
        let hidden = map_blocks(row_blocks(&mut y, out_w, m), parallel, |i, yb| {
            let start = i * ROW_BLOCK;
            let rows = ROW_BLOCK.min(m - start);
            let mut hb = bias_rows(&hidden_biases, rows);
            let mut rest: &mut [T] = &mut hb;
            let mut a: &[T] = &x.data()[start * n0..(start + rows) * n0];
            for l in 0..layers {
                let w = inputs[1 + 2 * l];
                if l + 1 == layers {
                    layer_forward(a, w, false, yb);
                    break;
                }
                let (out, tail) = std::mem::take(&mut rest).split_at_mut(rows * n[l + 1]);
                layer_forward(a, w, true, out);
                a = out;
                rest = tail;
            }
            hb
        });
        (vec![Tensor::from_vec(y, &[m, out_w])], MlpSaved { hidden })
    }

    fn backward(&self, c: &BackwardCtx<'_, T, MlpSaved<T>>) -> Vec<Option<Tensor<T>>> {
        let Dims {
            n,
            layers,
            m,
            parallel,
        } = Dims::of(c.inputs);
        let (x, n0, out_w) = (c.inputs[0], n[0], n[layers]);
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
                // g_l W_l^T: dx for the first layer, else g_{l-1} before its ReLU mask.
                let to: &mut [T] = if l == 0 {
                    if !need[0] {
                        break;
                    }
                    &mut *dx
                } else {
                    // Whatever the buffer held is overwritten: the product below does
                    // not read its destination.
                    below.resize(rows * k, T::zero());
                    &mut below
                };
                if k > 0 && nl > 0 {
                    T::gemm_serial(
                        T::one(),
                        MatRef::row_major(&gl, rows, nl),
                        MatRef::row_major(w.data(), k, nl).t(),
                        T::zero(),
                        MatMut::row_major(to, rows, k),
                    );
                } else {
                    to.fill(T::zero());
                }
                if l == 0 {
                    break;
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
            let hb = &hidden[i];
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
            let (mut xk, mut hk, mut gk) = (Vec::new(), Vec::new(), Vec::new());
            gather_rows(xb, n0, &keep, &mut xk);
            gather_rows(gb, out_w, &keep, &mut gk);
            let mut off = 0;
            for &w in &n[1..layers] {
                gather_rows(&hb[off..off + rows * w], w, &keep, &mut hk);
                off += rows * w;
            }
            let mut dxk = vec![T::zero(); if need[0] { keep.len() * n0 } else { 0 }];
            let part = rows_backward(keep.len(), &xk, &hk, &gk, &mut dxk);
            if need[0] {
                let mut j = 0;
                for (r, count) in row_runs(&keep) {
                    dx[r * n0..(r + count) * n0].copy_from_slice(&dxk[j * n0..(j + count) * n0]);
                    j += count;
                }
            }
            part
        };
        let mut dx = vec![T::zero(); if need[0] { m * n0 } else { 0 }];
        let per_row = if need[0] { n0 } else { 0 };
        let parts = map_blocks(row_blocks(&mut dx, per_row, m), parallel, block);
        let total = sum_in_order(parts.into_iter());
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
mod tests;
