//! The command line of `maaf bench-suite`: its arguments, the options that plan a
//! suite (refused with `--job`, `--report-only` and `--record`), and the backgrounds a
//! run trains and is evaluated on.

use std::path::PathBuf;

use maaf_eval::report::suite::SuiteRun;

use super::super::train::FilterArg;

/// Arguments of `maaf bench-suite`.
#[derive(clap::Args, Debug)]
pub struct BenchSuiteArgs {
    /// Suite folder: suite.json, configs/, runs/SCENE/PRESET-FILTER-BACKGROUND/,
    /// jobs.txt, report.md and report.json. Invoked again with the same options, the
    /// suite continues where it stopped.
    #[arg(long)]
    pub out: PathBuf,
    /// Folder of D-NeRF scenes: every subfolder holding transforms_train.json is a
    /// scene [default: none; required unless --report-only, --job or --record].
    #[arg(long, required_unless_present_any = ["report_only", "job", "record"])]
    pub data: Option<PathBuf>,
    /// Only these scenes (folder names, comma-separated) [default: every scene].
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Preset files (configs/*.json; repeat or comma-separate), one method each, named
    /// by the file's stem [default: none; required unless --report-only, --job or --record].
    #[arg(
        long = "preset",
        value_delimiter = ',',
        required_unless_present_any = ["report_only", "job", "record"]
    )]
    pub presets: Vec<PathBuf>,
    /// 3D filters, one run each.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "none,mip3d,motion"
    )]
    pub filters: Vec<FilterArg>,
    /// Backgrounds the RGBA images are composited on, for training and evaluation
    /// alike, one run each (black: the authors' D-NeRF runs; docs/cli.md says why it
    /// is the default); `random` trains each view on its own random colour
    /// (`random_background`) and evaluates on black.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "black")]
    pub backgrounds: Vec<SuiteBackground>,
    /// Evaluation split per scene, SCENE=SPLIT (comma-separated); every other scene is
    /// evaluated on test. Lego's test split does not match its training split, so lego
    /// is evaluated on val as Deformable-3DGS does; a scene named here but absent from
    /// --data is ignored.
    #[arg(long = "split", value_delimiter = ',', default_value = "lego=val")]
    pub splits: Vec<String>,
    /// Seeds (comma-separated), one run each per scene x preset x filter x background,
    /// so that the report can say how far two runs differ by chance (its seeds table)
    /// and average each scene over its seeds; the run folders end in `-seedN`
    /// [default: the preset's seed, one run each].
    #[arg(long, value_delimiter = ',')]
    pub seeds: Vec<u64>,
    /// Iterations of every run (quick checks) [default: each preset's].
    #[arg(long)]
    pub iters: Option<usize>,
    /// Extra arguments of `maaf eval` for every run, as one string split as a shell
    /// would (quotes group words).
    #[arg(long, default_value = "--no-images", allow_hyphen_values = true)]
    pub eval_args: String,
    /// Also evaluate every run on these backgrounds (`white` and/or `black`), after its
    /// own evaluation: `RUN/eval-on-NAME.json`, which the report tabulates beside the
    /// run's own PSNR (a model trained on black shows its black floaters on white); a
    /// run's own background is left out [default: none].
    #[arg(long, value_enum, value_delimiter = ',')]
    pub also_eval_on: Vec<SuiteBackground>,
    /// Write the run folders' configs and jobs.txt and stop (run the lines anywhere,
    /// then `maaf bench-suite --out OUT --report-only`).
    #[arg(long)]
    pub jobs_only: bool,
    /// Only write the report from the runs evaluated so far (reads OUT/suite.json;
    /// the options that plan a suite are refused with it).
    #[arg(long, conflicts_with_all = PLANNING)]
    pub report_only: bool,
    /// Only run job N of the suite written in --out (1-based, the line number in
    /// jobs.txt), as the whole suite would: skipped when evaluated, resumed from its
    /// newest checkpoint when interrupted, else trained; then evaluated. Reads
    /// OUT/suite.json (the options that plan a suite are refused with it); no report
    /// is written (`--report-only` does that) [default: every job].
    #[arg(long, conflicts_with_all = PLANNING, conflicts_with = "report_only")]
    pub job: Option<usize>,
    /// Copy the measurements of the suite in --out (suite.json and each evaluated
    /// run's eval.json, summary.json and eval-on-*.json, a few kB per run) into DIR, a
    /// record that `--report-only --out DIR` reports without the run folders; into an
    /// earlier record, the runs are added to it (docs/cli.md). Reads OUT/suite.json
    /// (the options that plan a suite are refused with it) [default: none].
    #[arg(long, value_name = "DIR", conflicts_with_all = PLANNING, conflicts_with_all = ["report_only", "job"])]
    pub record: Option<PathBuf>,
}

/// The options that plan a suite: `--job` and `--report-only` read the plan from
/// OUT/suite.json, so these given with them would be ignored; clap refuses them.
const PLANNING: [&str; 11] = [
    "jobs_only",
    "data",
    "scenes",
    "presets",
    "filters",
    "backgrounds",
    "splits",
    "seeds",
    "iters",
    "eval_args",
    "also_eval_on",
];

/// `--backgrounds` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SuiteBackground {
    /// White (D-NeRF's `white_bkgd`, maaf's default elsewhere).
    White,
    /// Black (SaRO-GS's and the MAAF authors' D-NeRF runs).
    Black,
    /// A random colour per training view, the ground truth composited on the same
    /// (config key `random_background`); the data set is opened on black, so the run
    /// is evaluated on black like the others and compares with Tab. 2.
    Random,
}

impl SuiteBackground {
    /// The run's label in folder names and the report.
    pub(super) fn name(self) -> &'static str {
        match self {
            SuiteBackground::White => "white",
            SuiteBackground::Black => "black",
            SuiteBackground::Random => "random",
        }
    }

    /// The `--background` of `maaf train` (the data set's background).
    pub(super) fn data(self) -> &'static str {
        match self {
            SuiteBackground::White => "white",
            SuiteBackground::Black | SuiteBackground::Random => "black",
        }
    }

    /// The background a run's label names.
    pub(super) fn of_run(run: &SuiteRun) -> anyhow::Result<Self> {
        <Self as clap::ValueEnum>::from_str(&run.background, false)
            .map_err(|_| anyhow::anyhow!("suite.json: unknown background {:?}", run.background))
    }

    /// Suffix of the config file of its runs: the random background's runs train with
    /// their own config (the preset's plus `random_background`).
    pub(super) fn config_suffix(self) -> &'static str {
        match self {
            SuiteBackground::Random => "-random",
            SuiteBackground::White | SuiteBackground::Black => "",
        }
    }
}
