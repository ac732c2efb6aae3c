//! Elementwise binary ops with numpy-style broadcasting (shapes aligned on the right,
//! dimensions equal or 1). The cotangent of a broadcast operand is summed over the
//! dimensions it was repeated along.

use crate::op::{BackwardCtx, Op};
use crate::{Float, Tensor, Var};

/// Which arithmetic a [`Binary`] op applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinaryKind {
    /// `a + b`.
    Add,
    /// `a - b`.
    Sub,
    /// `a * b`.
    Mul,
    /// `a / b`.
    Div,
}

/// An elementwise binary op (see [`BinaryKind`]).
pub struct Binary(pub BinaryKind);

/// Maps flat indices of the broadcast output to flat indices of one operand, with
/// fast paths for the common patterns (same shape, scalar, row vector, column).
enum Broadcast {
    /// Operand has the output's shape.
    Same,
    /// Operand has one element.
    Scalar,
    /// Operand equals the output's trailing dimensions: `index = i % len`.
    Row(usize),
    /// Operand equals the output's leading dimensions followed by ones:
    /// `index = i / inner`.
    Col(usize),
    /// Anything else: operand stride per output dimension (0 where repeated).
    General {
        out: Vec<usize>,
        strides: Vec<usize>,
    },
}

impl Broadcast {
    fn new(out: &[usize], operand: &[usize]) -> Self {
        let len: usize = operand.iter().product();
        let total: usize = out.iter().product();
        if out == operand {
            return Broadcast::Same;
        }
        if len == 1 {
            return Broadcast::Scalar;
        }
        let trimmed: Vec<usize> = operand.iter().copied().skip_while(|&d| d == 1).collect();
        if out.ends_with(&trimmed) {
            return Broadcast::Row(len);
        }
        let rank = out.len();
        let padded: Vec<usize> = std::iter::repeat_n(1, rank - operand.len())
            .chain(operand.iter().copied())
            .collect();
        let lead = padded.iter().take_while(|&&d| d != 1).count();
        if padded[..lead] == out[..lead] && padded[lead..].iter().all(|&d| d == 1) {
            return Broadcast::Col(total / len);
        }
        let mut strides = vec![0; rank];
        let mut stride = 1;
        for d in (0..rank).rev() {
            strides[d] = if padded[d] == 1 { 0 } else { stride };
            stride *= padded[d];
        }
        Broadcast::General {
            out: out.to_vec(),
            strides,
        }
    }

    #[inline]
    fn index(&self, flat: usize) -> usize {
        match self {
            Broadcast::Same => flat,
            Broadcast::Scalar => 0,
            Broadcast::Row(len) => flat % len,
            Broadcast::Col(inner) => flat / inner,
            Broadcast::General { out, strides } => {
                let (mut flat, mut idx) = (flat, 0);
                for (d, &n) in out.iter().enumerate().rev() {
                    idx += (flat % n) * strides[d];
                    flat /= n;
                }
                idx
            }
        }
    }
}

/// Calls `f(i, ia, ib)` for every output index `i` in order, with the operand indices;
/// the common patterns run as plain nested loops (no per-element index arithmetic).
#[inline]
fn visit(ba: &Broadcast, bb: &Broadcast, n: usize, mut f: impl FnMut(usize, usize, usize)) {
    use Broadcast::{Col, Row, Same, Scalar};
    let rows_of = |len: usize| n.checked_div(len).unwrap_or(0);
    match (ba, bb) {
        (Same, Same) => (0..n).for_each(|i| f(i, i, i)),
        (Same, Scalar) => (0..n).for_each(|i| f(i, i, 0)),
        (Scalar, Same) => (0..n).for_each(|i| f(i, 0, i)),
        (Same, Row(len)) => {
            for r in 0..rows_of(*len) {
                (0..*len).for_each(|j| f(r * len + j, r * len + j, j));
            }
        }
        (Row(len), Same) => {
            for r in 0..rows_of(*len) {
                (0..*len).for_each(|j| f(r * len + j, j, r * len + j));
            }
        }
        (Same, Col(inner)) => {
            for r in 0..rows_of(*inner) {
                (0..*inner).for_each(|j| f(r * inner + j, r * inner + j, r));
            }
        }
        (Col(inner), Same) => {
            for r in 0..rows_of(*inner) {
                (0..*inner).for_each(|j| f(r * inner + j, r, r * inner + j));
            }
        }
        _ => (0..n).for_each(|i| f(i, ba.index(i), bb.index(i))),
    }
}

