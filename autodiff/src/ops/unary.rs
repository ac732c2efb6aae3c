//! Elementwise unary ops: `y_i = f(x_i)`, backward `dx_i = dy_i f'(x_i)`.

use crate::op::{BackwardCtx, Op};
use crate::scalar::sigmoid;
use crate::{Float, Tensor, Var};

/// Which elementwise function a [`Unary`] op applies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UnaryKind {
    /// `exp(x)`; derivative `y`.
    Exp,
    /// `ln(x)`; derivative `1/x`.
    Ln,
    /// `sqrt(x)`; derivative `1/(2y)`.
    Sqrt,
    /// `x^2`; derivative `2x`.
    Square,
    /// `|x|`; derivative `sign(x)` (0 at 0).
    Abs,
    /// `1/(1+exp(-x))`; derivative `y(1-y)`.
    Sigmoid,
    /// `max(x, 0)`; derivative `[x > 0]`.
    Relu,
    /// `ln(1+exp(x))`, computed as `max(x,0) + ln(1+exp(-|x|))`; derivative `sigmoid(x)`.
    Softplus,
    /// `sin(x)`; derivative `cos(x)`.
    Sin,
    /// `cos(x)`; derivative `-sin(x)`.
    Cos,
    /// `tanh(x)`; derivative `1 - y^2`.
    Tanh,
    /// `-x`.
    Neg,
    /// `c x`; derivative `c`.
    Scale(f64),
    /// `x + c`; derivative 1.
    AddScalar(f64),
    /// `x^p` for a constant p; derivative `p x^(p-1)`.
    Powf(f64),
}

/// An elementwise op (see [`UnaryKind`]).
pub struct Unary(pub UnaryKind);

impl UnaryKind {
    fn eval<T: Float>(self, x: T) -> T {
        match self {
            UnaryKind::Exp => x.exp(),
            UnaryKind::Ln => x.ln(),
            UnaryKind::Sqrt => x.sqrt(),
            UnaryKind::Square => x * x,
            UnaryKind::Abs => x.abs(),
            UnaryKind::Sigmoid => sigmoid(x),
            UnaryKind::Relu => x.max(T::zero()),
            UnaryKind::Softplus => x.max(T::zero()) + (-x.abs()).exp().ln_1p(),
            UnaryKind::Sin => x.sin(),
            UnaryKind::Cos => x.cos(),
            UnaryKind::Tanh => x.tanh(),
            UnaryKind::Neg => -x,
            UnaryKind::Scale(c) => x * T::of(c),
            UnaryKind::AddScalar(c) => x + T::of(c),
            UnaryKind::Powf(p) => x.powf(T::of(p)),
        }
    }

    /// dy/dx given the input x and output y.
    fn derivative<T: Float>(self, x: T, y: T) -> T {
        let zero = T::zero();
        match self {
            UnaryKind::Exp => y,
            UnaryKind::Ln => T::one() / x,
            UnaryKind::Sqrt => T::of(0.5) / y,
            UnaryKind::Square => T::of(2.0) * x,
            UnaryKind::Abs => {
                if x > zero {
                    T::one()
                } else if x < zero {
                    -T::one()
                } else {
                    zero
                }
            }
            UnaryKind::Sigmoid => y * (T::one() - y),
            UnaryKind::Relu => {
                if x > zero {
                    T::one()
                } else {
                    zero
                }
            }
            UnaryKind::Softplus => sigmoid(x),
            UnaryKind::Sin => x.cos(),
            UnaryKind::Cos => -x.sin(),
            UnaryKind::Tanh => T::one() - y * y,
            UnaryKind::Neg => -T::one(),
            UnaryKind::Scale(c) => T::of(c),
            UnaryKind::AddScalar(_) => T::one(),
            UnaryKind::Powf(p) => T::of(p) * x.powf(T::of(p - 1.0)),
        }
    }
}

/// Evaluates `$body` with `$k` bound to `$kind`, in one copy per variant: inside each
/// copy the variant is a constant, so the per-element `match` of [`UnaryKind::eval`]
/// and [`UnaryKind::derivative`] folds away and the loop can vectorise.
macro_rules! unswitch {
    ($kind:expr, $k:ident => $body:expr) => {{
        use UnaryKind::*;
        match $kind {
            Exp => {
                let $k = Exp;
                $body
            }
            Ln => {
                let $k = Ln;
                $body
            }
            Sqrt => {
                let $k = Sqrt;
                $body
            }
            Square => {
                let $k = Square;
                $body
            }
            Abs => {
                let $k = Abs;
                $body
            }
            Sigmoid => {
                let $k = Sigmoid;
                $body
            }
            Relu => {
                let $k = Relu;
                $body
            }
            Softplus => {
                let $k = Softplus;
                $body
            }
            Sin => {
                let $k = Sin;
                $body
            }
            Cos => {
                let $k = Cos;
                $body
            }
            Tanh => {
                let $k = Tanh;
                $body
            }
            Neg => {
                let $k = Neg;
                $body
            }
            Scale(c) => {
                let $k = Scale(c);
                $body
            }
            AddScalar(c) => {
                let $k = AddScalar(c);
                $body
            }
            Powf(p) => {
                let $k = Powf(p);
                $body
            }
        }
    }};
}

impl<T: Float> Op<T> for Unary {
    type Saved = ();

    fn name(&self) -> String {
        format!("{:?}", self.0).to_lowercase()
    }

    fn forward(&self, inputs: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let x = inputs[0];
        (vec![unswitch!(self.0, k => x.map(|v| k.eval(v)))], ())
    }

