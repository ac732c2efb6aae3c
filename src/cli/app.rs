//! The `maaf` command line as a value a program of one's own runs, with loss terms,
//! representations, filters, densification strategies, image metrics and data layouts
//! of its own registered by name (docs/architecture.md, "The CLI as a library"; docs/extending.md).

use clap::Parser;
use maaf_autodiff::Var;
use maaf_eval::{ImageMetric, MetricRegistry};
use maaf_filter::{FilterConfig, SamplingFilter};
use maaf_scene::TrainConfig;
use maaf_train::Plugins;
use maaf_train::data::DataFormat;
use maaf_train::loss::{Term, TermCtx};
use maaf_train::models::{ModelInit, Representation};
use maaf_train::trainer::Strategy;

use super::command::{self, Cli};

/// Stack size of the worker threads, which run the whole command (as the main
/// thread's default would be).
const WORKER_STACK: usize = 8 << 20;

/// The whole `maaf` command line (every subcommand, config and flag merging, resume)
/// plus the loss terms a program registers, which a training config then names with
/// a weight (`"terms": {"smoothness": 0.01}`, docs/config.md):
///
/// ```no_run
/// use maaf::autodiff::Var;
/// use maaf::train::loss::TermCtx;
///
/// /// Mean rendered alpha: fewer, more opaque Gaussians.
/// fn alpha_mean<'t>(ctx: &TermCtx<'t, f32>) -> Var<'t, f32> {
///     ctx.alpha().mean()
/// }
///
/// fn main() {
///     maaf::cli::Maaf::new().term("alpha_mean", alpha_mean).run()
/// }
/// ```
///
/// The built-in terms ([`maaf_train::loss::builtin`]), representations, filters and
/// strategies are always registered. A run records the names it uses in
/// `config.json`; `train --resume` continues it when this program registers them all
/// and refuses it with one line naming what it lacks. The other commands (eval,
/// render, export-ply, ...) read such runs without the terms, filters and
/// strategies; a custom representation they need ([`Maaf::representation`]).
pub struct Maaf {
    plugins: Plugins,
    metrics: MetricRegistry,
}

impl Default for Maaf {
    /// [`Maaf::new`].
    fn default() -> Self {
        Self::new()
    }
}

impl Maaf {
    /// The command line with the built-in terms only: what the `maaf` binary runs.
    pub fn new() -> Self {
        Maaf {
            plugins: Plugins::builtin(),
            metrics: MetricRegistry::new(),
        }
    }

    /// Registers a term written as a function of the training step's context
    /// ([`TermCtx`]: render, ground truth, alpha, depth, deformed Gaussians, camera,
    /// time, iteration) under `name`; a config gives its weight. Panics if `name` is
    /// taken (a built-in term, `l1`, `dssim`) or is not 1 to 64 letters, digits or `_`.
    pub fn term<F>(mut self, name: &str, f: F) -> Self
    where
        F: for<'a, 't> Fn(&'a TermCtx<'t, f32>) -> Var<'t, f32> + Send + Sync + 'static,
    {
        if let Err(e) = self.plugins.terms.register_fn(name, f) {
            panic!("Maaf::term: {e}");
        }
        self
    }

    /// Registers a term made by `maker` from the weight a config gives it (a
    /// [`Term`] with state of its own); the term must be named `name` and keep that
    /// weight. Panics as [`Maaf::term`].
    pub fn term_with<F>(mut self, name: &str, maker: F) -> Self
    where
        F: Fn(f64) -> Box<dyn Term<f32>> + Send + Sync + 'static,
    {
        if let Err(e) = self.plugins.terms.register(name, maker) {
            panic!("Maaf::term_with: {e}");
        }
        self
    }

