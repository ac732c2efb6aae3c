//! `maaf report`: markdown tables (paper Tab. 2 layout) and PNG charts of evaluated runs.

use std::path::PathBuf;

use maaf_eval::report::write_report;

/// Arguments of `maaf report`.
#[derive(clap::Args, Debug)]
pub struct ReportArgs {
    /// Evaluated run directories (each holds eval.json), one row each.
    #[arg(long, num_args = 1.., required = true)]
    pub runs: Vec<PathBuf>,
    /// Output folder for report.md and the charts.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `maaf report`.
pub fn run(args: &ReportArgs) -> anyhow::Result<()> {
    let out = write_report(&args.runs, &args.out)?;
    print!("{}", out.table);
    if !out.extra.is_empty() {
        print!("\n{}", out.extra);
    }
    for c in &out.charts {
        println!("chart: {}", c.display());
    }
    println!("report: {}", out.markdown.display());
    Ok(())
}
