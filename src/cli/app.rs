//! The `maaf` command line as a value a program of one's own runs, with loss terms of
//! its own registered by name (docs/architecture.md, "The CLI as a library").

use clap::Parser;
use maaf_autodiff::Var;
use maaf_scene::ModelRegistry;
use maaf_scene::TrainConfig;
use maaf_train::loss::{Term, TermCtx, TermRegistry};
use maaf_train::models::{ModelInit, Representation};

use super::command::{self, Cli};
use crate::alloc;

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
/// The built-in terms ([`maaf_train::loss::builtin`]) are always registered. A run
/// records its terms in `config.json`; `train --resume` continues it when this
/// program registers them all and refuses it with one line naming those it lacks.
/// The other commands (eval, render, export-ply, ...) read such runs without them.
pub struct Maaf {
    terms: TermRegistry<f32>,
    models: ModelRegistry,
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
            terms: TermRegistry::builtin(),
            models: ModelRegistry::builtin(),
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
        self.terms.register_fn(name, f);
        self
    }

    /// Registers a term made by `maker` from the weight a config gives it (a
    /// [`Term`] with state of its own); the term must be named `name` and keep that
    /// weight. Panics as [`Maaf::term`].
    pub fn term_with<F>(mut self, name: &str, maker: F) -> Self
    where
        F: Fn(f64) -> Box<dyn Term<f32>> + Send + Sync + 'static,
    {
        self.terms.register(name, maker);
        self
    }

    /// Registers the loader of a representation of one's own under `name` (its
    /// [`Representation::name`], recorded in every checkpoint), so that `eval`,
    /// `render`, `render-video`, `export-ply` and the test PSNR after `train` load its
    /// runs as a [`maaf_scene::TrainedScene`]. The loader builds the model
    /// (empty parameters of the right names; the checkpoint fills them) from the run's
    /// config and initial values, as `examples/custom_representation.rs` does.
    pub fn representation<F>(mut self, name: &str, loader: F) -> Self
    where
        F: Fn(&TrainConfig, &ModelInit) -> Result<Box<dyn Representation<f32>>, String>
            + Send
            + Sync
            + 'static,
    {
        self.models.register(name, loader);
        self
    }

    /// Parses the process's arguments and runs the command, as the `maaf` binary
    /// does: mimalloc keeps freed pages ([`alloc::keep_freed_pages`]), the command
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
        alloc::keep_freed_pages();
        if let Err(e) = self.execute(Cli::parse()) {
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
            Ok(pool) => pool.install(|| command::run(cli, &self.terms, &self.models)),
            Err(e) => Err(anyhow::anyhow!("cannot start the worker threads: {e}")),
        }
    }
}
