//! `maaf sweep`: write an ablation grid as run folders and a plain job list
//! ([`maaf_train::sweep`]); running the jobs is left to `bash`, GNU parallel or a
//! cluster's array jobs.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, bail};
use maaf_scene::write_atomic;
use maaf_train::sweep::{Axis, Layout, points, shell_quote, split_args};

use super::train::{SettingsArgs, config_from};

/// Arguments of `maaf sweep`.
#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// Data folder every point trains on (D-NeRF, Plenoptic Video or the Dynamic 3D
    /// Gaussians layout).
    #[arg(long)]
    pub data: PathBuf,
    /// Sweep folder to create: one run folder per point, jobs.txt, report.sh.
    #[arg(long)]
    pub out: PathBuf,
    /// An axis `dotted.key=v1,v2,...` of the training config (repeat for more axes),
    /// e.g. `filter.grid_t=25,50,100,150` or `filter.h_x=0.1,0.2,0.3`.
    #[arg(long = "grid", required = true)]
    pub grid: Vec<String>,
    /// Every combination of the axes instead of one axis at a time around the base.
    #[arg(long)]
    pub cross: bool,
    /// Extra arguments of `maaf eval` for every point, as one string split as a shell
    /// would (quotes group words).
    #[arg(long, default_value = "", allow_hyphen_values = true)]
    pub eval_args: String,
    /// The base point's settings, as for `maaf train`.
    #[command(flatten)]
    pub settings: SettingsArgs,
}

/// Writes the sweep and prints how to run it.
pub fn run(args: &SweepArgs) -> anyhow::Result<()> {
    let settings = &args.settings;
    let data_arg = &args.data;
    if !data_arg.is_dir() {
        bail!("{}: not a data folder", data_arg.display());
    }
    if args.out.exists() {
        bail!(
            "{}: already exists; a sweep is written into a new folder",
            args.out.display()
        );
    }
    let eval_args = split_args(&args.eval_args, "--eval-args")?;
    let base = config_from(settings)?;
    let axes = args
        .grid
        .iter()
        .map(|g| Axis::parse(g))
        .collect::<Result<Vec<_>, _>>()?;
    let layout = if args.cross {
        Layout::Cross
    } else {
        Layout::OneAtATime
    };
    let pts = points(&base, &axes, layout)?;
    let exe = std::env::current_exe().context("cannot locate the maaf executable")?;
    let data = std::path::absolute(data_arg)
        .with_context(|| format!("{}: cannot resolve", data_arg.display()))?;
    std::fs::create_dir_all(args.out.join("configs"))
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let out = std::path::absolute(&args.out)
        .with_context(|| format!("{}: cannot resolve", args.out.display()))?;
    let q = |p: &std::path::Path| shell_quote(&p.display().to_string());
    let mut jobs = String::new();
    let mut runs = Vec::with_capacity(pts.len());
    for p in &pts {
        let dir = out.join(&p.name);
        let spec = out.join("configs").join(format!("{}.json", p.name));
        let json = serde_json::to_string_pretty(&p.config)?;
        write_atomic(&spec, json.as_bytes())?;
        let eval_extra: String = eval_args
            .iter()
            .map(|a| format!(" {}", shell_quote(a)))
            .collect();
        writeln!(
            jobs,
            "{exe} train --data {data} --out {dir} --config {spec} && {exe} eval --run {dir}{eval_extra}",
            exe = q(&exe),
            data = q(&data),
            dir = q(&dir),
            spec = q(&spec),
        )?;
        runs.push(q(&dir));
    }
    write_atomic(&out.join("jobs.txt"), jobs.as_bytes())?;
    let report = format!(
        "#!/bin/sh\n# Tables and charts of every evaluated point of this sweep.\nset --\nfor d in {}; do\n  [ -f \"$d/eval.json\" ] && set -- \"$@\" \"$d\"\ndone\n[ $# -gt 0 ] || {{ echo 'no evaluated point yet' >&2; exit 1; }}\nexec {} report --runs \"$@\" --out {}\n",
        runs.join(" "),
        q(&exe),
        q(&out.join("report"))
    );
    write_atomic(&out.join("report.sh"), report.as_bytes())?;
    println!(
        "sweep: {} points ({}) in {}",
        pts.len(),
        if args.cross {
            "every combination"
        } else {
            "one axis at a time"
        },
        out.display()
    );
    for p in &pts {
        println!("  {}", p.name);
    }
    println!(
        "run them:  bash {0}/jobs.txt   (or: parallel -j1 < {0}/jobs.txt)",
        out.display()
    );
    println!("report:    sh {}/report.sh", out.display());
    Ok(())
}
