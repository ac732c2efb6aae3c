//! The columns of `log.csv`: `iteration`, each objective term's unweighted value by
//! name, then each term's weighted value under `<weight>*<name>` (what it added to the
//! total, its weight in the header), then `total`, `num_gaussians`,
//! `elapsed_seconds`, `skipped_steps` and `val_psnr`.
//!
//! Runs logged before the weighted columns existed have the same header without them;
//! a resume of such a run keeps appending in that layout ([`LogLayout::unweighted`]).

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

    /// The header line (no newline).
    pub(super) fn header(&self) -> String {
        let mut header = String::from("iteration");
        for (name, _) in &self.terms {
            header.push(',');
            header.push_str(name);
        }
        if self.weighted {
            for (name, weight) in &self.terms {
                header.push_str(&format!(",{}*{name}", weight_text(*weight)));
            }
        }
        header.push_str(",total,num_gaussians,elapsed_seconds,skipped_steps,val_psnr");
        header
    }

    /// One row (with its newline) from the step's unweighted term values by name
    /// (`NaN` for a term the step did not report).
    pub(super) fn row(&self, values: &[(String, f64)], stats: &RowStats<'_>) -> String {
        let value = |name: &str| {
            values
                .iter()
                .find(|(n, _)| n == name)
                .map_or(f64::NAN, |(_, v)| *v)
        };
        let mut row = stats.iteration.to_string();
        for (name, _) in &self.terms {
            row.push_str(&format!(",{:.6e}", value(name)));
        }
        if self.weighted {
            for (name, weight) in &self.terms {
                row.push_str(&format!(",{:.6e}", weight * value(name)));
            }
        }
        row.push_str(&format!(
            ",{:.6e},{},{:.3},{},{}\n",
            stats.total, stats.num_gaussians, stats.elapsed, stats.skipped, stats.val
        ));
        row
    }
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
            layout.header(),
            "iteration,l1,dssim,reg,0.8*l1,0.2*dssim,8e-6*reg,total,num_gaussians,elapsed_seconds,skipped_steps,val_psnr"
        );
        assert_eq!(
            layout.unweighted().header(),
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
        let cells: Vec<f64> = row
            .split(',')
            .skip(4)
            .take(3)
            .map(|c| c.parse().expect("number"))
            .collect();
        assert_eq!(cells, vec![0.4, 0.05, 1.6e-5]);
        assert_eq!(row.split(',').count(), layout.header().split(',').count());
        let old = layout.unweighted().row(&values, &stats);
        assert_eq!(old.split(',').count(), 9, "{old}");
    }
}
