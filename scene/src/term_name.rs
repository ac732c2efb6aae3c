//! Which names a loss term may have: a config's `terms` keys are checked with it
//! ([`crate::TrainConfig::validate`]), before the trainer's term registry looks them up.

/// Names a config may not give a term: the photometric terms and the other columns
/// of `log.csv`.
pub const RESERVED: [&str; 8] = [
    "l1",
    "dssim",
    "iteration",
    "total",
    "num_gaussians",
    "elapsed_seconds",
    "skipped_steps",
    "val_psnr",
];

/// Why `name` cannot name a term, if it cannot: it must be 1 to 64 ASCII letters,
/// digits or `_` (it becomes a `log.csv` column) and not one of [`RESERVED`].
pub fn name_problem(name: &str) -> Option<String> {
    if !maaf_io::is_plugin_name(name) {
        Some(format!(
            "`{name}` is not a term name (1 to 64 letters, digits or _)"
        ))
    } else if RESERVED.contains(&name) {
        Some(format!(
            "`{name}` is reserved (the photometric loss or a log.csv column)"
        ))
    } else {
        None
    }
}