/// `f(a[ia], b[ib])` for every output index in order. The common patterns run as
/// plain slice loops that write each value once and vectorise (no per-element index
/// arithmetic, no per-element capacity check); the rest go through [`visit`].
fn combine<T: Float>(
    ba: &Broadcast,
    bb: &Broadcast,
    n: usize,
    ad: &[T],
    bd: &[T],
    f: impl Fn(T, T) -> T,
) -> Vec<T> {
    use Broadcast::{Col, Row, Same, Scalar};
    if n == 0 {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(n);
    match (ba, bb) {
        (Same, Same) => out.extend(ad.iter().zip(bd).map(|(&x, &y)| f(x, y))),
        (Same, Scalar) => out.extend(ad.iter().map(|&x| f(x, bd[0]))),
        (Scalar, Same) => out.extend(bd.iter().map(|&y| f(ad[0], y))),
        (Same, Row(len)) => {
            for row in ad.chunks_exact(*len) {
                out.extend(row.iter().zip(bd).map(|(&x, &y)| f(x, y)));
            }
        }
        (Row(len), Same) => {
            for row in bd.chunks_exact(*len) {
                out.extend(ad.iter().zip(row).map(|(&x, &y)| f(x, y)));
            }
        }
        (Same, Col(inner)) => {
            for (row, &y) in ad.chunks_exact(*inner).zip(bd) {
                out.extend(row.iter().map(|&x| f(x, y)));
            }
        }
        (Col(inner), Same) => {
            for (row, &x) in bd.chunks_exact(*inner).zip(ad) {
                out.extend(row.iter().map(|&y| f(x, y)));
            }
        }
        _ => visit(ba, bb, n, |_, ia, ib| out.push(f(ad[ia], bd[ib]))),
    }
    out
}

/// The broadcast shape of `a` and `b`, or a panic naming both.
fn broadcast_shape(a: &[usize], b: &[usize]) -> Vec<usize> {
    let rank = a.len().max(b.len());
    (0..rank)
        .map(|k| {
            let da = if k < rank - a.len() {
                1
            } else {
                a[k - (rank - a.len())]
            };
            let db = if k < rank - b.len() {
                1
            } else {
                b[k - (rank - b.len())]
            };
            assert!(
                da == db || da == 1 || db == 1,
                "broadcast: shapes {a:?} and {b:?} are incompatible"
            );
            da.max(db)
        })
        .collect()
}

impl<T: Float> Op<T> for Binary {
    type Saved = ();

    fn name(&self) -> String {
        format!("{:?}", self.0).to_lowercase()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (a, b) = (x[0], x[1]);
        let shape = broadcast_shape(a.shape(), b.shape());
        let (ba, bb) = (
            Broadcast::new(&shape, a.shape()),
            Broadcast::new(&shape, b.shape()),
        );
        let n: usize = shape.iter().product();
        let (ad, bd) = (a.data(), b.data());
        let data = match self.0 {
            BinaryKind::Add => combine(&ba, &bb, n, ad, bd, |x, y| x + y),
            BinaryKind::Sub => combine(&ba, &bb, n, ad, bd, |x, y| x - y),
            BinaryKind::Mul => combine(&ba, &bb, n, ad, bd, |x, y| x * y),
            BinaryKind::Div => combine(&ba, &bb, n, ad, bd, |x, y| x / y),
        };
        (vec![Tensor::from_vec(data, &shape)], ())
    }

    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (a, b, g) = (c.inputs[0], c.inputs[1], &c.grad_outputs[0]);
        let shape = g.shape();
        let (ba, bb) = (
            Broadcast::new(shape, a.shape()),
            Broadcast::new(shape, b.shape()),
        );
        let (ad, bd) = (a.data(), b.data());
        if self.0 == BinaryKind::Add || self.0 == BinaryKind::Sub {
            // Linear in both operands: the cotangent is g (or -g) summed over repeats.
            let sign = if self.0 == BinaryKind::Sub {
                -T::one()
            } else {
                T::one()
            };
            let reduce = |b: &Broadcast, shape: &[usize], sign: T| {
                if matches!(b, Broadcast::Same) {
                    return if sign == T::one() {
                        g.clone()
                    } else {
                        g.map(|v| -v)
                    };
                }
                let mut d: Tensor<T> = Tensor::zeros(shape);
                let dd = d.data_mut();
                let gd = g.data();
                let same = Broadcast::Same;
                visit(&same, b, gd.len(), |i, _, ib| dd[ib] += gd[i]);
                if sign != T::one() {
                    dd.iter_mut().for_each(|v| *v = -*v);
                }
                d
            };
            return vec![
                c.needs_grad[0].then(|| reduce(&ba, a.shape(), T::one())),
                c.needs_grad[1].then(|| reduce(&bb, b.shape(), sign)),
            ];
        }
        let (mut da, mut db) = (Tensor::zeros(a.shape()), Tensor::zeros(b.shape()));
        let (dad, dbd, gd) = (da.data_mut(), db.data_mut(), g.data());
        let kind = self.0;
        visit(&ba, &bb, gd.len(), |i, ia, ib| {
            let (gi, x, y) = (gd[i], ad[ia], bd[ib]);
            let (ga, gb) = match kind {
                BinaryKind::Mul => (gi * y, gi * x),
                _ => (gi / y, -gi * x / (y * y)),
            };
            dad[ia] += ga;
            dbd[ib] += gb;
        });
        let (da, db) = (c.needs_grad[0].then_some(da), c.needs_grad[1].then_some(db));
        vec![da, db]
    }
}

