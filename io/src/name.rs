//! The names a program registers its own loss terms, representations, filters and
//! densification strategies under: configs, checkpoints and `log.csv` columns carry
//! them, so every registry accepts the same spelling.

/// Whether `name` can name a registered term, representation, filter or strategy:
/// 1 to 64 ASCII letters, digits or `_` (safe as a JSON key, a file name and a CSV
/// column).
pub fn is_plugin_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The one line for a `name` that no registry of `kind` (`filter`, `representation
/// (model.kind)`, ...) holds: the closest registered name when one is close, as clap
/// suggests (`filter `mip` is not registered: did you mean `mip3d`?`), else how a
/// program registers its own (`api`, e.g. `maaf::cli::Maaf::filter`); the registered
/// names either way.
pub fn unknown_name(kind: &str, name: &str, registered: &[&str], api: &str) -> String {
    let list = registered.join(", ");
    let closest = registered
        .iter()
        .map(|r| (strsim::jaro(name, r), *r))
        .filter(|(score, _)| *score > 0.7)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match closest {
        Some((_, r)) => {
            format!("{kind} `{name}` is not registered: did you mean `{r}`? (registered: {list})")
        }
        None => format!(
            "{kind} `{name}` is not registered in this program (registered: {list}); a program of one's own registers others ({api}, docs/extending.md)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::{is_plugin_name, unknown_name};

    #[test]
    fn a_close_name_is_suggested_and_a_far_one_gets_the_registered_list() {
        let names = ["none", "mip3d", "motion", "window_max"];
        let msg = unknown_name("filter", "mip", &names, "Maaf::filter");
        assert!(msg.contains("did you mean `mip3d`?"), "{msg}");
        let msg = unknown_name("filter", "windowmax", &names, "Maaf::filter");
        assert!(msg.contains("did you mean `window_max`?"), "{msg}");
        let msg = unknown_name("filter", "gaussian_blur", &names, "Maaf::filter");
        assert!(!msg.contains("did you mean"), "{msg}");
        assert!(
            msg.contains("none, mip3d, motion, window_max") && msg.contains("Maaf::filter"),
            "{msg}"
        );
    }

    #[test]
    fn letters_digits_and_underscores_up_to_64() {
        for good in ["median", "tiny_deform", "l2", "_", &"a".repeat(64)] {
            assert!(is_plugin_name(good), "{good}");
        }
        for bad in ["", "a b", "a-b", "médian", "a.b", &"a".repeat(65)] {
            assert!(!is_plugin_name(bad), "{bad}");
        }
    }
}
