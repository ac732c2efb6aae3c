//! Shape and indexing ops: reshape, row gather and scatter-add, concat, slice.

use crate::op::{BackwardCtx, Op};
use crate::{Float, Tensor, Var};

/// Same values, new shape; backward reshapes the cotangent back.
pub struct Reshape(pub Vec<usize>);

impl<T: Float> Op<T> for Reshape {
    type Saved = ();
    fn name(&self) -> String {
        "reshape".into()
    }
    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        (vec![x[0].clone().reshaped(&self.0)], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        vec![Some(
            c.grad_outputs[0].clone().reshaped(c.inputs[0].shape()),
        )]
    }
}

/// `y[i] = x[index[i]]` over rows (first dimension); backward scatter-adds
/// `dx[index[i]] += dy[i]`, so repeated indices accumulate.
pub struct GatherRows(pub Vec<usize>);

/// `y[index[i]] += x[i]` into `rows` zero rows; backward gathers `dx[i] = dy[index[i]]`.
pub struct ScatterAddRows {
    /// Destination row of each input row.
    pub index: Vec<usize>,
    /// Number of rows of the output.
    pub rows: usize,
}

fn scatter_add<T: Float>(x: &Tensor<T>, index: &[usize], rows: usize) -> Tensor<T> {
    assert_eq!(
        x.rows(),
        index.len(),
        "scatter_add_rows: {} rows but {} indices",
        x.rows(),
        index.len()
    );
    let w = x.row_len();
    let mut shape = x.shape().to_vec();
    shape[0] = rows;
    let mut out = Tensor::zeros(&shape);
    for (r, &i) in index.iter().enumerate() {
        assert!(
            i < rows,
            "scatter_add_rows: index {i} out of range for {rows} rows"
        );
        let dst = &mut out.data_mut()[i * w..(i + 1) * w];
        for (d, &s) in dst.iter_mut().zip(&x.data()[r * w..(r + 1) * w]) {
            *d += s;
        }
    }
    out
}

impl<T: Float> Op<T> for GatherRows {
    type Saved = ();
    fn name(&self) -> String {
        "gather_rows".into()
    }
    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        (vec![x[0].gather_rows(&self.0)], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        vec![Some(scatter_add(
            &c.grad_outputs[0],
            &self.0,
            c.inputs[0].rows(),
        ))]
    }
}

impl<T: Float> Op<T> for ScatterAddRows {
    type Saved = ();
    fn name(&self) -> String {
        "scatter_add_rows".into()
    }
    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        (vec![scatter_add(x[0], &self.index, self.rows)], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        vec![Some(c.grad_outputs[0].gather_rows(&self.index))]
    }
}

/// Joins tensors along `axis`; all other dimensions must agree.
pub struct Concat(pub usize);

/// `(outer, inner)` sizes around `axis`: elements before and after it.
fn split_at_axis(shape: &[usize], axis: usize) -> (usize, usize) {
    (
        shape[..axis].iter().product(),
        shape[axis + 1..].iter().product(),
    )
}

impl<T: Float> Op<T> for Concat {
    type Saved = ();
    fn name(&self) -> String {
        format!("concat(axis={})", self.0)
    }
    fn forward(&self, xs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let axis = self.0;
        assert!(!xs.is_empty(), "concat: no inputs");
        let first = xs[0].shape();
        assert!(
            axis < first.len(),
            "concat: axis {axis} out of range for {first:?}"
        );
        for x in xs {
            let s = x.shape();
            assert!(
                s.len() == first.len()
                    && s.iter()
                        .zip(first)
                        .enumerate()
                        .all(|(d, (a, b))| d == axis || a == b),
                "concat: shapes {first:?} and {s:?} do not agree off axis {axis}"
            );
        }
        let (outer, inner) = split_at_axis(first, axis);
        let total: usize = xs.iter().map(|x| x.shape()[axis]).sum();
        let mut data = Vec::with_capacity(outer * total * inner);
        for o in 0..outer {
            for x in xs {
                let block = x.shape()[axis] * inner;
                data.extend_from_slice(&x.data()[o * block..(o + 1) * block]);
            }
        }
        let mut shape = first.to_vec();
        shape[axis] = total;
        (vec![Tensor::from_vec(data, &shape)], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        // Inputs that need no gradient (a constant time encoding) are not sliced.
        let mut start = 0;
        c.inputs
            .iter()
            .zip(c.needs_grad)
            .map(|(x, &need)| {
                let len = x.shape()[self.0];
                let g = need.then(|| slice(&c.grad_outputs[0], self.0, start, start + len));
                start += len;
                g
            })
            .collect()
    }
}

fn slice<T: Float>(x: &Tensor<T>, axis: usize, start: usize, end: usize) -> Tensor<T> {
    let shape = x.shape();
    assert!(
        axis < shape.len() && start <= end && end <= shape[axis],
        "slice: {start}..{end} on axis {axis} of {shape:?}"
    );
    let (outer, inner) = split_at_axis(shape, axis);
    let n = shape[axis];
    let mut data = Vec::with_capacity(outer * (end - start) * inner);
    for o in 0..outer {
        data.extend_from_slice(&x.data()[(o * n + start) * inner..(o * n + end) * inner]);
    }
    let mut out_shape = shape.to_vec();
    out_shape[axis] = end - start;
    Tensor::from_vec(data, &out_shape)
}

/// The sub-range `start..end` of `axis`; backward pads the cotangent with zeros.
pub struct Slice {
    /// Axis to cut.
    pub axis: usize,
    /// First index kept.
    pub start: usize,
    /// One past the last index kept.
    pub end: usize,
}

impl<T: Float> Op<T> for Slice {
    type Saved = ();
    fn name(&self) -> String {
        format!("slice(axis={}, {}..{})", self.axis, self.start, self.end)
    }
    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        (vec![slice(x[0], self.axis, self.start, self.end)], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let shape = c.inputs[0].shape();
        let (outer, inner) = split_at_axis(shape, self.axis);
        let n = shape[self.axis];
        let width = (self.end - self.start) * inner;
        let mut dx = Tensor::zeros(shape);
        let g = c.grad_outputs[0].data();
        for o in 0..outer {
            let dst = (o * n + self.start) * inner;
            dx.data_mut()[dst..dst + width].copy_from_slice(&g[o * width..(o + 1) * width]);
        }
        vec![Some(dx)]
    }
}

/// Concatenates `xs` along `axis` (see [`Concat`]).
pub fn concat<'t, T: Float>(xs: &[Var<'t, T>], axis: usize) -> Var<'t, T> {
    assert!(!xs.is_empty(), "concat: no inputs");
    xs[0].tape().apply1(Concat(axis), xs)
}

