//! Adam working on tensors outside the tape, and the learning-rate schedules that
//! give it each step's rate (the caller evaluates a schedule and passes the number).

use std::collections::HashMap;

use rayon::prelude::*;

use crate::{Float, PerGaussian, Tensor};

/// Elements per rayon task of an Adam update (whole rows when rows are scaled): each
/// element is updated alone, so the blocks change no value, only who computes it.
const ADAM_BLOCK: usize = 32 * 1024;

/// A learning rate as a function of the iteration.
#[derive(Clone, Debug, PartialEq)]
pub enum LrSchedule {
    /// The same rate at every iteration.
    Constant(f64),
    /// Log-linear decay from `init` to `last` over `max_steps` iterations, then flat
    /// (3DGS `get_expon_lr_func`): `lr(i) = exp((1-u) ln init + u ln last)`,
    /// `u = clamp(i / max_steps, 0, 1)`.
    ExpDecay {
        /// Rate at iteration 0.
        init: f64,
        /// Rate from `max_steps` on.
        last: f64,
        /// Length of the decay.
        max_steps: usize,
    },
    /// `lr` for iterations below `until`, 0 from `until` on: a parameter frozen after
    /// a first stage (Dynamic 3D Gaussians' opacities and scales after frame 0).
    Until {
        /// Rate before `until`.
        lr: f64,
        /// First iteration at rate 0.
        until: usize,
    },
}

impl LrSchedule {
    /// The rate at `iteration`.
    pub fn at(&self, iteration: usize) -> f64 {
        match *self {
            LrSchedule::Constant(lr) => lr,
            LrSchedule::ExpDecay {
                init,
                last,
                max_steps,
            } => {
                if init <= 0.0 || last <= 0.0 {
                    return 0.0;
                }
                let u = (iteration as f64 / max_steps.max(1) as f64).clamp(0.0, 1.0);
                ((1.0 - u) * init.ln() + u * last.ln()).exp()
            }
            LrSchedule::Until { lr, until } => {
                if iteration < until {
                    lr
                } else {
                    0.0
                }
            }
        }
    }
}

/// Adam's constants.
#[derive(Clone, Debug, PartialEq)]
pub struct AdamConfig {
    /// First-moment decay.
    pub beta1: f64,
    /// Second-moment decay.
    pub beta2: f64,
    /// Denominator guard (3DGS uses 1e-15).
    pub eps: f64,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig {
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-15,
        }
    }
}

/// Adam's running moments for one parameter; rows follow the parameter's rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Moments<T: Float> {
    /// First moment, same shape as the parameter.
    pub m: Tensor<T>,
    /// Second moment, same shape as the parameter.
    pub v: Tensor<T>,
    /// Updates applied so far (for bias correction).
    pub steps: u64,
}

impl<T: Float> PerGaussian for Moments<T> {
    fn rows(&self) -> usize {
        self.m.rows()
    }
    /// Selected rows keep their moments (clones copy them, as in 3DGS's
    /// `densification_postfix` the new rows could also start at zero; maaf copies).
    fn select_rows(&mut self, index: &[usize]) {
        self.m.select_rows(index);
        self.v.select_rows(index);
    }
}

/// Adam (Kingma and Ba 2015) with bias correction, moments per named parameter and
/// the learning rate given at each step (a number: `LrSchedule::at` of the
/// parameter's schedule, or anything else):
/// `m = b1 m + (1-b1) g`, `v = b2 v + (1-b2) g^2`,
/// `p -= lr * (m / (1-b1^t)) / (sqrt(v / (1-b2^t)) + eps)`.
#[derive(Clone, Debug)]
pub struct Adam<T: Float> {
    config: AdamConfig,
    state: HashMap<String, Moments<T>>,
}

impl<T: Float> Adam<T> {
    /// An optimiser with no moments yet.
    pub fn new(config: AdamConfig) -> Self {
        Adam {
            config,
            state: HashMap::new(),
        }
    }

    /// One Adam update of `param` with gradient `grad` at learning rate `lr`; the
    /// moments of `name` start at zero on its first step. Panics if shapes differ.
    pub fn step(&mut self, name: &str, param: &mut Tensor<T>, grad: &Tensor<T>, lr: f64) {
        self.step_l2(name, param, grad, lr, 0.0);
    }

    /// [`Adam::step`] with L2 weight decay folded into the gradient first,
    /// `g' = g + weight_decay * p` (PyTorch `Adam(weight_decay=...)`, which SaRO-GS
    /// uses for its MLPs and planes; not AdamW's decoupled decay).
    pub fn step_l2(
        &mut self,
        name: &str,
        param: &mut Tensor<T>,
        grad: &Tensor<T>,
        lr: f64,
        weight_decay: f64,
    ) {
        self.step_rows(name, param, grad, lr, weight_decay, None);
    }