    /// Registers the factory of a representation of one's own under `name` (its
    /// [`Representation::name`], recorded in every checkpoint). `maaf train` builds
    /// it for a config whose `"model": {"kind": "NAME", ...}` names it: the factory
    /// gets the run's config (its own options, the section's other keys, as JSON:
    /// `config.model.options()`, which it validates, naming the field) and the
    /// initial cloud. `eval`, `render`, `render-video`, `export-ply` and the test
    /// PSNR after `train` rebuild it the same way from a checkpoint (whose tensors
    /// then replace the parameters) to load its runs as a
    /// [`maaf_scene::TrainedScene`]; `examples/custom_representation.rs`. Panics if
    /// `name` is taken (`saro`, `deform`, `track`) or is not 1 to 64 letters, digits
    /// or `_`.
    pub fn representation<F>(mut self, name: &str, factory: F) -> Self
    where
        F: Fn(&TrainConfig, &ModelInit) -> Result<Box<dyn Representation<f32>>, String>
            + Send
            + Sync
            + 'static,
    {
        if let Err(e) = self.plugins.models.register(name, factory) {
            panic!("Maaf::representation: {e}");
        }
        self
    }

    /// Registers a sampling-rate filter of one's own under `name`, made by `factory`
    /// from the run's filter settings (its own under `filter.options`, which it
    /// checks, an error naming the option): `maaf train --filter NAME` or a config's
    /// `"filter": {"kind": "NAME"}` trains with it, `config.json` and every
    /// checkpoint record the name, `train --resume` of such a run needs a program
    /// that registers it, and `eval` and `report` label the run by it
    /// (`examples/custom_filter.rs`). Panics if `name` is taken (a built-in filter)
    /// or is not 1 to 64 letters, digits or `_`.
    pub fn filter<F>(mut self, name: &str, factory: F) -> Self
    where
        F: Fn(&FilterConfig) -> Result<Box<dyn SamplingFilter>, String> + Send + Sync + 'static,
    {
        if let Err(e) = self.plugins.filters.register(name, factory) {
            panic!("Maaf::filter: {e}");
        }
        self
    }

    /// Registers a densification strategy of one's own under `name`, made by
    /// `factory` from the run's config (its own options under `densify.options`; an
    /// error names the field): a config's
    /// `"densify": {"strategy": "NAME"}` trains with it, and its
    /// [`Strategy::state`] is saved in every checkpoint so that `train --resume`
    /// continues it bit for bit (`examples/custom_strategy.rs`). Panics if `name` is
    /// taken (`default`, `sensitivity`) or is not 1 to 64 letters, digits or `_`.
    pub fn strategy<F>(mut self, name: &str, factory: F) -> Self
    where
        F: Fn(&TrainConfig) -> Result<Box<dyn Strategy>, String> + Send + Sync + 'static,
    {
        if let Err(e) = self.plugins.strategies.register(name, factory) {
            panic!("Maaf::strategy: {e}");
        }
        self
    }

    /// Registers a per-image metric of one's own under `name` (its
    /// [`ImageMetric::name`]), made by `factory` once per evaluation: `maaf eval`
    /// computes it on every view beside PSNR, SSIM and LPIPS (`--metrics` chooses
    /// among the registered ones), writes a `metrics.csv` column and its mean per
    /// scale in `eval.json`'s `extra`, and `maaf report` tabulates it
    /// (`examples/custom_metric.rs`). Panics if `name` is taken (`psnr`, `ssim`,
    /// `lpips`, another registered metric, the `view` and `time` columns) or is not
    /// 1 to 64 letters, digits or `_`.
    pub fn metric<F>(mut self, name: &str, factory: F) -> Self
    where
        F: Fn() -> Box<dyn ImageMetric> + Send + Sync + 'static,
    {
        if let Err(e) = self.metrics.register(name, factory) {
            panic!("Maaf::metric: {e}");
        }
        self
    }

