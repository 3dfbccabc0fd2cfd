//! The `survey` command line.
//!
//! Exit status: 0 on success, 1 when the work failed at run time (an
//! instrument, the disk), 2 for bad usage or bad input. Every command that
//! fails on its input stores nothing.

use crate::commands;
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;

/// Calibrate rotary positioners and correct their angular error.
///
/// A survey steps the axis forward and back over several runs, pairing the
/// positioner's readout with an independent reference (a tracking laser or an
/// autocollimator), stores every sample in SQLite, and computes ISO 230-2
/// statistics. Without `--config`, `survey run` uses the built-in simulated
/// instruments (the paper's Figure 8 positioner and a tracking laser).
#[derive(Debug, Parser)]
#[command(name = "survey", version, propagate_version = true, max_term_width = 100)]
pub struct Cli {
    /// The SQLite database that holds the surveys.
    #[arg(long, global = true, value_name = "PATH", default_value = "survey.db", env = "SURVEY_DB")]
    pub db: PathBuf,

    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Acquire a survey (the simulated instruments unless --config is given).
    Run(RunArgs),
    /// Connect to every configured instrument and say plainly what is wrong.
    Check(CheckArgs),
    /// Continue an interrupted survey from its last stored sample.
    Resume(ResumeArgs),
    /// Write the survey's report (a self-contained HTML page with its plots and tables) into DIR.
    Report(ReportArgs),
    /// Store measured data from a CSV file as a new survey; prints its id.
    Import(ImportArgs),
    /// Write a survey in the import CSV format.
    Export(ExportArgs),
    /// ISO 230-2 statistics across runs.
    Stats(StatsArgs),
    /// Find where a model and the measured data disagree, name what the model lacks, and close the gap.
    ModelGap(ModelGapArgs),
    /// The paper's DSP processing: spectrum, lines, aliases, the correction table and its exports.
    Process(ProcessArgs),
}

/// The reference instrument that measures the actual angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReferenceKind {
    /// A tracking laser measuring an SMR on an arm (the axis is located first).
    Tracker,
    /// An autocollimator on a polygon: the targets are the faces (--points = faces).
    Autocollimator,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Targets per revolution (or over the travel of a partial-range axis);
    /// with an autocollimator, the polygon's faces.
    #[arg(long, value_name = "N")]
    pub points: Option<u32>,
    /// Measure the reverse pass too (needed for hysteresis and the reversal value).
    #[arg(long)]
    pub bidirectional: bool,
    /// Runs [default: 5, as ISO 230-2 asks].
    #[arg(long, value_name = "R")]
    pub runs: Option<u32>,
    /// Survey real instruments described in this configuration file (TOML).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["model", "preset", "reference", "seed"])]
    pub config: Option<PathBuf>,
    /// Positioner model file (TOML) for the simulated positioner, instead of the preset's.
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// Simulated positioner: one of the paper's positioners.
    #[arg(long, value_name = "NAME", default_value = "fig8", value_parser = ["fig1", "fig4", "fig8"])]
    pub preset: String,
    /// Reference instrument of the simulated bench.
    #[arg(long, value_enum, default_value_t = ReferenceKind::Tracker)]
    pub reference: ReferenceKind,
    /// Seed of every random draw of the simulated instruments.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the summary as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Process with this recipe (TOML) at the end, as the last calibration did.
    #[arg(long, value_name = "FILE")]
    pub recipe: Option<PathBuf>,
    /// After processing, load the table into the positioner, apply it in the
    /// feedback path and measure the corrected accuracy with a new survey.
    #[arg(long)]
    pub verify: bool,
    /// Fault injection for tests: the process aborts (like a power loss)
    /// once N samples have been measured on the simulated bench.
    #[arg(long, value_name = "N", hide = true, conflicts_with = "config")]
    pub sim_crash_after: Option<u64>,
}

#[derive(Debug, Args)]
pub struct CheckArgs {
    /// The configuration file whose instruments to check.
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct ResumeArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Print the summary as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// The folder to write index.html into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct ImportArgs {
    /// CSV file: run,direction,target_deg,readout_deg,actual_deg[,timestamp_s].
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
}

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Where to write the CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: PathBuf,
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
}

#[derive(Debug, Args)]
pub struct StatsArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct ProcessArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Positioner model file (TOML) whose [design] names the lines [default: the survey's stored model].
    #[arg(long, value_name = "FILE")]
    pub design: Option<PathBuf>,
    /// Replay this processing recipe (TOML) instead of deriving one from the survey.
    #[arg(long, value_name = "FILE")]
    pub recipe: Option<PathBuf>,
    /// The correction table CSV [default: table-<ID>.csv]; the LinuxCNC files
    /// (<stem>.comp0, <stem>.comp1), the binary table (<stem>.bin) and the recipe
    /// used (<stem>.recipe.toml) go beside it.
    #[arg(long, value_name = "FILE")]
    pub table_out: Option<PathBuf>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct ModelGapArgs {
    /// The positioner model file (TOML) to compare with the survey.
    #[arg(long, value_name = "FILE")]
    pub model: PathBuf,
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Write the improved model file (the model with the effects added and adjusted) here.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// A failed command: bad usage or input (exit 2) or a run-time failure (exit 1).
#[derive(Debug)]
pub enum Failure {
    Usage(anyhow::Error),
    Runtime(anyhow::Error),
}

impl Failure {
    pub fn usage(e: impl Into<anyhow::Error>) -> Self {
        Failure::Usage(e.into())
    }
    pub fn runtime(e: impl Into<anyhow::Error>) -> Self {
        Failure::Runtime(e.into())
    }
}

/// Parse the arguments, run the command, map the outcome to the exit status.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging();
    let runtime = match tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build() {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(commands::dispatch(cli)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Usage(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
        Err(Failure::Runtime(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Logs go to stderr through `tracing`; `RUST_LOG` sets the level (default: warnings).
fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    use std::io::IsTerminal as _;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
}

/// Write command output to stdout. A closed pipe (`survey stats | head`) is
/// not an error worth a panic: the reader has what it wanted.
pub fn emit(text: &str) {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(text.as_bytes()).and_then(|()| out.flush());
}
