//! The training objective (docs/architecture.md): a list of named, weighted [`Term`]s.
//!
//! `total = sum_k w_k * term_k(ctx)`, and every term's unweighted value is returned by
//! name for logging. The default 3DGS / SaRO-GS photometric loss is
//! `(1 - 0.2) L1 + 0.2 (1 - SSIM)` ([`Objective::photometric`]); a representation's
//! own regularisers (SaRO-GS's `8e-6 L_SR`, `helper_train.py::getloss`) are added by
//! [`Objective::for_model`] with the weights the representation declares. A new term
//! is one `impl Term` (or a closure, [`Objective::with_fn`]) plus [`Objective::with`],
//! or registered by name in a [`TermRegistry`] so that a config's `terms` names it
//! with a weight ([`Objective::for_run`]; the built-in regularisers are in
//! [`builtin`]); the training step only calls [`Objective::evaluate`], so it never
//! changes.
//!
//! ```
//! use maaf_autodiff::{Tape, Tensor};
//! use maaf_train::loss::{Objective, TermCtx};
//! let tape = Tape::<f64>::new();
//! let gt = Tensor::full(&[16, 16, 3], 0.5);
//! let render = tape.param("render", Tensor::full(&[16, 16, 3], 0.25));
//! let out = Objective::photometric(0.2).evaluate(&TermCtx::new(render, &gt));
//! assert!((out.get("l1").unwrap() - 0.25).abs() < 1e-12);
//! let grads = tape.backward(out.total).unwrap();
//! assert!(grads.param("render").is_some());
//! ```

pub mod builtin;
mod forward_terms;
mod registry;
pub mod ssim;
mod terms;

use maaf_autodiff::{Float, Var};

pub use forward_terms::{ForwardTerms, batch_mean};
pub use maaf_scene::{RESERVED, name_problem};
pub use registry::{TermMaker, TermRegistry};
pub use ssim::{Ssim, SsimOutput, ssim, ssim_map};
pub use terms::{DSsim, FnTerm, L1, Provided, Term, TermCtx};

use std::collections::BTreeMap;

use crate::Error;
use crate::models::Representation;

/// A weighted sum of named terms (module docs).
pub struct Objective<T: Float> {
    terms: Vec<Box<dyn Term<T>>>,
    /// Terms a config named that no registry knew ([`Objective::for_run`]).
    unregistered: Vec<String>,
}

impl<T: Float> Default for Objective<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// The value of one term in one step, for logging.
#[derive(Clone, Debug, PartialEq)]
pub struct TermValue {
    /// [`Term::name`].
    pub name: String,
    /// [`Term::weight`].
    pub weight: f64,
    /// Unweighted value `term(ctx)`.
    pub value: f64,
}

/// What [`Objective::evaluate`] returns: the total on the tape (call
/// `tape.backward(total)`) and each term's value in insertion order.
pub struct Evaluated<'t, T: Float> {
    /// `sum_k w_k term_k`, rank 0.
    pub total: Var<'t, T>,
    /// One entry per term, in the order the terms were added.
    pub terms: Vec<TermValue>,
}

impl<T: Float> Evaluated<'_, T> {
    /// The unweighted value of the term called `name`.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.terms.iter().find(|t| t.name == name).map(|t| t.value)
    }

    /// The value of the total as f64.
    pub fn total_value(&self) -> f64 {
        Float::to_f64(self.total.value().item())
    }
}

impl<T: Float> Objective<T> {
    /// An objective with no term (its total is 0).
    pub fn new() -> Self {
        Objective {
            terms: Vec::new(),
            unregistered: Vec::new(),
        }
    }

    /// `(1 - lambda) L1 + lambda D-SSIM`, the 3DGS photometric loss (`lambda = 0.2` in
    /// 3DGS and SaRO-GS, the default of `TrainConfig::lambda_dssim`), as the two terms
    /// `l1` and `dssim`.
    pub fn photometric(lambda: f64) -> Self {
        Self::new()
            .with(L1 {
                weight: 1.0 - lambda,
            })
            .with(DSsim { weight: lambda })
    }

    /// The training objective of `model`: [`Objective::photometric`]`(lambda)` plus
    /// one [`Provided`] term per regulariser the representation declares, with its
    /// weight (SaRO: `8e-6 l_sr`; 0 on steps where the model does not provide it,
    /// e.g. the static stage).
    pub fn for_model(lambda: f64, model: &dyn Representation<T>) -> Self {
        let mut out = Self::photometric(lambda);
        for (name, weight) in model.regularisers() {
            out.push(Box::new(Provided::new(&name, weight)));
        }
        out
    }