impl<'t, T: Float> Var<'t, T> {
    fn binary(self, kind: BinaryKind, rhs: Var<'t, T>) -> Var<'t, T> {
        self.tape().apply1(Binary(kind), &[self, rhs])
    }
}

/// `a + b`, `a - b`, `a * b`, `a / b` on [`Var`]s record a [`Binary`] op
/// (elementwise, with broadcasting).
macro_rules! impl_std_op {
    ($tr:ident, $method:ident, $kind:ident) => {
        impl<'t, T: Float> std::ops::$tr for Var<'t, T> {
            type Output = Var<'t, T>;
            fn $method(self, rhs: Var<'t, T>) -> Var<'t, T> {
                self.binary(BinaryKind::$kind, rhs)
            }
        }
    };
}
impl_std_op!(Add, add, Add);
impl_std_op!(Sub, sub, Sub);
impl_std_op!(Mul, mul, Mul);
impl_std_op!(Div, div, Div);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    #[test]
    fn every_binary_op_passes_gradcheck_under_broadcasting() {
        let cfg = GradcheckConfig::default();
        let shapes: [(&[usize], &[usize]); 5] = [
            (&[3, 4], &[3, 4]),
            (&[3, 4], &[4]),
            (&[3, 4], &[3, 1]),
            (&[3, 4], &[]),
            (&[1, 4], &[3, 1]),
        ];
        for kind in [
            BinaryKind::Add,
            BinaryKind::Sub,
            BinaryKind::Mul,
            BinaryKind::Div,
        ] {
            for (k, (sa, sb)) in shapes.iter().enumerate() {
                let a = random_tensor(sa, -1.0, 1.0, k as u64);
                // Keep divisors away from zero.
                let b = random_tensor(sb, 0.5, 1.5, 10 + k as u64);
                let report = gradcheck(|_, v| v[0].binary(kind, v[1]), &[a, b], &cfg);
                assert!(report.passed(), "{kind:?} {sa:?} {sb:?}: {report}");
            }
        }
    }

    #[test]
    fn fast_paths_agree_with_the_general_index_map() {
        let pairs: [(&[usize], &[usize]); 10] = [
            (&[3, 4], &[3, 4]),
            (&[3, 4], &[4]),
            (&[4], &[3, 4]),
            (&[3, 4], &[3, 1]),
            (&[3, 1], &[3, 4]),
            (&[3, 4], &[]),
            (&[], &[3, 4]),
            (&[2, 3, 4], &[3, 4]),
            (&[2, 1, 1], &[2, 3, 4]),
            (&[1, 4], &[3, 1]),
        ];
        for (k, (sa, sb)) in pairs.iter().enumerate() {
            let a: Tensor<f64> = random_tensor(sa, -1.0, 1.0, k as u64);
            let b: Tensor<f64> = random_tensor(sb, -1.0, 1.0, 20 + k as u64);
            let shape = broadcast_shape(sa, sb);
            let (ba, bb) = (Broadcast::new(&shape, sa), Broadcast::new(&shape, sb));
            let n: usize = shape.iter().product();
            let f = |x: f64, y: f64| x - 2.0 * y;
            let fast = combine(&ba, &bb, n, a.data(), b.data(), f);
            let slow: Vec<f64> = (0..n)
                .map(|i| f(a.data()[ba.index(i)], b.data()[bb.index(i)]))
                .collect();
            assert_eq!(fast, slow, "{sa:?} {sb:?}");
        }
    }

    #[test]
    fn row_broadcast_values() {
        let t = crate::Tape::<f64>::new();
        let a = t.constant(Tensor::from_vec(vec![1.0, 2.0, 3.0, 4.0], &[2, 2]));
        let b = t.constant(Tensor::from_vec(vec![10.0, 20.0], &[2]));
        assert_eq!((a + b).value().data(), &[11.0, 22.0, 13.0, 24.0]);
        let col = t.constant(Tensor::from_vec(vec![10.0, 20.0], &[2, 1]));
        assert_eq!((a * col).value().data(), &[10.0, 20.0, 60.0, 80.0]);
    }
}
