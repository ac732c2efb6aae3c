//! Loss terms by name: what a config's `terms` section (`{"NAME": weight}`,
//! docs/config.md) can name. The built-in regularisers are always registered
//! ([`TermRegistry::builtin`]); a program adds its own
//! ([`TermRegistry::register_fn`], or `maaf::cli::Maaf::term` for the whole command
//! line), and every run it trains or resumes may then name them.

use std::collections::BTreeMap;
use std::sync::Arc;

use maaf_io::Registry;

use maaf_autodiff::{Float, Var};

use super::builtin::{self, DepthTv, OpacityEntropy, ScaleAnisotropy};
use super::{FnTerm, Term, TermCtx, name_problem};

/// Makes the term registered under a name, given the weight the config gives it.
pub type TermMaker<T> = dyn Fn(f64) -> Box<dyn Term<T>> + Send + Sync;

/// Term makers by name (module docs, [`maaf_io::Registry`]). Cloning shares the
/// makers.
pub struct TermRegistry<T: Float> {
    makers: Registry<TermMaker<T>>,
}

impl<T: Float> Clone for TermRegistry<T> {
    fn clone(&self) -> Self {
        TermRegistry {
            makers: self.makers.clone(),
        }
    }
}

impl<T: Float> TermRegistry<T> {
    /// The built-in regularisers ([`super::builtin`]): `depth_tv`,
    /// `opacity_entropy`, `scale_anisotropy`.
    pub fn builtin() -> Self {
        let mut r = TermRegistry {
            makers: Registry::new("term", "maaf::cli::Maaf::term"),
        };
        // Three distinct term names: registering cannot fail.
        let _ = r.register(builtin::depth_tv::NAME, |weight| {
            Box::new(DepthTv { weight })
        });
        let _ = r.register(builtin::opacity_entropy::NAME, |weight| {
            Box::new(OpacityEntropy { weight })
        });
        let _ = r.register(builtin::scale_anisotropy::NAME, |weight| {
            Box::new(ScaleAnisotropy { weight })
        });
        r
    }

    /// Registers `maker` under `name`: a config entry `"name": w` adds `maker(w)`,
    /// which must be named `name` and weigh `w` (the objective refuses it otherwise).
    /// Refuses a name that is taken, malformed or reserved for the photometric loss
    /// and the log's columns ([`name_problem`]).
    pub fn register<F>(&mut self, name: &str, maker: F) -> Result<(), String>
    where
        F: Fn(f64) -> Box<dyn Term<T>> + Send + Sync + 'static,
    {
        if let Some(problem) = name_problem(name) {
            return Err(problem);
        }
        self.makers.register(name, Arc::new(maker))
    }

    /// Registers a term written as a function of the context (the shortest form):
    /// `registry.register_fn("alpha_l1", |ctx| ctx.alpha().mean())`; a config gives
    /// its weight. Refuses a name as [`TermRegistry::register`].
    pub fn register_fn<F>(&mut self, name: &str, f: F) -> Result<(), String>
    where
        F: for<'a, 't> Fn(&'a TermCtx<'t, T>) -> Var<'t, T> + Send + Sync + 'static,
    {
        let f = Arc::new(f);
        let owned = name.to_string();
        self.register(name, move |weight| {
            let f = Arc::clone(&f);
            Box::new(FnTerm::new(&owned, weight, move |ctx: &TermCtx<'_, T>| {
                f(ctx)
            }))
        })
    }

    /// The registered names, in registration order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.makers.names().into_iter()
    }

    /// The term `name` with `weight`, if `name` is registered.
    pub fn make(&self, name: &str, weight: f64) -> Option<Box<dyn Term<T>>> {
        self.makers.get(name).ok().map(|maker| maker(weight))
    }

    /// The names in `terms` (a config's `terms`) that are not registered, sorted.
    pub fn missing<'a>(&self, terms: &'a BTreeMap<String, f64>) -> Vec<&'a str> {
        terms
            .keys()
            .filter(|n| !self.makers.contains(n))
            .map(String::as_str)
            .collect()
    }

    /// `Err` with one line naming every term of `terms` that is not registered and
    /// the registered ones, prefixed by `what` (the config or run at fault).
    pub fn check(&self, terms: &BTreeMap<String, f64>, what: &str) -> Result<(), crate::Error> {
        let missing = self.missing(terms);
        if missing.is_empty() {
            return Ok(());
        }
        let quoted = |names: Vec<&str>| {
            names
                .iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let (noun, verb, pronoun) = if missing.len() == 1 {
            ("term", "is", "it")
        } else {
            ("terms", "are", "them")
        };
        Err(crate::Error::Input(format!(
            "{what}: the {noun} {} {verb} not registered in this program (it knows {}); use a program that registers {pronoun} (maaf::cli::Maaf::term)",
            quoted(missing),
            quoted(self.names().collect()),
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::{Tape, Tensor};

    fn terms(entries: &[(&str, f64)]) -> BTreeMap<String, f64> {
        entries.iter().map(|&(n, w)| (n.to_string(), w)).collect()
    }

    #[test]
    fn a_registered_function_is_made_with_the_config_weight_and_evaluates() {
        let mut r = TermRegistry::<f64>::builtin();
        r.register_fn("render_mean", |ctx| ctx.render.mean())
            .expect("a new name");
        assert_eq!(
            r.names().collect::<Vec<_>>(),
            [
                "depth_tv",
                "opacity_entropy",
                "scale_anisotropy",
                "render_mean"
            ]
        );
        let term = r.make("render_mean", 0.25).expect("registered");
        assert_eq!((term.name(), term.weight()), ("render_mean", 0.25));
        let tape = Tape::new();
        let render = tape.var(Tensor::from_vec(vec![0.5, 1.5, 1.0], &[1, 1, 3]));
        let ctx = TermCtx::new(render, &Tensor::zeros(&[1, 1, 3]));
        assert_eq!(term.value(&ctx).value().item(), 1.0);
        assert!(r.make("absent", 1.0).is_none());
    }

    #[test]
    fn missing_terms_are_named_in_one_line_with_the_known_ones() {
        let r = TermRegistry::<f32>::builtin();
        let wanted = terms(&[("opacity_entropy", 0.1), ("smooth", 1.0), ("zeta", 2.0)]);
        assert_eq!(r.missing(&wanted), ["smooth", "zeta"]);
        let msg = r
            .check(&wanted, "RUN/config.json")
            .expect_err("missing")
            .to_string();
        assert!(
            msg.starts_with("RUN/config.json: the terms `smooth`, `zeta` are not registered"),
            "{msg}"
        );
        assert!(
            msg.contains("`depth_tv`, `opacity_entropy`, `scale_anisotropy`"),
            "{msg}"
        );
        assert!(!msg.contains('\n'));
        r.check(&terms(&[("depth_tv", 1.0)]), "x")
            .expect("built in");
    }

    #[test]
    fn a_taken_or_reserved_name_is_refused() {
        let mut r = TermRegistry::<f32>::builtin();
        let taken = r.register_fn("depth_tv", |ctx| ctx.render.mean());
        assert!(taken.expect_err("taken").contains("already registered"));
        let reserved = r.register_fn("l1", |ctx| ctx.render.mean());
        assert!(reserved.expect_err("reserved").contains("reserved"));
    }
}