    /// Registers a data layout of one's own under `name`: every command that opens a
    /// data folder (`train --data`, `eval`, `render`, `bench`, `cameras`, `inspect`,
    /// a run's recorded folder) reads a folder that no built-in layout (D-NeRF,
    /// Plenoptic Video, Dynamic 3D Gaussians) claims with the first registered format
    /// whose [`DataFormat::detect`] accepts it (`examples/custom_data_format.rs`).
    /// Panics if `name` is taken (another registered format, `dnerf`, `plenoptic`,
    /// `dynamic3dgs`) or is not 1 to 64 letters, digits or `_`.
    pub fn data_format<F: DataFormat + 'static>(mut self, name: &str, format: F) -> Self {
        if let Err(e) = self.plugins.formats.register(name, format) {
            panic!("Maaf::data_format: {e}");
        }
        self
    }

    /// Parses the process's arguments and runs the command, as the `maaf` binary
    /// does: messages go to stderr at the level `-q` / `-v` choose, the command
    /// runs on a worker of the rayon pool (`RAYON_NUM_THREADS` threads, default one
    /// per core), and an error prints as one line (`maaf: error: ...`) and exits with
    /// code 1. `--help` and argument errors print and exit as clap does.
    ///
    /// Why a worker: a parallel loop started from outside the pool hands its work
    /// over and sleeps until a worker has finished it, and a training step starts
    /// hundreds of small parallel loops, which then each paid a thread wake-up. From
    /// inside the pool, the calling worker starts on the work at once and the others
    /// join when they wake.
    pub fn run(self) {
        quiet_on_closed_pipe();
        // A child of `maaf bench-suite` ends with the suite, however the suite ends.
        if let Err(e) = maaf_io::process::end_with_parent() {
            eprintln!("maaf: error: {e}");
            std::process::exit(1);
        }
        let cli = Cli::parse();
        init_logger(cli.log_level());
        if let Err(e) = self.execute(cli) {
            eprintln!("maaf: error: {e:#}");
            std::process::exit(1);
        }
    }

    /// Runs the command line `args` (the first item is the program name, as in
    /// `std::env::args`) on a worker pool as [`Maaf::run`] does, and returns its error
    /// instead of printing it and exiting: for a program that runs maaf commands
    /// itself, or a test. `--help` and argument errors come back as errors too.
    pub fn run_args<I, S>(&self, args: I) -> anyhow::Result<()>
    where
        I: IntoIterator<Item = S>,
        S: Into<std::ffi::OsString> + Clone,
    {
        self.execute(Cli::try_parse_from(args)?)
    }

    /// Runs a parsed command on a worker of a new rayon pool.
    fn execute(&self, cli: Cli) -> anyhow::Result<()> {
        match rayon::ThreadPoolBuilder::new()
            .stack_size(WORKER_STACK)
            .build()
        {
            Ok(pool) => pool.install(|| command::run(cli, &self.plugins, &self.metrics)),
            Err(e) => Err(anyhow::anyhow!("cannot start the worker threads: {e}")),
        }
    }
}

/// Prints the library's messages on stderr at `level` and above (`RUST_LOG` wins when
/// set), one line each: `maaf: MESSAGE`, `maaf: warning: MESSAGE`. A program that set
/// a logger of its own keeps it.
fn init_logger(level: log::LevelFilter) {
    let _ = env_logger::Builder::new()
        .filter_level(level)
        .parse_default_env()
        .format(|buf, record| {
            use std::io::Write;
            match record.level() {
                log::Level::Warn => writeln!(buf, "maaf: warning: {}", record.args()),
                log::Level::Error => writeln!(buf, "maaf: error: {}", record.args()),
                _ => writeln!(buf, "maaf: {}", record.args()),
            }
        })
        .try_init();
}

/// Lets a closed pipe end the process quietly, as command-line tools do (`maaf
/// bench-suite ... | head -1`): Rust starts with SIGPIPE ignored, so a print to a
/// closed pipe would panic with a backtrace instead. Outputs are written atomically,
/// so a process ended by the signal leaves no partial file.
#[allow(unsafe_code)]
fn quiet_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: sets the disposition of one signal to its default, at start-up before
    // any command runs; no handler is installed.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
