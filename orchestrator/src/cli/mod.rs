//! The `survey` command line: the roof. `main` parses the arguments,
//! [`dispatch`] runs the command (one file per command), and the exit status
//! is decided once, from the error's type ([`crate::error::exit_status`]):
//! 0 on success, 1 when the work failed at run time (an instrument, the
//! disk), 2 for bad usage or bad input. Every command that fails on its input
//! stores nothing. Nothing below this module imports it.

mod check;
mod export;
mod import;
mod list;
mod model_gap;
mod process;
mod report;
mod resume;
mod run;
mod sim;
mod stats;
mod support;

use clap::{Parser, Subcommand};
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
    #[arg(long, global = true, value_name = "PATH", default_value = crate::process::DEFAULT_DB, env = "SURVEY_DB")]
    pub db: PathBuf,

    #[command(subcommand)]
    pub command: Command,
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Acquire a survey (the simulated instruments unless --config is given).
    Run(run::RunArgs),
    /// Connect to every configured instrument and say plainly what is wrong.
    Check(check::CheckArgs),
    /// Continue an interrupted survey from its last stored sample.
    Resume(resume::ResumeArgs),
    /// Write the survey's report (a self-contained HTML page with its plots and tables) into DIR.
    Report(report::ReportArgs),
    /// Store measured data from a CSV file as a new survey; prints its id.
    Import(import::ImportArgs),
    /// Write a survey in the import CSV format.
    Export(export::ExportArgs),
    /// ISO 230-2 statistics across runs.
    Stats(stats::StatsArgs),
    /// Find where a model and the measured data disagree, name what the model lacks, and close the gap.
    ModelGap(model_gap::ModelGapArgs),
    /// The paper's DSP processing: spectrum, lines, aliases, the correction table and its exports.
    Process(process::ProcessArgs),
    /// Every survey in the database: id, status, source, plan, samples stored of planned, dates.
    List(list::ListArgs),
    /// One survey in full: plan, instruments, located axis, model and event log.
    Show(list::ShowArgs),
    /// Serve the simulated instruments of a configuration over their real protocols, until a signal.
    Sim(sim::SimArgs),
}

/// Parse the arguments, run the command, map the outcome to the exit status.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    support::init_logging();
    let runtime = match tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build() {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(dispatch(cli)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(crate::error::exit_status(&e))
        }
    }
}

/// Run the command.
pub async fn dispatch(cli: Cli) -> anyhow::Result<()> {
    let db = &cli.db;
    match cli.command {
        Command::Run(args) => run::run(db, args).await,
        Command::Check(args) => check::check(args).await,
        Command::Resume(args) => resume::resume(db, args).await,
        Command::Report(args) => report::report(db, args).await,
        Command::Import(args) => import::import(db, args).await,
        Command::Export(args) => export::export(db, args).await,
        Command::Stats(args) => stats::stats(db, args).await,
        Command::ModelGap(args) => model_gap::model_gap(db, args).await,
        Command::Process(args) => process::process(db, args).await,
        Command::List(args) => list::list(db, args).await,
        Command::Show(args) => list::show(db, args).await,
        Command::Sim(args) => sim::sim(args).await,
    }
}