impl<'t, T: Float> Var<'t, T> {
    /// Same values with a new shape of equal element count.
    pub fn reshape(self, shape: &[usize]) -> Var<'t, T> {
        self.tape().apply1(Reshape(shape.to_vec()), &[self])
    }
    /// Rows `index[i]` of `self` (first dimension), repeats allowed.
    pub fn gather_rows(self, index: &[usize]) -> Var<'t, T> {
        self.tape().apply1(GatherRows(index.to_vec()), &[self])
    }
    /// Adds row `i` of `self` into row `index[i]` of a zero tensor with `rows` rows.
    pub fn scatter_add_rows(self, index: &[usize], rows: usize) -> Var<'t, T> {
        self.tape().apply1(
            ScatterAddRows {
                index: index.to_vec(),
                rows,
            },
            &[self],
        )
    }
    /// The range `start..end` of `axis`.
    pub fn slice(self, axis: usize, start: usize, end: usize) -> Var<'t, T> {
        self.tape().apply1(Slice { axis, start, end }, &[self])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    fn x(shape: &[usize], seed: u64) -> Tensor<f64> {
        random_tensor(shape, -1.0, 1.0, seed)
    }

    #[test]
    fn reshape_gather_scatter_slice_pass_gradcheck() {
        let cfg = GradcheckConfig::default();
        gradcheck(
            |_, v| v[0].reshape(&[6, 2]).square(),
            &[x(&[3, 4], 1)],
            &cfg,
        )
        .assert_passed();
        // Repeated index: the gradient must accumulate both uses.
        gradcheck(
            |_, v| v[0].gather_rows(&[2, 0, 2, 1]).square(),
            &[x(&[3, 4], 2)],
            &cfg,
        )
        .assert_passed();
        gradcheck(
            |_, v| v[0].scatter_add_rows(&[1, 1, 0], 4).square(),
            &[x(&[3, 2], 3)],
            &cfg,
        )
        .assert_passed();
        gradcheck(|_, v| v[0].slice(1, 1, 3).square(), &[x(&[3, 4], 4)], &cfg).assert_passed();
        gradcheck(|_, v| v[0].slice(0, 2, 3).square(), &[x(&[3, 4], 5)], &cfg).assert_passed();
    }

    #[test]
    fn concat_passes_gradcheck_on_both_axes() {
        let cfg = GradcheckConfig::default();
        let inputs = [x(&[2, 3], 6), x(&[2, 1], 7), x(&[2, 2], 8)];
        gradcheck(|_, v| concat(v, 1).square(), &inputs, &cfg).assert_passed();
        let inputs = [x(&[1, 3], 9), x(&[2, 3], 10)];
        gradcheck(|_, v| concat(v, 0).square(), &inputs, &cfg).assert_passed();
    }

    #[test]
    fn concat_and_slice_values() {
        let t = crate::Tape::<f64>::new();
        let a = t.constant(Tensor::from_vec(vec![1.0, 2.0, 3.0, 4.0], &[2, 2]));
        let b = t.constant(Tensor::from_vec(vec![5.0, 6.0], &[2, 1]));
        let c = concat(&[a, b], 1);
        assert_eq!(c.value().data(), &[1.0, 2.0, 5.0, 3.0, 4.0, 6.0]);
        assert_eq!(c.slice(1, 1, 3).value().data(), &[2.0, 5.0, 4.0, 6.0]);
        assert_eq!(a.gather_rows(&[1, 1]).value().data(), &[3.0, 4.0, 3.0, 4.0]);
        assert_eq!(b.scatter_add_rows(&[0, 0], 1).value().data(), &[11.0]);
    }
}