    fn backward(&self, ctx: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let (x, y, g) = (ctx.inputs[0], ctx.outputs[0], &ctx.grad_outputs[0]);
        let data = unswitch!(self.0, k => x
            .data()
            .iter()
            .zip(y.data())
            .zip(g.data())
            .map(|((&x, &y), &g)| g * k.derivative(x, y))
            .collect());
        vec![Some(Tensor::from_vec(data, x.shape()))]
    }
}

impl<'t, T: Float> Var<'t, T> {
    fn unary(self, kind: UnaryKind) -> Var<'t, T> {
        self.tape().apply1(Unary(kind), &[self])
    }
    /// Elementwise `exp(x)`.
    pub fn exp(self) -> Var<'t, T> {
        self.unary(UnaryKind::Exp)
    }
    /// Elementwise natural logarithm.
    pub fn ln(self) -> Var<'t, T> {
        self.unary(UnaryKind::Ln)
    }
    /// Elementwise square root.
    pub fn sqrt(self) -> Var<'t, T> {
        self.unary(UnaryKind::Sqrt)
    }
    /// Elementwise `x^2`.
    pub fn square(self) -> Var<'t, T> {
        self.unary(UnaryKind::Square)
    }
    /// Elementwise `|x|` (subgradient 0 at 0).
    pub fn abs(self) -> Var<'t, T> {
        self.unary(UnaryKind::Abs)
    }
    /// Elementwise logistic sigmoid.
    pub fn sigmoid(self) -> Var<'t, T> {
        self.unary(UnaryKind::Sigmoid)
    }
    /// Elementwise `max(x, 0)`.
    pub fn relu(self) -> Var<'t, T> {
        self.unary(UnaryKind::Relu)
    }
    /// Elementwise `ln(1 + exp(x))`, numerically stable.
    pub fn softplus(self) -> Var<'t, T> {
        self.unary(UnaryKind::Softplus)
    }
    /// Elementwise sine.
    pub fn sin(self) -> Var<'t, T> {
        self.unary(UnaryKind::Sin)
    }
    /// Elementwise cosine.
    pub fn cos(self) -> Var<'t, T> {
        self.unary(UnaryKind::Cos)
    }
    /// Elementwise hyperbolic tangent.
    pub fn tanh(self) -> Var<'t, T> {
        self.unary(UnaryKind::Tanh)
    }
    /// `c x` for a constant `c`.
    pub fn scale(self, c: f64) -> Var<'t, T> {
        self.unary(UnaryKind::Scale(c))
    }
    /// `x + c` for a constant `c`.
    pub fn add_scalar(self, c: f64) -> Var<'t, T> {
        self.unary(UnaryKind::AddScalar(c))
    }
    /// `x^p` for a constant `p` (x > 0 unless p is an integer).
    pub fn powf(self, p: f64) -> Var<'t, T> {
        self.unary(UnaryKind::Powf(p))
    }
}

impl<'t, T: Float> std::ops::Neg for Var<'t, T> {
    type Output = Var<'t, T>;
    fn neg(self) -> Var<'t, T> {
        self.unary(UnaryKind::Neg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    fn check(kind: UnaryKind, lo: f64, hi: f64) {
        let x = random_tensor(&[3, 5], lo, hi, 7);
        let report = gradcheck(|_, v| v[0].unary(kind), &[x], &GradcheckConfig::default());
        assert!(report.passed(), "{kind:?}: {report}");
    }

    #[test]
    fn every_unary_op_passes_gradcheck() {
        use UnaryKind::*;
        for (kind, lo, hi) in [
            (Exp, -2.0, 2.0),
            (Ln, 0.2, 3.0),
            (Sqrt, 0.2, 3.0),
            (Square, -2.0, 2.0),
            (Abs, 0.1, 2.0),
            (Abs, -2.0, -0.1),
            (Sigmoid, -4.0, 4.0),
            (Relu, 0.1, 2.0),
            (Relu, -2.0, -0.1),
            (Softplus, -30.0, 30.0),
            (Sin, -3.0, 3.0),
            (Cos, -3.0, 3.0),
            (Tanh, -2.0, 2.0),
            (Neg, -2.0, 2.0),
            (Scale(-2.5), -2.0, 2.0),
            (AddScalar(3.0), -2.0, 2.0),
            (Powf(1.7), 0.2, 2.0),
        ] {
            check(kind, lo, hi);
        }
    }

    #[test]
    fn softplus_is_stable_for_large_inputs() {
        let t = crate::Tape::<f32>::new();
        let x = t.constant(Tensor::from_vec(vec![-200.0, 0.0, 200.0], &[3]));
        let y = x.softplus();
        let y = y.value();
        assert_eq!(y.data()[0], 0.0);
        assert!((y.data()[1] - 2f32.ln()).abs() < 1e-7);
        assert_eq!(y.data()[2], 200.0);
    }

    #[test]
    fn negative_control_wrong_derivative_is_rejected() {
        // Sin with the derivative of Cos: gradcheck must fail.
        struct WrongSin;
        impl Op<f64> for WrongSin {
            type Saved = ();
            fn name(&self) -> String {
                "wrong_sin".into()
            }
            fn forward(&self, x: &[&Tensor<f64>]) -> (Vec<Tensor<f64>>, ()) {
                (vec![x[0].map(f64::sin)], ())
            }
            fn backward(&self, c: &BackwardCtx<'_, f64, ()>) -> Vec<Option<Tensor<f64>>> {
                vec![Some(
                    c.inputs[0].zip_map(&c.grad_outputs[0], |x, g| -g * x.sin()),
                )]
            }
        }
        let x = random_tensor(&[4], -1.0, 1.0, 1);
        let report = gradcheck(
            |t, v| t.apply1(WrongSin, v),
            &[x],
            &GradcheckConfig::default(),
        );
        assert!(!report.passed());
        assert!(report.failures().len() == 4, "{report}");
    }
}
