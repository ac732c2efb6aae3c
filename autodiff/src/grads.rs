//! The gradients a reverse sweep of a [`crate::Tape`] returns.

use std::collections::HashMap;

use crate::{Float, Tensor, Var};

/// Gradients from one reverse sweep, keyed by node and by parameter name.
#[derive(Debug)]
pub struct Grads<T: Float> {
    pub(crate) by_node: Vec<Option<Tensor<T>>>,
    pub(crate) params: HashMap<String, usize>,
}

impl<T: Float> Grads<T> {
    /// dL/d`var`, or `None` when no path leads from `var` to the loss or `var` is constant.
    pub fn wrt(&self, var: Var<'_, T>) -> Option<&Tensor<T>> {
        self.by_node.get(var.id()).and_then(Option::as_ref)
    }

    /// dL/d(parameter `name`), or `None` when the loss does not depend on it.
    pub fn param(&self, name: &str) -> Option<&Tensor<T>> {
        self.params
            .get(name)
            .and_then(|&id| self.by_node[id].as_ref())
    }

    /// Names of the parameters registered on the tape, sorted.
    pub fn param_names(&self) -> Vec<&str> {
        let mut names: Vec<&str> = self.params.keys().map(String::as_str).collect();
        names.sort_unstable();
        names
    }
}
