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

#[cfg(test)]
mod tests {
    use super::is_plugin_name;

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
