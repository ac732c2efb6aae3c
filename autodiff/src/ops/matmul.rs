//! Matrix product through [`crate::Float::gemm`] (the `gemm` crate's kernels on fixed
//! blocks over rayon).

use crate::op::{BackwardCtx, Op};
use crate::{Float, Tensor, Var};

/// `C = A B` for `A` [m, k] and `B` [k, n]; backward `dA = dC B^T`, `dB = A^T dC`
/// (transposes are stride swaps, no copies).
pub struct Matmul;

impl<T: Float> Op<T> for Matmul {
    type Saved = ();

    fn name(&self) -> String {
        "matmul".into()
    }

    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let (a, b) = (x[0], x[1]);
        let (sa, sb) = (a.shape(), b.shape());
        assert!(
            sa.len() == 2 && sb.len() == 2 && sa[1] == sb[0],
            "matmul: shapes {sa:?} x {sb:?} do not chain"
        );
        let (m, k, n) = (sa[0], sa[1], sb[1]);
        let mut c = Tensor::zeros(&[m, n]);
        T::gemm(
            m,
            k,
            n,
            T::one(),
            a.data(),
            k as isize,
            1,
            b.data(),
            n as isize,
            1,
            T::zero(),
            c.data_mut(),
            n as isize,
            1,
        );
        (vec![c], ())
    }

    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (a, b, g) = (c.inputs[0], c.inputs[1], &c.grad_outputs[0]);
        let (m, k, n) = (a.shape()[0], a.shape()[1], b.shape()[1]);
        let da = c.needs_grad[0].then(|| {
            let mut da = Tensor::zeros(&[m, k]);
            // dA [m,k] = G [m,n] * B^T [n,k]; B^T has row stride 1, column stride n.
            T::gemm(
                m,
                n,
                k,
                T::one(),
                g.data(),
                n as isize,
                1,
                b.data(),
                1,
                n as isize,
                T::zero(),
                da.data_mut(),
                k as isize,
                1,
            );
            da
        });
        let db = c.needs_grad[1].then(|| {
            let mut db = Tensor::zeros(&[k, n]);
            // dB [k,n] = A^T [k,m] * G [m,n]; A^T has row stride 1, column stride k.
            T::gemm(
                k,
                m,
                n,
                T::one(),
                a.data(),
                1,
                k as isize,
                g.data(),
                n as isize,
                1,
                T::zero(),
                db.data_mut(),
                n as isize,
                1,
            );
            db
        });
        vec![da, db]
    }
}

impl<'t, T: Float> Var<'t, T> {
    /// Matrix product `self [m, k] x rhs [k, n]`.
    pub fn matmul(self, rhs: Var<'t, T>) -> Var<'t, T> {
        self.tape().apply1(Matmul, &[self, rhs])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    #[test]
    fn matmul_matches_a_triple_loop() {
        let a: Tensor<f64> = random_tensor(&[5, 7], -1.0, 1.0, 1);
        let b: Tensor<f64> = random_tensor(&[7, 3], -1.0, 1.0, 2);
        let t = crate::Tape::new();
        let c = t.constant(a.clone()).matmul(t.constant(b.clone()));
        let c = c.value();
        for i in 0..5 {
            for j in 0..3 {
                let want: f64 = (0..7)
                    .map(|p| a.data()[i * 7 + p] * b.data()[p * 3 + j])
                    .sum();
                assert!((c.data()[i * 3 + j] - want).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn matmul_passes_gradcheck_in_f64() {
        let a = random_tensor(&[4, 6], -1.0, 1.0, 3);
        let b = random_tensor(&[6, 5], -1.0, 1.0, 4);
        gradcheck(
            |_, v| v[0].matmul(v[1]),
            &[a, b],
            &GradcheckConfig::default(),
        )
        .assert_passed();
    }

    #[test]
    fn f32_matmul_agrees_with_f64() {
        let a: Tensor<f64> = random_tensor(&[9, 8], -1.0, 1.0, 5);
        let b: Tensor<f64> = random_tensor(&[8, 4], -1.0, 1.0, 6);
        let t64 = crate::Tape::new();
        let c64 = t64
            .constant(a.clone())
            .matmul(t64.constant(b.clone()))
            .value()
            .clone();
        let t32 = crate::Tape::<f32>::new();
        let c32 = t32
            .constant(a.cast())
            .matmul(t32.constant(b.cast()))
            .value()
            .to_f64();
        assert!(crate::check::compare(&c64, &c32, 1e-5, 1e-5).passed());
    }
}
