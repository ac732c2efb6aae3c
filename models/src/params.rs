//! One store of named parameters for any representation (docs/architecture.md).
//!
//! A representation declares each trainable tensor once with [`ParamStore::add`]: its
//! name, its values, whether it has one row per Gaussian, its learning-rate schedule
//! and its L2 weight decay. Everything else comes from the store:
//!
//! - binding on a tape ([`ParamStore::bind`]: every tensor registered by name, so
//!   `Grads::param(name)` finds its gradient), or from any list of `Var`s in store
//!   order ([`BoundParams::from_vars`], what a gradient check passes);
//! - densification resizing ([`ParamStore::select_rows`] applies one row-index list to
//!   every per-Gaussian tensor; shared tensors are untouched) and the writes to the
//!   canonical 3DGS tensors (`canonical.rs`: [`ParamStore::canonical`],
//!   [`ParamStore::set_canonical_rows`], [`ParamStore::cap_opacity`]);
//! - the optimiser ([`ParamStore::iter_mut`] yields every [`Param`] with its schedule);
//! - checkpoints ([`ParamStore::named_tensors`] and [`ParamStore::load`]).

use maaf_autodiff::nn::{LinearVars, Mlp, MlpVars};
use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, PerGaussian, Tape, Tensor, Var};

/// Index of a parameter in its [`ParamStore`] (stable: parameters are never removed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ParamId(usize);

/// Whether a parameter has one row per Gaussian (resized by densification) or is
/// shared by all Gaussians (MLP weights, field planes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rows {
    /// Row `i` belongs to Gaussian `i`.
    PerGaussian,
    /// Shared by every Gaussian.
    Shared,
}

/// One trainable tensor and how it is optimised.
#[derive(Clone, Debug, PartialEq)]
pub struct Param<T: Float> {
    /// Name on the tape, in the optimiser and in checkpoints (`param/{name}`).
    pub name: String,
    /// The values.
    pub value: Tensor<T>,
    /// Per-Gaussian or shared.
    pub rows: Rows,
    /// Learning-rate schedule (already scaled by the scene extent where it applies).
    pub lr: LrSchedule,
    /// L2 weight decay added to the gradient before Adam (`g + wd p`, PyTorch
    /// `Adam(weight_decay=wd)`), 0 for none.
    pub weight_decay: f64,
}

/// The named parameters of one representation, in declaration order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamStore<T: Float> {
    params: Vec<Param<T>>,
}

/// Every parameter of a store as a `Var` on one tape, looked up by [`ParamId`].
pub struct BoundParams<'t, T: Float> {
    vars: Vec<Var<'t, T>>,
}

impl<'t, T: Float> BoundParams<'t, T> {
    /// Binds from `vars` given in store order (e.g. the inputs of a gradient check).
    /// Panics if the count differs from the store's.
    pub fn from_vars(store: &ParamStore<T>, vars: &[Var<'t, T>]) -> Self {
        assert_eq!(
            vars.len(),
            store.len(),
            "BoundParams: {} vars for a store of {} parameters",
            vars.len(),
            store.len()
        );
        BoundParams {
            vars: vars.to_vec(),
        }
    }

    /// The handle of parameter `id`.
    pub fn get(&self, id: ParamId) -> Var<'t, T> {
        self.vars[id.0]
    }
}

impl<T: Float> ParamStore<T> {
    /// An empty store.
    pub fn new() -> Self {
        ParamStore { params: Vec::new() }
    }

