//! Small neural-network helpers built from primitives: [`Linear`] and [`Mlp`].
//!
//! Weights live outside the tape as plain tensors (so an optimiser can update them);
//! each step binds them to a tape under a name prefix with `bind`, which returns
//! handles whose `forward` records the computation.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use crate::ops::dense::Activation;
use crate::{Float, Tape, Tensor, Var};

/// A fully connected layer `y = x W + b`, `W` \[in, out\], `b` \[out\].
#[derive(Clone, Debug, PartialEq)]
pub struct Linear<T: Float> {
    /// Weight matrix [in, out].
    pub weight: Tensor<T>,
    /// Bias \[out\].
    pub bias: Tensor<T>,
}

impl<T: Float> Linear<T> {
    /// PyTorch's default initialisation: `W, b ~ U(-1/sqrt(in), 1/sqrt(in))`, seeded.
    pub fn new(inputs: usize, outputs: usize, seed: u64) -> Self {
        let mut rng = Pcg64::seed_from_u64(seed);
        let bound = 1.0 / (inputs.max(1) as f64).sqrt();
        let mut draw = |n: usize| -> Vec<T> {
            (0..n)
                .map(|_| T::of(rng.random_range(-bound..bound)))
                .collect()
        };
        Linear {
            weight: Tensor::from_vec(draw(inputs * outputs), &[inputs, outputs]),
            bias: Tensor::from_vec(draw(outputs), &[outputs]),
        }
    }

    /// A layer whose weight and bias are zero: its output is 0 for any input, which
    /// makes a residual head start as the identity deformation.
    pub fn zeros(inputs: usize, outputs: usize) -> Self {
        Linear {
            weight: Tensor::zeros(&[inputs, outputs]),
            bias: Tensor::zeros(&[outputs]),
        }
    }

    /// Registers `{name}.weight` and `{name}.bias` as parameters on `tape`.
    pub fn bind<'t>(&self, tape: &'t Tape<T>, name: &str) -> LinearVars<'t, T> {
        LinearVars {
            weight: tape.param(&format!("{name}.weight"), self.weight.clone()),
            bias: tape.param(&format!("{name}.bias"), self.bias.clone()),
        }
    }

    /// Parameters as `(name, tensor)` pairs under `name`.
    pub fn params_mut(&mut self, name: &str) -> Vec<(String, &mut Tensor<T>)> {
        vec![
            (format!("{name}.weight"), &mut self.weight),
            (format!("{name}.bias"), &mut self.bias),
        ]
    }
}

/// A [`Linear`] bound to a tape.
#[derive(Clone, Copy)]
pub struct LinearVars<'t, T: Float> {
    /// Weight handle.
    pub weight: Var<'t, T>,
    /// Bias handle.
    pub bias: Var<'t, T>,
}

impl<'t, T: Float> LinearVars<'t, T> {
    /// `x W + b` for `x` [rows, in], as one fused [`crate::ops::dense::Dense`] op.
    pub fn forward(&self, x: Var<'t, T>) -> Var<'t, T> {
        self.forward_act(x, Activation::Identity)
    }

    /// `act(x W + b)` for `x` [rows, in], as one fused [`crate::ops::dense::Dense`] op.
    pub fn forward_act(&self, x: Var<'t, T>, act: Activation) -> Var<'t, T> {
        x.dense(self.weight, self.bias, act)
    }
}

/// A multilayer perceptron: linear layers with ReLU between them, none after the last.
#[derive(Clone, Debug, PartialEq)]
pub struct Mlp<T: Float> {
    /// The layers, input first.
    pub layers: Vec<Linear<T>>,
}

impl<T: Float> Mlp<T> {
    /// Layers of sizes `widths[0] -> widths[1] -> ... -> widths[last]`, seeded; when
    /// `zero_output` is set the last layer starts at zero (see [`Linear::zeros`]).
    pub fn new(widths: &[usize], zero_output: bool, seed: u64) -> Self {
        assert!(
            widths.len() >= 2,
            "Mlp::new: need at least input and output widths"
        );
        let n = widths.len() - 1;
        let layers = (0..n)
            .map(|i| {
                if zero_output && i == n - 1 {
                    Linear::zeros(widths[i], widths[i + 1])
                } else {
                    Linear::new(
                        widths[i],
                        widths[i + 1],
                        seed.wrapping_mul(1_000_003).wrapping_add(i as u64),
                    )
                }
            })
            .collect();
        Mlp { layers }
    }

    /// Registers every layer's parameters as `{name}.{i}.weight` / `.bias`.
    pub fn bind<'t>(&self, tape: &'t Tape<T>, name: &str) -> MlpVars<'t, T> {
        MlpVars {
            layers: self
                .layers
                .iter()
                .enumerate()
                .map(|(i, l)| l.bind(tape, &format!("{name}.{i}")))
                .collect(),
        }
    }

