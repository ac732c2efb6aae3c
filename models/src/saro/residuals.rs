//! The two ends of SaRO's residual MLPs as fused ops: building their input from the
//! field features of the rows that run, and adding their outputs back onto the
//! canonical Gaussians. Each replaces a chain of gather, concat, scatter, slice, add,
//! exp and reshape ops with one pass over the rows, on rayon, computing every value
//! with the same arithmetic as that chain (so a run writes the same tensors).

use std::sync::Arc;

use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::{Float, Tensor, Var};
use rayon::prelude::*;

use crate::encoding::encode_row;

/// Rows per parallel chunk (below it, rayon's hand-off costs more than the work).
const CHUNK_ROWS: usize = 2048;

/// `h = [f[rows], PE(dt)]`: row `j` holds the features of Gaussian `rows[j]` followed
/// by the NeRF encoding of its time offset `dt[j]` (`[d, sin(2^k d), cos(2^k d)]`, k <
/// `freqs`: [`encode_row`], as [`crate::encoding::positional_encoding`] of one
/// column). The encoding is a constant (SaRO-GS detaches it), so the backward
/// only scatters `dh[:, ..C]` to the feature rows; others get zero.
pub struct SaroInput {
    /// Feature row of each output row, strictly increasing.
    pub rows: Arc<[usize]>,
    /// Time offset `t - mu_t` of each output row.
    pub dt: Vec<f64>,
    /// Encoding frequencies F (the encoding is `1 + 2F` wide).
    pub freqs: usize,
}

impl SaroInput {
    /// Every one of `n` rows, each at the same time offset `dt`.
    pub fn every_row(n: usize, dt: f64, freqs: usize) -> Self {
        SaroInput {
            rows: (0..n).collect(),
            dt: vec![dt; n],
            freqs,
        }
    }

    /// Width of the encoding, `1 + 2F`.
    fn pe_width(&self) -> usize {
        1 + 2 * self.freqs
    }
}

/// `pos[i]` = the output row that reads row `i` of an `n`-row tensor, or `None`.
fn positions(rows: &[usize], n: usize) -> Vec<Option<u32>> {
    let mut pos = vec![None; n];
    for (j, &i) in rows.iter().enumerate() {
        assert!(
            i < n && pos[i].is_none(),
            "rows must be distinct and below {n}, got {i} at {j}"
        );
        pos[i] = Some(j as u32);
    }
    pos
}

impl<T: Float> Op<T> for SaroInput {
    type Saved = ();

    fn name(&self) -> String {
        "saro_input".into()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let f = x[0];
        let c = f.row_len();
        assert_eq!(
            self.rows.len(),
            self.dt.len(),
            "saro_input: {} rows but {} time offsets",
            self.rows.len(),
            self.dt.len()
        );
        assert!(
            self.rows.iter().all(|&i| i < f.rows()),
            "saro_input: a row index is out of range for {} feature rows",
            f.rows()
        );
        let w = c + self.pe_width();
        let mut h = vec![T::zero(); self.rows.len() * w];
        h.par_chunks_mut(w * CHUNK_ROWS)
            .enumerate()
            .for_each(|(b, block)| {
                for (k, out) in block.chunks_exact_mut(w).enumerate() {
                    let j = b * CHUNK_ROWS + k;
                    let i = self.rows[j];
                    out[..c].copy_from_slice(&f.data()[i * c..(i + 1) * c]);
                    encode_row(&[self.dt[j]], self.freqs, &mut out[c..]);
                }
            });
        (vec![Tensor::from_vec(h, &[self.rows.len(), w])], ())
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let f = ctx.inputs[0];
        let (n, c) = (f.rows(), f.row_len());
        let w = c + self.pe_width();
        let g = ctx.grad_outputs[0].data();
        let pos = positions(&self.rows, n);
        let mut df = vec![T::zero(); n * c];
        df.par_chunks_mut(c * CHUNK_ROWS)
            .enumerate()
            .for_each(|(b, block)| {
                for (k, out) in block.chunks_exact_mut(c).enumerate() {
                    if let Some(j) = pos[b * CHUNK_ROWS + k] {
                        let j = j as usize;
                        out.copy_from_slice(&g[j * w..j * w + c]);
                    }
                }
            });
        vec![Some(Tensor::from_vec(df, f.shape()))]
    }
}

/// SaRO's deformation at time t from its residuals on the rows that run (module docs
/// of [`super`]): `mu = x + dx`, `q = q0 + dq`, `s = exp(log s + d log s)`, `SH = SH0 +
/// dSH`, where the residual of Gaussian `rows[j]` is row `j` of `dx` \[P,3], `r =
/// \[dq, d log s]` \[P,7] and `dSH` \[P,3K]; every other Gaussian keeps its canonical
/// values (residual zero). Inputs `[x, q0, log s, dx, r]`, then `[SH0, dSH]` when SH
/// has a residual; outputs `[mu, q, s]`, then `SH` in that case. Backward: each output's
/// cotangent goes to its canonical input and, on the running rows, to its residual;
/// the scale's through `ds/d(log s) = s`.
pub struct ApplyResiduals {
    /// Gaussian of each residual row, strictly increasing.
    pub rows: Arc<[usize]>,
}

