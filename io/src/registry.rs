//! Plug-ins by name: the one registry behind every extension point (representations,
//! loss terms, filters, strategies, data formats, metrics). Every kind refuses a
//! malformed name ([`is_plugin_name`]) and a name already taken with the same kind of
//! error, and answers an unknown name with the registered ones and the closest
//! ([`unknown_name`]). What a plug-in is (a factory, a loader, a layout) is the
//! type parameter; what a kind adds (names it reserves, how it builds) lives in the
//! registry that wraps this one.

use std::sync::Arc;

use crate::name::{is_plugin_name, unknown_name};

/// Plug-ins of one kind, in registration order. Cloning shares the plug-ins.
pub struct Registry<P: ?Sized> {
    /// What a plug-in of this kind is called in messages (`filter`, `strategy`, ...).
    kind: &'static str,
    /// How a program registers one (`maaf::cli::Maaf::filter`), for messages.
    api: &'static str,
    entries: Vec<(String, Arc<P>)>,
}

impl<P: ?Sized> Clone for Registry<P> {
    fn clone(&self) -> Self {
        Registry {
            kind: self.kind,
            api: self.api,
            entries: self.entries.clone(),
        }
    }
}

impl<P: ?Sized> std::fmt::Debug for Registry<P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("kind", &self.kind)
            .field("names", &self.names())
            .finish()
    }
}

impl<P: ?Sized> Registry<P> {
    /// An empty registry of plug-ins called `kind` in messages, registered through
    /// `api`.
    pub fn new(kind: &'static str, api: &'static str) -> Self {
        Registry {
            kind,
            api,
            entries: Vec::new(),
        }
    }

    /// Adds `plugin` under `name`. Refuses a name that is not 1 to 64 letters, digits
    /// or `_`, and a name already registered (naming the registered ones).
    pub fn register(&mut self, name: &str, plugin: Arc<P>) -> Result<(), String> {
        if !is_plugin_name(name) {
            return Err(format!(
                "`{name}` is not a {} name (1 to 64 letters, digits or _)",
                self.kind
            ));
        }
        if self.contains(name) {
            return Err(format!(
                "{} `{name}` is already registered (registered: {})",
                self.kind,
                self.names().join(", ")
            ));
        }
        self.entries.push((name.to_string(), plugin));
        Ok(())
    }

    /// The plug-in registered as `name`, or the line naming the registered ones and
    /// the closest ([`unknown_name`]).
    pub fn get(&self, name: &str) -> Result<&Arc<P>, String> {
        self.entries
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, p)| p)
            .ok_or_else(|| unknown_name(self.kind, name, &self.names(), self.api))
    }

    /// Whether a plug-in is registered as `name`.
    pub fn contains(&self, name: &str) -> bool {
        self.entries.iter().any(|(n, _)| n == name)
    }

    /// The registered names, in registration order.
    pub fn names(&self) -> Vec<&str> {
        self.entries.iter().map(|(n, _)| n.as_str()).collect()
    }

    /// Whether nothing is registered.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// `(name, plug-in)` in registration order.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &Arc<P>)> {
        self.entries.iter().map(|(n, p)| (n.as_str(), p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Maker = dyn Fn() -> u32 + Send + Sync;

    fn registry() -> Registry<Maker> {
        let mut r: Registry<Maker> = Registry::new("widget", "Maaf::widget");
        r.register("small", Arc::new(|| 1)).expect("new name");
        r.register("large", Arc::new(|| 2)).expect("new name");
        r
    }

    #[test]
    fn a_registered_name_is_found_in_registration_order() {
        let r = registry();
        assert_eq!(r.names(), ["small", "large"]);
        assert_eq!(r.get("large").map(|m| m()), Ok(2));
        assert!(r.contains("small") && !r.contains("medium"));
        assert_eq!(r.clone().names(), r.names());
    }

    #[test]
    fn a_taken_or_malformed_name_is_refused_and_an_unknown_one_gets_a_suggestion() {
        let mut r = registry();
        let taken = r.register("small", Arc::new(|| 3)).expect_err("taken");
        assert_eq!(
            taken,
            "widget `small` is already registered (registered: small, large)"
        );
        assert_eq!(r.get("small").map(|m| m()), Ok(1), "the first one stays");
        let bad = r
            .register("no name", Arc::new(|| 3))
            .expect_err("malformed");
        assert!(bad.contains("`no name` is not a widget name"), "{bad}");
        let unknown = r.get("smal").err().expect("unknown");
        assert!(unknown.contains("did you mean `small`?"), "{unknown}");
        let far = r.get("zzz").err().expect("unknown");
        assert!(far.contains("registered: small, large") && far.contains("Maaf::widget"));
    }
}
