//! Reductions: sum and mean over all elements or along one axis.

use crate::op::{BackwardCtx, Op};
use crate::{Float, Tensor, Var};

/// Sum (or mean) over everything (`axis = None`, rank-0 output) or over one axis
/// (that axis removed). Backward broadcasts the cotangent back, divided by the count
/// for a mean.
pub struct Reduce {
    /// Axis to reduce, or `None` for all elements.
    pub axis: Option<usize>,
    /// Divide by the number of reduced elements.
    pub mean: bool,
}

fn outer_inner(shape: &[usize], axis: usize) -> (usize, usize, usize) {
    (
        shape[..axis].iter().product(),
        shape[axis],
        shape[axis + 1..].iter().product(),
    )
}

impl<T: Float> Op<T> for Reduce {
    type Saved = ();

    fn name(&self) -> String {
        let what = if self.mean { "mean" } else { "sum" };
        match self.axis {
            Some(a) => format!("{what}(axis={a})"),
            None => what.into(),
        }
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let x = x[0];
        match self.axis {
            None => {
                let s = x.sum();
                let s = if self.mean {
                    s / T::of(x.len().max(1) as f64)
                } else {
                    s
                };
                (vec![Tensor::scalar(s)], ())
            }
            Some(axis) => {
                assert!(
                    axis < x.shape().len(),
                    "reduce: axis {axis} out of range for {:?}",
                    x.shape()
                );
                let (outer, n, inner) = outer_inner(x.shape(), axis);
                let mut out = vec![T::zero(); outer * inner];
                for o in 0..outer {
                    for k in 0..n {
                        let src = &x.data()[(o * n + k) * inner..(o * n + k + 1) * inner];
                        for (d, &s) in out[o * inner..(o + 1) * inner].iter_mut().zip(src) {
                            *d += s;
                        }
                    }
                }
                if self.mean {
                    let inv = T::one() / T::of(n.max(1) as f64);
                    out.iter_mut().for_each(|v| *v *= inv);
                }
                let mut shape = x.shape().to_vec();
                shape.remove(axis);
                (vec![Tensor::from_vec(out, &shape)], ())
            }
        }
    }

    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (x, g) = (c.inputs[0], &c.grad_outputs[0]);
        let dx = match self.axis {
            None => {
                let scale = if self.mean {
                    T::one() / T::of(x.len().max(1) as f64)
                } else {
                    T::one()
                };
                Tensor::full(x.shape(), g.item() * scale)
            }
            Some(axis) => {
                let (outer, n, inner) = outer_inner(x.shape(), axis);
                let scale = if self.mean {
                    T::one() / T::of(n.max(1) as f64)
                } else {
                    T::one()
                };
                let mut dx = Vec::with_capacity(x.len());
                for o in 0..outer {
                    let row = &g.data()[o * inner..(o + 1) * inner];
                    for _ in 0..n {
                        dx.extend(row.iter().map(|&v| v * scale));
                    }
                }
                Tensor::from_vec(dx, x.shape())
            }
        };
        vec![Some(dx)]
    }
}

impl<'t, T: Float> Var<'t, T> {
    /// Sum of all elements (rank-0 result).
    pub fn sum(self) -> Var<'t, T> {
        self.tape().apply1(
            Reduce {
                axis: None,
                mean: false,
            },
            &[self],
        )
    }
    /// Mean of all elements (rank-0 result).
    pub fn mean(self) -> Var<'t, T> {
        self.tape().apply1(
            Reduce {
                axis: None,
                mean: true,
            },
            &[self],
        )
    }
    /// Sum along `axis` (removed from the shape).
    pub fn sum_axis(self, axis: usize) -> Var<'t, T> {
        self.tape().apply1(
            Reduce {
                axis: Some(axis),
                mean: false,
            },
            &[self],
        )
    }
    /// Mean along `axis` (removed from the shape).
    pub fn mean_axis(self, axis: usize) -> Var<'t, T> {
        self.tape().apply1(
            Reduce {
                axis: Some(axis),
                mean: true,
            },
            &[self],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    #[test]
    fn reductions_pass_gradcheck() {
        let cfg = GradcheckConfig::default();
        let x = random_tensor(&[2, 3, 4], -1.0, 1.0, 3);
        for mean in [false, true] {
            for axis in [None, Some(0), Some(1), Some(2)] {
                let report = gradcheck(
                    |t, v| t.apply1(Reduce { axis, mean }, v).square(),
                    std::slice::from_ref(&x),
                    &cfg,
                );
                assert!(report.passed(), "mean={mean} axis={axis:?}: {report}");
            }
        }
    }

    #[test]
    fn reduction_values() {
        let t = crate::Tape::<f64>::new();
        let x = t.constant(Tensor::from_vec(
            vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            &[2, 3],
        ));
        assert_eq!(x.sum().value().item(), 21.0);
        assert_eq!(x.mean().value().item(), 3.5);
        assert_eq!(x.sum_axis(0).value().data(), &[5.0, 7.0, 9.0]);
        assert_eq!(x.mean_axis(1).value().data(), &[2.0, 5.0]);
    }
}