/// `out[i] = act(base[i] + res[pos[i], off..off + w])` (or `act(base[i] + 0)` for rows
/// without a residual), `w` values per row, in parallel row chunks.
fn add_rows<T: Float>(
    base: &[T],
    w: usize,
    res: &[T],
    (rw, off): (usize, usize),
    pos: &[Option<u32>],
    act: impl Fn(T) -> T + Sync,
) -> Vec<T> {
    let mut out = vec![T::zero(); base.len()];
    out.par_chunks_mut(w * CHUNK_ROWS)
        .enumerate()
        .for_each(|(b, block)| {
            for (k, o) in block.chunks_exact_mut(w).enumerate() {
                let i = b * CHUNK_ROWS + k;
                let x = &base[i * w..(i + 1) * w];
                match pos[i] {
                    Some(j) => {
                        let r = &res[j as usize * rw + off..j as usize * rw + off + w];
                        for ((o, &x), &r) in o.iter_mut().zip(x).zip(r) {
                            *o = act(x + r);
                        }
                    }
                    None => {
                        for (o, &x) in o.iter_mut().zip(x) {
                            *o = act(x + T::zero());
                        }
                    }
                }
            }
        });
    out
}

impl<T: Float> Op<T> for ApplyResiduals {
    type Saved = ();

    fn name(&self) -> String {
        "apply_residuals".into()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (xyz, q0, log_s, dx, r) = (x[0], x[1], x[2], x[3], x[4]);
        let sh = x.get(5).zip(x.get(6));
        let n = xyz.rows();
        let p = self.rows.len();
        let shapes_ok = [xyz, q0, log_s].iter().all(|t| t.rows() == n)
            && [dx, r].iter().all(|t| t.rows() == p)
            && (xyz.row_len(), q0.row_len(), log_s.row_len()) == (3, 4, 3)
            && (dx.row_len(), r.row_len()) == (3, 7)
            && x.len() == if sh.is_some() { 7 } else { 5 }
            && sh.is_none_or(|(sh0, d)| {
                sh0.rows() == n && d.rows() == p && d.row_len() == sh0.row_len()
            });
        assert!(
            shapes_ok,
            "apply_residuals: shapes {:?} do not fit {p} residual rows",
            x.iter().map(|t| t.shape()).collect::<Vec<_>>()
        );
        let pos = positions(&self.rows, n);
        let id = |v: T| v;
        let mut out = vec![
            Tensor::from_vec(
                add_rows(xyz.data(), 3, dx.data(), (3, 0), &pos, id),
                xyz.shape(),
            ),
            Tensor::from_vec(
                add_rows(q0.data(), 4, r.data(), (7, 0), &pos, id),
                q0.shape(),
            ),
            Tensor::from_vec(
                add_rows(log_s.data(), 3, r.data(), (7, 4), &pos, |v: T| v.exp()),
                log_s.shape(),
            ),
        ];
        if let Some((sh0, dsh)) = sh {
            let w = sh0.row_len();
            out.push(Tensor::from_vec(
                add_rows(sh0.data(), w, dsh.data(), (w, 0), &pos, id),
                sh0.shape(),
            ));
        }
        (out, ())
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let g = ctx.grad_outputs;
        let p = self.rows.len();
        let need = ctx.needs_grad;
        // ds/d(log s) = s: the scale cotangent in log space.
        let g_log_s: Vec<T> = g[2]
            .data()
            .par_iter()
            .zip(ctx.outputs[2].data().par_iter())
            .map(|(&g, &s)| g * s)
            .collect();
        // r = [dq, d log s]: each running row's quaternion and log-scale cotangents.
        let (g_q, rows) = (g[1].data(), &self.rows);
        let mut dr = vec![T::zero(); p * 7];
        dr.par_chunks_mut(7 * CHUNK_ROWS)
            .enumerate()
            .for_each(|(b, block)| {
                for (k, d) in block.chunks_exact_mut(7).enumerate() {
                    let i = rows[b * CHUNK_ROWS + k];
                    d[..4].copy_from_slice(&g_q[i * 4..i * 4 + 4]);
                    d[4..].copy_from_slice(&g_log_s[i * 3..i * 3 + 3]);
                }
            });
        let mut grads = vec![
            need[0].then(|| g[0].clone()),
            need[1].then(|| g[1].clone()),
            need[2].then(|| Tensor::from_vec(g_log_s, ctx.inputs[2].shape())),
            need[3].then(|| g[0].gather_rows(rows)),
            need[4].then(|| Tensor::from_vec(dr, &[p, 7])),
        ];
        if let Some(gsh) = g.get(3) {
            grads.push(need[5].then(|| gsh.clone()));
            grads.push(need[6].then(|| gsh.gather_rows(rows).reshaped(&[p, gsh.row_len()])));
        }
        grads
    }
}

/// `[f[rows], PE(dt)]` (see [`SaroInput`]).
pub fn saro_input<'t, T: Float>(features: Var<'t, T>, op: SaroInput) -> Var<'t, T> {
    features.tape().apply1(op, &[features])
}