    /// Declares a parameter; panics on a repeated name or, for a per-Gaussian
    /// parameter, a row count that differs from the others'.
    pub fn add(
        &mut self,
        name: &str,
        value: Tensor<T>,
        rows: Rows,
        lr: LrSchedule,
        weight_decay: f64,
    ) -> ParamId {
        assert!(
            self.id(name).is_none(),
            "ParamStore: parameter `{name}` declared twice"
        );
        if rows == Rows::PerGaussian
            && let Some(n) = self.gaussians()
        {
            assert_eq!(
                value.rows(),
                n,
                "ParamStore: `{name}` has {} rows, other per-Gaussian parameters {n}",
                value.rows()
            );
        }
        self.params.push(Param {
            name: name.to_string(),
            value,
            rows,
            lr,
            weight_decay,
        });
        ParamId(self.params.len() - 1)
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// True when nothing is declared.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// The id of the parameter called `name`.
    pub fn id(&self, name: &str) -> Option<ParamId> {
        self.params.iter().position(|p| p.name == name).map(ParamId)
    }

    /// Parameter `id`.
    pub fn param(&self, id: ParamId) -> &Param<T> {
        &self.params[id.0]
    }

    /// The values of parameter `id`.
    pub fn value(&self, id: ParamId) -> &Tensor<T> {
        &self.params[id.0].value
    }

    /// The values of parameter `id`, mutably.
    pub fn value_mut(&mut self, id: ParamId) -> &mut Tensor<T> {
        &mut self.params[id.0].value
    }

    /// Every parameter, in declaration order.
    pub fn iter(&self) -> impl Iterator<Item = &Param<T>> {
        self.params.iter()
    }

    /// Every parameter, mutably (the optimiser's view).
    pub fn iter_mut(&mut self) -> impl Iterator<Item = &mut Param<T>> {
        self.params.iter_mut()
    }

    /// Names in declaration order.
    pub fn names(&self) -> Vec<String> {
        self.params.iter().map(|p| p.name.clone()).collect()
    }

    /// Copies of every value in declaration order (the inputs of a gradient check).
    pub fn tensors(&self) -> Vec<Tensor<T>> {
        self.params.iter().map(|p| p.value.clone()).collect()
    }

    /// Number of Gaussians: the row count of the per-Gaussian parameters (`None` if
    /// the store has none).
    pub fn gaussians(&self) -> Option<usize> {
        self.params
            .iter()
            .find(|p| p.rows == Rows::PerGaussian)
            .map(|p| p.value.rows())
    }

    /// Number of stored scalars.
    pub fn num_scalars(&self) -> usize {
        self.params.iter().map(|p| p.value.len()).sum()
    }

    /// Registers every parameter on `tape` under its name (`tape.param`).
    pub fn bind<'t>(&self, tape: &'t Tape<T>) -> BoundParams<'t, T> {
        BoundParams {
            vars: self
                .params
                .iter()
                .map(|p| tape.param(&p.name, p.value.clone()))
                .collect(),
        }
    }

    /// Every parameter as a constant on `tape` (evaluation outside training: no
    /// gradient is recorded).
    pub fn bind_constants<'t>(&self, tape: &'t Tape<T>) -> BoundParams<'t, T> {
        BoundParams {
            vars: self
                .params
                .iter()
                .map(|p| tape.constant(p.value.clone()))
                .collect(),
        }
    }

    /// Names of the per-Gaussian parameters (whose optimiser moments densification
    /// resizes with them).
    pub fn per_gaussian_names(&self) -> Vec<String> {
        self.params
            .iter()
            .filter(|p| p.rows == Rows::PerGaussian)
            .map(|p| p.name.clone())
            .collect()
    }

    /// `(name, value)` of every parameter, for a checkpoint.
    pub fn named_tensors(&self) -> impl Iterator<Item = (&str, &Tensor<T>)> {
        self.params.iter().map(|p| (p.name.as_str(), &p.value))
    }

    /// Replaces every value by the one `lookup(name)` returns (a checkpoint's).
    /// Shared parameters must keep their shape; per-Gaussian ones keep their row
    /// width and may change their row count, which must then agree among them.
    /// Errors name the parameter; nothing is changed on error.
    pub fn load(
        &mut self,
        mut lookup: impl FnMut(&str) -> Result<Tensor<T>, String>,
    ) -> Result<(), String> {
        let mut loaded = Vec::with_capacity(self.params.len());
        let mut rows: Option<(usize, String)> = None;
        for p in &self.params {
            let t = lookup(&p.name)?;
            let same = match p.rows {
                Rows::Shared => t.shape() == p.value.shape(),
                Rows::PerGaussian => {
                    t.shape().len() == p.value.shape().len()
                        && t.shape().get(1..) == p.value.shape().get(1..)
                }
            };
            if !same {
                return Err(format!(
                    "parameter `{}` has shape {:?}, the model expects {:?}{}",
                    p.name,
                    t.shape(),
                    p.value.shape(),
                    if p.rows == Rows::PerGaussian {
                        " (any row count)"
                    } else {
                        ""
                    }
                ));
            }
            if p.rows == Rows::PerGaussian {
                match &rows {
                    Some((n, first)) if *n != t.rows() => {
                        return Err(format!(
                            "parameter `{}` has {} rows but `{first}` has {n}",
                            p.name,
                            t.rows()
                        ));
                    }
                    Some(_) => {}
                    None => rows = Some((t.rows(), p.name.clone())),
                }
            }
            loaded.push(t);
        }
        for (p, t) in self.params.iter_mut().zip(loaded) {
            p.value = t;
        }
        Ok(())
    }
}

/// An [`Mlp`] whose weights live in a store: layer `i` is `{name}.{i}.weight` and
/// `{name}.{i}.bias` (the names [`Mlp::bind`] uses), all shared parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct MlpParams {
    layers: Vec<(ParamId, ParamId)>,
}

impl MlpParams {
    /// Moves `mlp`'s weights into `store` under `name`, every layer with schedule `lr`
    /// and weight decay `weight_decay`.
    pub fn add<T: Float>(
        store: &mut ParamStore<T>,
        name: &str,
        mlp: Mlp<T>,
        lr: &LrSchedule,
        weight_decay: f64,
    ) -> Self {
        let layers = mlp
            .layers
            .into_iter()
            .enumerate()
            .map(|(i, l)| {
                let w = store.add(
                    &format!("{name}.{i}.weight"),
                    l.weight,
                    Rows::Shared,
                    lr.clone(),
                    weight_decay,
                );
                let b = store.add(
                    &format!("{name}.{i}.bias"),
                    l.bias,
                    Rows::Shared,
                    lr.clone(),
                    weight_decay,
                );
                (w, b)
            })
            .collect();
        MlpParams { layers }
    }

