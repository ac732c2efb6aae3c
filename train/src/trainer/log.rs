//! The columns of `log.csv`: `iteration`, each objective term's unweighted value by
//! name, then each term's weighted value under `<weight>*<name>` (what it added to the
//! total, its weight in the header), then `total`, `num_gaussians`,
//! `elapsed_seconds`, `skipped_steps` and `val_psnr`.
//!
//! Runs logged before the weighted columns existed have the same header without them;
//! a resume of such a run keeps appending in that layout ([`LogLayout::unweighted`]).
//! The file is written and read with the `csv` crate.

use crate::loss::Objective;

/// Which columns a `log.csv` has (module docs).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct LogLayout {
    /// `(name, weight)` of every term, in objective order.
    terms: Vec<(String, f64)>,
    /// Whether the weighted-value columns are written.
    weighted: bool,
}

/// What one row reports besides the term values.
pub(super) struct RowStats<'a> {
    /// The iteration of the row.
    pub iteration: usize,
    /// The step's total loss.
    pub total: f64,
    /// Gaussians after the step.
    pub num_gaussians: usize,
    /// Training seconds so far (validation excluded).
    pub elapsed: f64,
    /// Steps skipped so far.
    pub skipped: usize,
    /// The validation PSNR, formatted, or empty.
    pub val: &'a str,
}

impl LogLayout {
    /// The current layout for `objective` (weighted columns included).
    pub(super) fn of<T: maaf_autodiff::Float>(objective: &Objective<T>) -> Self {
        LogLayout {
            terms: objective
                .terms()
                .iter()
                .map(|t| (t.name().to_string(), t.weight()))
                .collect(),
            weighted: true,
        }
    }

    /// The layout of logs written before the weighted columns (same terms).
    pub(super) fn unweighted(&self) -> Self {
        LogLayout {
            terms: self.terms.clone(),
            weighted: false,
        }
    }

    /// The header's fields.
    pub(super) fn header(&self) -> Vec<String> {
        let mut header = vec!["iteration".to_string()];
        header.extend(self.terms.iter().map(|(name, _)| name.clone()));
        if self.weighted {
            header.extend(
                self.terms
                    .iter()
                    .map(|(name, weight)| format!("{}*{name}", weight_text(*weight))),
            );
        }
        header.extend(
            [
                "total",
                "num_gaussians",
                "elapsed_seconds",
                "skipped_steps",
                "val_psnr",
            ]
            .map(String::from),
        );
        header
    }

    /// One row's fields from the step's unweighted term values by name (`NaN` for a
    /// term the step did not report).
    pub(super) fn row(&self, values: &[(String, f64)], stats: &RowStats<'_>) -> Vec<String> {
        let value = |name: &str| {
            values
                .iter()
                .find(|(n, _)| n == name)
                .map_or(f64::NAN, |(_, v)| *v)
        };
        let mut row = vec![stats.iteration.to_string()];
        row.extend(
            self.terms
                .iter()
                .map(|(name, _)| format!("{:.6e}", value(name))),
        );
        if self.weighted {
            row.extend(
                self.terms
                    .iter()
                    .map(|(name, weight)| format!("{:.6e}", weight * value(name))),
            );
        }
        row.extend([
            format!("{:.6e}", stats.total),
            stats.num_gaussians.to_string(),
            format!("{:.3}", stats.elapsed),
            stats.skipped.to_string(),
            stats.val.to_string(),
        ]);
        row
    }
}

/// `fields` as one line of CSV (quoted where a field needs it), as `log.csv` holds it.
pub(super) fn csv_line(fields: &[String]) -> Result<Vec<u8>, crate::Error> {
    let mut line = csv::Writer::from_writer(Vec::new());
    line.write_record(fields)
        .map_err(|e| crate::Error::Input(format!("log.csv: {e}")))?;
    line.into_inner()
        .map_err(|e| crate::Error::Input(format!("log.csv: {e}")))
}

/// A weight as the header spells it: the shortest decimal (`0.8`), or scientific
/// below 1e-3 (`8e-6`) so small regulariser weights stay readable.
fn weight_text(w: f64) -> String {
    if w != 0.0 && w.abs() < 1e-3 {
        format!("{w:e}")
    } else {
        format!("{w}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_columns_carry_the_weight_and_the_contribution() {
        let objective = Objective::<f64>::photometric(0.2).with_fn("reg", 8e-6, |ctx| ctx.zero());
        let layout = LogLayout::of(&objective);
        assert_eq!(
            layout.header().join(","),
            "iteration,l1,dssim,reg,0.8*l1,0.2*dssim,8e-6*reg,total,num_gaussians,elapsed_seconds,skipped_steps,val_psnr"
        );
        assert_eq!(
            layout.unweighted().header().join(","),
            "iteration,l1,dssim,reg,total,num_gaussians,elapsed_seconds,skipped_steps,val_psnr"
        );
        let values = vec![
            ("l1".to_string(), 0.5),
            ("dssim".to_string(), 0.25),
            ("reg".to_string(), 2.0),
        ];
        let stats = RowStats {
            iteration: 7,
            total: 0.45,
            num_gaussians: 3,
            elapsed: 1.5,
            skipped: 0,
            val: "",
        };
        let row = layout.row(&values, &stats);
        let cells: Vec<f64> = row[4..7]
            .iter()
            .map(|c| c.parse().expect("number"))
            .collect();
        assert_eq!(cells, vec![0.4, 0.05, 1.6e-5]);
        assert_eq!(row.len(), layout.header().len());
        let old = layout.unweighted().row(&values, &stats);
        assert_eq!(old.len(), 9, "{old:?}");
    }
}
