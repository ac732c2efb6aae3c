//! Reading a run's `log.csv` back: one column against another over the rows where the
//! second has a value (the validation PSNR is logged on some rows only).

use std::path::Path;

use crate::Error;

/// `(x, y)` of every row of the log at `path` whose column `y` is not empty, `x` and
/// `y` the columns of those names; empty when the log is missing or lacks either
/// column (a run from before it existed). A cell that is not a number is an error
/// naming the line.
pub fn logged_pairs(path: &Path, x: &str, y: &str) -> Result<Vec<(f64, f64)>, Error> {
    if !path.is_file() {
        return Ok(Vec::new());
    }
    let bad = |e: csv::Error| Error::Input(format!("{}: {e}", path.display()));
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .from_path(path)
        .map_err(bad)?;
    let header = reader.headers().map_err(bad)?.clone();
    let column = |name: &str| header.iter().position(|h| h == name);
    let (Some(cx), Some(cy)) = (column(x), column(y)) else {
        return Ok(Vec::new());
    };
    let mut points = Vec::new();
    for (k, row) in reader.records().enumerate() {
        let row = row.map_err(bad)?;
        let cell = |i: usize| row.get(i).unwrap_or("");
        if cell(cy).is_empty() {
            continue;
        }
        let parse = |i: usize| {
            cell(i).parse::<f64>().map_err(|_| {
                Error::Input(format!(
                    "{}: line {}: `{}` is not a number",
                    path.display(),
                    k + 2,
                    cell(i)
                ))
            })
        };
        points.push((parse(cx)?, parse(cy)?));
    }
    Ok(points)
}