    /// The network bound on the tape of `params`.
    pub fn bind<'t, T: Float>(&self, params: &BoundParams<'t, T>) -> MlpVars<'t, T> {
        MlpVars {
            layers: self
                .layers
                .iter()
                .map(|&(w, b)| LinearVars {
                    weight: params.get(w),
                    bias: params.get(b),
                })
                .collect(),
        }
    }

    /// The network with its current weights as constants on `tape` (evaluation
    /// outside training; binds only this network, not the whole store).
    pub fn bind_constants<'t, T: Float>(
        &self,
        store: &ParamStore<T>,
        tape: &'t Tape<T>,
    ) -> MlpVars<'t, T> {
        MlpVars {
            layers: self
                .layers
                .iter()
                .map(|&(w, b)| LinearVars {
                    weight: tape.constant(store.value(w).clone()),
                    bias: tape.constant(store.value(b).clone()),
                })
                .collect(),
        }
    }

    /// Number of scalar weights in `store`.
    pub fn num_params<T: Float>(&self, store: &ParamStore<T>) -> usize {
        self.layers
            .iter()
            .map(|&(w, b)| store.value(w).len() + store.value(b).len())
            .sum()
    }

    /// The ids of the last layer's weight and bias (a residual head: tests and
    /// initialisations overwrite it).
    pub fn last_layer(&self) -> (ParamId, ParamId) {
        self.layers[self.layers.len() - 1]
    }
}

impl<T: Float> PerGaussian for ParamStore<T> {
    fn rows(&self) -> usize {
        self.gaussians().unwrap_or(0)
    }

    /// Applies the densification index list to every per-Gaussian parameter.
    fn select_rows(&mut self, index: &[usize]) {
        for p in &mut self.params {
            if p.rows == Rows::PerGaussian {
                p.value.select_rows(index);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store() -> (ParamStore<f64>, ParamId, ParamId) {
        let mut s = ParamStore::new();
        let a = s.add(
            "a",
            Tensor::from_vec(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0], &[3, 2]),
            Rows::PerGaussian,
            LrSchedule::Constant(0.1),
            0.0,
        );
        let w = s.add(
            "w",
            Tensor::from_vec(vec![7.0, 8.0], &[2]),
            Rows::Shared,
            LrSchedule::Constant(0.2),
            1e-3,
        );
        (s, a, w)
    }

    #[test]
    fn select_rows_resizes_only_per_gaussian_parameters() {
        let (mut s, a, w) = store();
        s.select_rows(&[2, 0, 0]);
        assert_eq!(s.value(a).data(), &[5.0, 6.0, 1.0, 2.0, 1.0, 2.0]);
        assert_eq!(s.value(w).data(), &[7.0, 8.0]);
        assert_eq!(s.gaussians(), Some(3));
        assert_eq!(s.num_scalars(), 8);
    }

    #[test]
    fn bind_registers_by_name_and_from_vars_follows_store_order() {
        let (s, a, w) = store();
        let tape = Tape::new();
        let b = s.bind(&tape);
        let loss = b.get(a).sum() + b.get(w).square().sum();
        let grads = tape.backward(loss).expect("finite");
        assert_eq!(grads.param("w").expect("w").data(), &[14.0, 16.0]);
        assert_eq!(grads.param("a").expect("a").len(), 6);
        let tape = Tape::new();
        let vars: Vec<_> = s.tensors().into_iter().map(|t| tape.var(t)).collect();
        let b = BoundParams::from_vars(&s, &vars);
        assert_eq!(b.get(w).value().data(), &[7.0, 8.0]);
    }

    #[test]
    fn load_accepts_a_new_row_count_and_names_a_bad_shape() {
        let (mut s, a, _) = store();
        let before = s.clone();
        let bad = s.load(|name| {
            Ok(match name {
                "a" => Tensor::zeros(&[5, 2]),
                _ => Tensor::zeros(&[3]),
            })
        });
        let msg = bad.expect_err("shared shape differs");
        assert!(msg.contains("`w`") && msg.contains("[3]"), "{msg}");
        assert_eq!(s, before, "nothing changed on error");
        s.load(|name| {
            Ok(match name {
                "a" => Tensor::zeros(&[5, 2]),
                _ => Tensor::zeros(&[2]),
            })
        })
        .expect("loads");
        assert_eq!(s.value(a).shape(), &[5, 2]);
        let missing = s.load(|name| Err(format!("no `{name}`")));
        assert_eq!(missing.expect_err("missing"), "no `a`");
    }

    #[test]
    #[should_panic(expected = "declared twice")]
    fn a_repeated_name_is_refused() {
        let (mut s, _, _) = store();
        s.add(
            "w",
            Tensor::zeros(&[1]),
            Rows::Shared,
            LrSchedule::Constant(0.0),
            0.0,
        );
    }
}
