//! Dense row-major tensors.

use smallvec::SmallVec;

use crate::Float;

/// Shape of a tensor: up to four dimensions inline.
pub type Shape = SmallVec<[usize; 4]>;

/// A dense row-major tensor: a flat `Vec<T>` plus a shape. A plain value; gradients
/// live in [`crate::Grads`], never inside the tensor.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor<T> {
    data: Vec<T>,
    shape: Shape,
}

impl<T: Float> Tensor<T> {
    /// Wraps `data` with `shape`; panics if the element count does not match.
    pub fn from_vec(data: Vec<T>, shape: &[usize]) -> Self {
        let n: usize = shape.iter().product();
        assert_eq!(
            data.len(),
            n,
            "Tensor::from_vec: {} values for shape {shape:?}",
            data.len()
        );
        Tensor {
            data,
            shape: shape.into(),
        }
    }

    /// A tensor of zeros.
    pub fn zeros(shape: &[usize]) -> Self {
        Self::full(shape, T::zero())
    }

    /// A tensor filled with `value`.
    pub fn full(shape: &[usize], value: T) -> Self {
        Tensor {
            data: vec![value; shape.iter().product()],
            shape: shape.into(),
        }
    }

    /// A rank-0 tensor holding one value.
    pub fn scalar(value: T) -> Self {
        Tensor {
            data: vec![value],
            shape: Shape::new(),
        }
    }

    /// Converts from f64 values (rounding for f32).
    pub fn from_f64(data: &[f64], shape: &[usize]) -> Self {
        Self::from_vec(data.iter().map(|&x| T::of(x)).collect(), shape)
    }

    /// The values as f64.
    pub fn to_f64(&self) -> Tensor<f64> {
        Tensor {
            data: self.data.iter().map(|x| Float::to_f64(*x)).collect(),
            shape: self.shape.clone(),
        }
    }

    /// Converts to another float type.
    pub fn cast<U: Float>(&self) -> Tensor<U> {
        Tensor {
            data: self.data.iter().map(|x| U::of(Float::to_f64(*x))).collect(),
            shape: self.shape.clone(),
        }
    }

    /// Flat row-major values.
    pub fn data(&self) -> &[T] {
        &self.data
    }

    /// Mutable flat values.
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// Consumes the tensor, returning its flat values.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// The shape.
    pub fn shape(&self) -> &[usize] {
        &self.shape
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// True when the tensor holds no element.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Size of the first dimension (1 for a scalar).
    pub fn rows(&self) -> usize {
        self.shape.first().copied().unwrap_or(1)
    }

    /// Elements per row: the product of all dimensions after the first.
    pub fn row_len(&self) -> usize {
        self.shape.iter().skip(1).product()
    }

    /// The same values under a new shape with the same element count.
    pub fn reshaped(mut self, shape: &[usize]) -> Self {
        let n: usize = shape.iter().product();
        assert_eq!(n, self.data.len(), "reshape: {:?} -> {shape:?}", self.shape);
        self.shape = shape.into();
        self
    }

    /// Rows `index[0], index[1], ...` of the first dimension, repeats allowed (the row
    /// gather behind the `gather_rows` op and every per-Gaussian resize).
    pub fn gather_rows(&self, index: &[usize]) -> Self {
        let (rows, w) = (self.rows(), self.row_len());
        let mut data = Vec::with_capacity(index.len() * w);
        for &i in index {
            assert!(
                i < rows,
                "gather_rows: index {i} out of range for {rows} rows"
            );
            data.extend_from_slice(&self.data[i * w..(i + 1) * w]);
        }
        let mut shape = self.shape.clone();
        shape[0] = index.len();
        Tensor { data, shape }
    }

    /// Applies `f` to every element.
    pub fn map(&self, f: impl Fn(T) -> T) -> Self {
        Tensor {
            data: self.data.iter().map(|&x| f(x)).collect(),
            shape: self.shape.clone(),
        }
    }

    /// Elementwise combination of two tensors of the same shape.
    pub fn zip_map(&self, other: &Self, f: impl Fn(T, T) -> T) -> Self {
        assert_eq!(self.shape, other.shape, "zip_map: shape mismatch");
        Tensor {
            data: self
                .data
                .iter()
                .zip(&other.data)
                .map(|(&a, &b)| f(a, b))
                .collect(),
            shape: self.shape.clone(),
        }
    }

    /// `self += other` elementwise (same shape).
    pub fn add_assign(&mut self, other: &Self) {
        assert_eq!(self.shape, other.shape, "add_assign: shape mismatch");
        for (a, &b) in self.data.iter_mut().zip(&other.data) {
            *a += b;
        }
    }

    /// Index of the first NaN or infinite value, if any.
    pub fn first_non_finite(&self) -> Option<usize> {
        self.data.iter().position(|x| !x.is_finite())
    }

    /// The single value of a one-element tensor.
    pub fn item(&self) -> T {
        assert_eq!(
            self.data.len(),
            1,
            "item: tensor has {} elements",
            self.data.len()
        );
        self.data[0]
    }

    /// Sum of all elements (sequential, deterministic order).
    pub fn sum(&self) -> T {
        self.data.iter().copied().sum()
    }
}