    /// Parameters as `(name, tensor)` pairs, named as in [`Mlp::bind`].
    pub fn params_mut(&mut self, name: &str) -> Vec<(String, &mut Tensor<T>)> {
        self.layers
            .iter_mut()
            .enumerate()
            .flat_map(|(i, l)| l.params_mut(&format!("{name}.{i}")))
            .collect()
    }

    /// Number of scalar parameters.
    pub fn num_params(&self) -> usize {
        self.layers
            .iter()
            .map(|l| l.weight.len() + l.bias.len())
            .sum()
    }
}

/// An [`Mlp`] bound to a tape.
pub struct MlpVars<'t, T: Float> {
    /// Bound layers, input first.
    pub layers: Vec<LinearVars<'t, T>>,
}

impl<'t, T: Float> MlpVars<'t, T> {
    /// Runs the network on `x` [rows, in]: `h_{i+1} = relu(h_i W_i + b_i)` for the
    /// hidden layers and `h_i W_i + b_i` for the last, as one fused
    /// [`crate::ops::mlp::FusedMlp`] op (bit-identical to one dense op per layer).
    pub fn forward(&self, x: Var<'t, T>) -> Var<'t, T> {
        let layers: Vec<_> = self.layers.iter().map(|l| (l.weight, l.bias)).collect();
        x.mlp(&layers)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};

    #[test]
    fn zero_output_mlp_outputs_zero() {
        let mlp = Mlp::<f32>::new(&[4, 8, 3], true, 1);
        let tape = Tape::new();
        let x = tape.constant(random_tensor(&[5, 4], -1.0, 1.0, 2));
        let y = mlp.bind(&tape, "m").forward(x);
        assert!(y.value().data().iter().all(|&v| v == 0.0));
        assert_eq!(mlp.num_params(), 4 * 8 + 8 + 8 * 3 + 3);
    }

    #[test]
    fn two_layer_mlp_passes_gradcheck_end_to_end() {
        // Inputs, both weight matrices and both biases are checked; the loss is a
        // squared error so every path through the ReLU contributes.
        let mlp = Mlp::<f64>::new(&[3, 6, 2], false, 3);
        let x = random_tensor(&[4, 3], -1.0, 1.0, 4);
        let target = random_tensor(&[4, 2], -1.0, 1.0, 5);
        let mut inputs = vec![x];
        for l in &mlp.layers {
            inputs.push(l.weight.clone());
            inputs.push(l.bias.clone());
        }
        let report = gradcheck(
            |t, v| {
                let net = MlpVars {
                    layers: vec![
                        LinearVars {
                            weight: v[1],
                            bias: v[2],
                        },
                        LinearVars {
                            weight: v[3],
                            bias: v[4],
                        },
                    ],
                };
                (net.forward(v[0]) - t.constant(target.clone()))
                    .square()
                    .mean()
            },
            &inputs,
            &GradcheckConfig::default(),
        );
        report.assert_passed();
        assert_eq!(report.checked, 4 * 3 + 3 * 6 + 6 + 6 * 2 + 2);
    }
}