    /// [`Adam::step_l2`] with a learning rate per row: row `r` of `param` (its first
    /// axis) moves by `lr * row_scale[r] * m_hat / (sqrt(v_hat) + eps)`; the
    /// moments are those of plain Adam. SaRO-GS's adaptive optimisation scales the
    /// rates of short-lived Gaussians this way (`update_learning_rate` with a
    /// per-Gaussian `lr` column). `None` is a scale of 1 everywhere. Panics if
    /// `row_scale` does not have one entry per row.
    pub fn step_rows(
        &mut self,
        name: &str,
        param: &mut Tensor<T>,
        grad: &Tensor<T>,
        lr: f64,
        weight_decay: f64,
        row_scale: Option<&[T]>,
    ) {
        assert_eq!(
            param.shape(),
            grad.shape(),
            "Adam: gradient of `{name}` has the wrong shape"
        );
        let state = self
            .state
            .entry(name.to_string())
            .or_insert_with(|| Moments {
                m: Tensor::zeros(param.shape()),
                v: Tensor::zeros(param.shape()),
                steps: 0,
            });
        assert_eq!(
            state.m.shape(),
            param.shape(),
            "Adam: moments of `{name}` were not resized with it"
        );
        state.steps += 1;
        let AdamConfig { beta1, beta2, eps } = self.config;
        let c1 = 1.0 - beta1.powi(state.steps as i32);
        let c2 = 1.0 - beta2.powi(state.steps as i32);
        let (b1, b2) = (T::of(beta1), T::of(beta2));
        let (one, step, eps) = (T::one(), T::of(lr / c1), T::of(eps));
        let inv_c2 = T::of(1.0 / c2);
        let wd = T::of(weight_decay);
        let decay = weight_decay != 0.0;
        let (m, v) = (state.m.data_mut(), state.v.data_mut());
        // Each factor is zeroed where its product would be subnormal, as on a
        // flush-to-zero FPU (see `zero_below`).
        let tiny = T::min_positive_value();
        let p_min = if decay { tiny / wd } else { T::infinity() };
        let (g_min, g2_min) = (tiny / (one - b1), (tiny / (one - b2)).sqrt());
        let (m_min, v_min) = (tiny / b1, tiny / b2);
        let update = |p: &mut [T], g: &[T], m: &mut [T], v: &mut [T], step: T| {
            let step_min = tiny / step;
            for (((p, &g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
                let g = if decay {
                    g + wd * zero_below(*p, p_min)
                } else {
                    g
                };
                *m = b1 * zero_below(*m, m_min) + (one - b1) * zero_below(g, g_min);
                let g2 = zero_below(g, g2_min);
                *v = b2 * zero_below(*v, v_min) + (one - b2) * g2 * g2;
                *p -= step * zero_below(*m, step_min) / ((*v * inv_c2).sqrt() + eps);
            }
        };
        // Rows (one element each when unscaled) in blocks of about ADAM_BLOCK elements.
        let width = match row_scale {
            None => 1,
            Some(scale) => {
                let rows = param.rows();
                assert_eq!(
                    scale.len(),
                    rows,
                    "Adam: row scale of `{name}` has {} entries for {rows} rows",
                    scale.len()
                );
                if param.is_empty() {
                    return;
                }
                param.len() / rows
            }
        };
        let block_rows = (ADAM_BLOCK / width).max(1);
        let block = block_rows * width;
        param
            .data_mut()
            .par_chunks_mut(block)
            .zip(grad.data().par_chunks(block))
            .zip(m.par_chunks_mut(block).zip(v.par_chunks_mut(block)))
            .enumerate()
            .for_each(|(b, ((p, g), (m, v)))| match row_scale {
                None => update(p, g, m, v, step),
                Some(scale) => {
                    let rows = p
                        .chunks_mut(width)
                        .zip(g.chunks(width))
                        .zip(m.chunks_mut(width).zip(v.chunks_mut(width)));
                    for (((p, g), (m, v)), &s) in rows.zip(&scale[b * block_rows..]) {
                        update(p, g, m, v, step * s);
                    }
                }
            });
    }

    /// The moments of `name`, for resizing with its parameter or checkpointing.
    pub fn moments_mut(&mut self, name: &str) -> Option<&mut Moments<T>> {
        self.state.get_mut(name)
    }

    /// Zeroes both moments of `name`, keeping its step count (PyTorch keeps `step`
    /// when a parameter's `exp_avg` and `exp_avg_sq` are replaced, as 3DGS's opacity
    /// reset and Dynamic 3D Gaussians' new frames do); false when it has none yet.
    pub fn zero_moments(&mut self, name: &str) -> bool {
        let Some(m) = self.state.get_mut(name) else {
            return false;
        };
        m.m.data_mut().fill(T::zero());
        m.v.data_mut().fill(T::zero());
        true
    }

    /// The moments of `name`.
    pub fn moments(&self, name: &str) -> Option<&Moments<T>> {
        self.state.get(name)
    }

    /// Restores moments (e.g. from a checkpoint).
    pub fn set_moments(&mut self, name: &str, moments: Moments<T>) {
        self.state.insert(name.to_string(), moments);
    }

    /// Names with moments, sorted.
    pub fn names(&self) -> Vec<&str> {
        let mut names: Vec<&str> = self.state.keys().map(String::as_str).collect();
        names.sort_unstable();
        names
    }
}

/// `x`, or zero when `|x| < min`: Adam's guard against subnormal arithmetic. A
/// moment that decays with no gradient (a K-plane cell or a Gaussian that no view
/// reaches) goes subnormal after a few hundred steps at beta1 = 0.9, and L2 decay
/// drives such parameters towards zero until `weight_decay * p` and `g * g` underflow.
/// Every multiply that reads or writes a subnormal takes a microcode assist of about
/// a hundred cycles: on a SaRO model trained 20k iterations, most cells of the spatial
/// planes were in that state and Adam took 23 ms per step. `step_rows` zeroes each
/// factor where its product would be subnormal (`min` is the smallest normal over the
/// other factor), which is what a flush-to-zero FPU returns, without touching the
/// FPU's mode (Rust treats a changed MXCSR as undefined behaviour); in the normal
/// range nothing changes. The products are taken after the select, so no lane of a
/// vectorised loop computes the subnormal value it then discards.
#[inline(always)]
fn zero_below<T: Float>(x: T, min: T) -> T {
    if x.abs() < min { T::zero() } else { x }
}

#[cfg(test)]
mod tests;