    /// The objective of a run: [`Objective::for_model`] plus, in name order, one term
    /// per entry of a config's `terms` (`name -> weight`) that `registry` knows. A
    /// name it does not know is left out and listed by [`Objective::unregistered`]:
    /// such an objective can stand beside a model loaded for rendering, and every
    /// training entry point refuses it. Errors (one line) when a name is already a
    /// term of the objective (a model's own regulariser) or the registered maker
    /// returns a term with another name or weight.
    pub fn for_run(
        lambda: f64,
        model: &dyn Representation<T>,
        terms: &BTreeMap<String, f64>,
        registry: &TermRegistry<T>,
    ) -> Result<Self, Error> {
        let mut out = Self::for_model(lambda, model);
        for (name, &weight) in terms {
            if out.terms.iter().any(|t| t.name() == name) {
                return Err(Error::Input(format!(
                    "config: terms: `{name}` is already a term of the {} objective (its own regulariser, weighted in its model settings)",
                    model.name()
                )));
            }
            match registry.make(name, weight) {
                Some(term) if term.name() == name && term.weight() == weight => out.push(term),
                Some(term) => {
                    return Err(Error::Input(format!(
                        "config: terms: `{name}`: its registered maker returned a term named `{}` with weight {} (it must keep the name it is registered under and the weight {weight} it is given)",
                        term.name(),
                        term.weight()
                    )));
                }
                None => out.unregistered.push(name.clone()),
            }
        }
        Ok(out)
    }

    /// Names a config gave this objective that no registry knew (module docs of
    /// [`TermRegistry`]); empty for any objective that can train.
    pub fn unregistered(&self) -> &[String] {
        &self.unregistered
    }

    /// Adds a term written as a closure over the context (about as short as a term
    /// gets): `obj.with_fn("opacity_l1", 1e-3, |ctx| ctx.gaussians().opacity.mean())`.
    pub fn with_fn<F>(self, name: &str, weight: f64, f: F) -> Self
    where
        F: for<'a, 't> Fn(&'a TermCtx<'t, T>) -> Var<'t, T> + Send + Sync + 'static,
    {
        self.with(FnTerm::new(name, weight, f))
    }

    /// [`Objective::with_fn`] on an existing objective (e.g. `trainer.objective`).
    pub fn push_fn<F>(&mut self, name: &str, weight: f64, f: F)
    where
        F: for<'a, 't> Fn(&'a TermCtx<'t, T>) -> Var<'t, T> + Send + Sync + 'static,
    {
        self.push(Box::new(FnTerm::new(name, weight, f)));
    }

    /// Adds a term; panics if its name is already used (log columns must be unique).
    pub fn with(mut self, term: impl Term<T> + 'static) -> Self {
        self.push(Box::new(term));
        self
    }

    /// Adds a boxed term; panics if its name is already used.
    pub fn push(&mut self, term: Box<dyn Term<T>>) {
        assert!(
            self.terms.iter().all(|t| t.name() != term.name()),
            "Objective: a term named `{}` is already present",
            term.name()
        );
        self.terms.push(term);
    }

    /// Term names in order (the loss columns of `log.csv`).
    pub fn names(&self) -> Vec<String> {
        self.terms.iter().map(|t| t.name().to_string()).collect()
    }

    /// The terms.
    pub fn terms(&self) -> &[Box<dyn Term<T>>] {
        &self.terms
    }

    /// Evaluates every term on `ctx` and sums `w_k term_k` on the tape. Every term is
    /// evaluated and logged, including zero-weight ones (which add nothing to the total).
    /// Panics, naming the term, if a term's value has more than one element.
    pub fn evaluate<'t>(&self, ctx: &TermCtx<'t, T>) -> Evaluated<'t, T> {
        let mut total: Option<Var<'t, T>> = None;
        let mut terms = Vec::with_capacity(self.terms.len());
        for term in &self.terms {
            let v = term.value(ctx);
            let n = v.value().len();
            assert_eq!(
                n,
                1,
                "Objective: term `{}` returned {n} values, expected one",
                term.name()
            );
            let v = if v.shape().is_empty() {
                v
            } else {
                v.reshape(&[])
            };
            terms.push(TermValue {
                name: term.name().to_string(),
                weight: term.weight(),
                value: Float::to_f64(v.value().item()),
            });
            if term.weight() != 0.0 {
                let weighted = v.scale(term.weight());
                total = Some(match total {
                    Some(acc) => acc + weighted,
                    None => weighted,
                });
            }
        }
        Evaluated {
            total: total.unwrap_or_else(|| ctx.zero()),
            terms,
        }
    }
}
