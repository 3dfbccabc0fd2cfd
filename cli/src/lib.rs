//! The `survey` command line: the roof. `main` parses the arguments,
//! [`dispatch`] runs the command (one file per command), and the exit status
//! is decided once, from the error's type ([`survey_lab::error::exit_status`]):
//! 0 on success, 1 when the work failed at run time (an instrument, the
//! disk), 2 for bad usage or bad input. Every command that fails on its input
//! stores nothing. Nothing below this module imports it.

pub mod progress;

#[cfg(test)]
mod architecture_tests;
#[cfg(test)]
mod fuzz_tests;
#[cfg(test)]
mod import_circles_tests;

mod args;
mod check;
mod compare;
mod docs;
mod due;
mod export;
mod history;
mod import;
mod list;
mod model_gap;
mod process;
mod push;
mod report;
mod resume;
mod run;
mod serve;
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
#[command(name = "survey", version, propagate_version = true, max_term_width = 100, after_help = EXAMPLES)]
pub struct Cli {
    /// The SQLite database that holds the surveys, or a lab store's postgres:// URL (read commands) [default: survey.db; env: SURVEY_DB].
    #[arg(long, value_name = "PATH|URL", value_hint = clap::ValueHint::FilePath)]
    pub db: Option<PathBuf>,

    /// Say more on stderr: -v how the work is done, -vv debug, -vvv trace (RUST_LOG, when set, decides instead).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,

    #[command(subcommand)]
    pub command: Command,
}

const EXAMPLES: &str = "\
Examples:
  survey run --points 360 --bidirectional     # a survey on the simulated bench, processed
  survey stats                                # ISO 230-2 figures of the latest survey
  survey process --table-start -720 --table-end 720
  survey report --out certificate/            # the page and its DCC (index.html, dcc.xml)
  survey help process                         # every option of one command";

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Acquire a survey (the simulated instruments unless --config is given).
    #[command(override_usage = run::USAGE, after_help = "\
Examples:
  survey run --points 360 --bidirectional                 # simulated Figure 8 bench, 5 runs
  survey run --points 720 --runs 3 --bidirectional --preset fig4 --json
  survey run --points 24 --reference autocollimator       # a 24-face polygon
  survey run --config bench.toml --points 360 --bidirectional --verify")]
    Run {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: run::RunArgs,
    },
    /// Connect to every configured instrument and say plainly what is wrong.
    #[command(after_help = "\
Examples:
  survey check --config bench.toml
  survey check --config bench.toml --json")]
    Check(check::CheckArgs),
    /// Continue an interrupted survey from its last stored sample.
    #[command(after_help = "\
Examples:
  survey resume                   # the latest survey
  survey resume --survey 3 --json")]
    Resume {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: resume::ResumeArgs,
    },
    /// Write the survey's report, its calibration certificate: the HTML page (index.html) and the DCC (dcc.xml) into --out DIR.
    #[command(after_help = "\
Examples:
  survey report --out certificate/          # certificate/index.html and certificate/dcc.xml of the latest survey
  survey report --survey 3 --out survey-3/")]
    Report {
        #[command(flatten)]
        db: args::DbArg,
        // Boxed: the report's flags are many (clippy's large_enum_variant).
        #[command(flatten)]
        args: Box<report::ReportArgs>,
    },
    /// Store measured data from a CSV file as a new survey; prints its id.
    #[command(after_help = "\
Examples:
  survey import measured.csv
  survey --db lab.db import measured.csv && survey --db lab.db stats")]
    Import {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: import::ImportArgs,
    },
    /// Write a survey in the import CSV format.
    #[command(after_help = "\
Examples:
  survey export --csv survey.csv              # the latest survey
  survey export --csv survey-3.csv --survey 3")]
    Export {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: export::ExportArgs,
    },
    /// ISO 230-2 statistics across runs.
    #[command(after_help = "\
Examples:
  survey stats
  survey stats --survey 3 --json")]
    Stats {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: stats::StatsArgs,
    },
    /// Find where a model and the measured data disagree, name what the model lacks, and close the gap.
    #[command(after_help = "\
Examples:
  survey model-gap --model positioner.toml
  survey model-gap --model positioner.toml --out improved.toml --json")]
    ModelGap {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: model_gap::ModelGapArgs,
    },
    /// The paper's DSP processing: spectrum, lines, aliases, the correction table and its exports.
    #[command(after_help = "\
Examples:
  survey process --design positioner.toml                # name the lines from the design
  survey process --recipe survey-1/table-1.recipe.toml   # a recalibration, processed as the last one
  survey process --controller linuxcnc --table-start -720 --table-end 720
  survey process --controller 840d --sinumerik-axis A1 --sinumerik-absolute
  survey process --controller fanuc --table-interval 5 --table-directions separate
  survey process --controller generic --table-sign correction --table-values incremental")]
    Process {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: process::ProcessArgs,
    },
    /// Every survey in the database: id, status, source, plan, samples stored of planned, dates.
    #[command(after_help = "\
Examples:
  survey list
  survey --db lab.db list --json")]
    List {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: list::ListArgs,
    },
    /// One survey in full: plan, instruments, located axis, model and event log.
    #[command(after_help = "\
Examples:
  survey show          # the latest survey
  survey show 3 --json")]
    Show {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: list::ShowArgs,
    },
    /// An asset's surveys in time order, and what changed from each complete survey to the next.
    #[command(after_help = "\
Examples:
  survey history                          # the asset of the latest survey
  survey history --asset bay-2/az --json")]
    History {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: history::HistoryArgs,
    },
    /// What is due: each asset's next check, by its interval's method (ILAC-G24), when and why.
    #[command(after_help = "\
Examples:
  survey due                              # every asset, as of now
  survey due --asset bay-2/az --json
  survey due --at 2026-07-01              # what will be due by the first of July")]
    Due {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: due::DueArgs,
    },
    /// Has the positioner changed from survey A to survey B, and does A's table still hold?
    #[command(after_help = "\
Examples:
  survey compare 3 7
  survey compare 3 7 --json")]
    Compare {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: compare::CompareArgs,
    },
    /// Copy complete surveys from this station's SQLite file to the lab store, each once by its uid.
    #[command(after_help = "\
Examples:
  survey push --to postgres://station1:PASSWORD@lab-db:5432/surveys --all
  survey push --json        # the latest survey, to the lab store SURVEY_LAB names")]
    Push {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: push::PushArgs,
    },
    /// Serve the lab's pages, read-only: assets, live surveys, histories, reports and the JSON documents.
    #[command(after_help = "\
Examples:
  survey serve                                          # survey.db on http://127.0.0.1:8080
  survey --db lab.db serve --listen 127.0.0.1:0         # any free port: the ready line says which
  survey --db postgres://viewer:PASSWORD@lab-db/surveys serve --due-after 180   # the lab store
  survey serve --hash-password < password.txt           # a user's hash for the --auth file
  survey serve --listen 0.0.0.0:8443 --auth users.toml --tls-cert lab.crt --tls-key lab.key")]
    Serve {
        #[command(flatten)]
        db: args::DbArg,
        #[command(flatten)]
        args: serve::ServeArgs,
    },
    /// Serve the simulated instruments of a configuration over their real protocols, until a signal.
    #[command(after_help = "\
Examples:
  survey sim --config examples/config/modbus-emscon.toml --time-scale 100
  survey sim --config examples/config/scpi-elcomat.toml --preset fig4 --faults 0.01")]
    Sim(sim::SimArgs),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell) on stdout.
    #[command(after_help = "\
Examples:
  survey completions bash > ~/.local/share/bash-completion/completions/survey
  survey completions zsh > ~/.zfunc/_survey        # with fpath+=(~/.zfunc) in ~/.zshrc
  survey completions fish > ~/.config/fish/completions/survey.fish")]
    Completions(docs::CompletionsArgs),
    /// Print the manual page (roff) on stdout, or write one page per command into DIR.
    #[command(after_help = "\
Examples:
  survey man > survey.1 && man ./survey.1
  survey man --out /usr/local/share/man/man1")]
    Man(docs::ManArgs),
}

impl Command {
    /// The `--db` of a command that opens the survey database.
    fn db_arg(&self) -> Option<&args::DbArg> {
        match self {
            Command::Run { db, .. }
            | Command::Resume { db, .. }
            | Command::Report { db, .. }
            | Command::Import { db, .. }
            | Command::Export { db, .. }
            | Command::Stats { db, .. }
            | Command::ModelGap { db, .. }
            | Command::Process { db, .. }
            | Command::List { db, .. }
            | Command::Show { db, .. }
            | Command::History { db, .. }
            | Command::Due { db, .. }
            | Command::Compare { db, .. }
            | Command::Push { db, .. }
            | Command::Serve { db, .. } => Some(db),
            Command::Check(_) | Command::Sim(_) | Command::Completions(_) | Command::Man(_) => None,
        }
    }
}

/// The arguments parsed, with what clap alone knows of them: whether
/// `report`'s lab store came from `SURVEY_LAB` rather than `--lab`.
fn parse() -> Result<Cli, clap::Error> {
    use clap::{CommandFactory as _, FromArgMatches as _};
    let matches = Cli::command().try_get_matches()?;
    let mut cli = Cli::from_arg_matches(&matches)?;
    if let Command::Report { args, .. } = &mut cli.command {
        let source = matches.subcommand_matches("report").and_then(|m| m.value_source("lab"));
        args.lab_from_env = source == Some(clap::parser::ValueSource::EnvVariable);
    }
    Ok(cli)
}

/// Parse the arguments, run the command, map the outcome to the exit status.
pub fn main() -> ExitCode {
    let cli = match parse() {
        Ok(cli) => cli,
        // Help and version go to stdout, usage errors to stderr (clap's exit
        // codes); a help whose write failed is not a silent success.
        Err(e) => {
            let code = e.exit_code();
            return match e.print() {
                Err(w) if w.kind() != std::io::ErrorKind::BrokenPipe && code == 0 => {
                    survey_bench::say!("error: the help could not be written to stdout: {w}");
                    ExitCode::from(1)
                }
                _ => ExitCode::from(u8::try_from(code).unwrap_or(2)),
            };
        }
    };
    support::init_logging(cli.verbose);
    // The command awaits its work and every write; a background task that
    // never yields cannot keep the process alive (`survey_store::runtime`).
    let outcome = survey_store::runtime::block_on_bounded(2, async {
        if std::env::var_os(WEDGE_AT_EXIT).is_some() {
            wedge_a_worker();
        }
        dispatch(cli).await
    });
    match outcome {
        Ok(Ok(())) => match support::output_lost() {
            None => ExitCode::SUCCESS,
            // The work is done (stored, written), but what it printed is lost.
            Some(why) => {
                survey_bench::say!("error: the command's output could not be written to stdout: {why}");
                ExitCode::from(1)
            }
        },
        Ok(Err(e)) => {
            let status = survey_lab::error::exit_status(&e);
            match e.downcast_ref::<clap::Error>() {
                // A usage error found after parsing reads as clap's own, usage line and all.
                Some(usage) => {
                    let _ = usage.print();
                }
                // A recalibration is what `run --check` reports, not an error.
                None if status == survey_lab::error::RECALIBRATED => survey_bench::say!("{e:#}"),
                None => survey_bench::say!("error: {}", survey_store::error::said(&e)),
            }
            ExitCode::from(status)
        }
        Err(e) => {
            survey_bench::say!("error: cannot start the async runtime: {e}");
            ExitCode::from(1)
        }
    }
}

/// For tests only: with this variable set, a task that spins without ever
/// yielding occupies a worker thread, as sqlx's wedged reaper does, and the
/// process must still exit once its command is done.
const WEDGE_AT_EXIT: &str = "SURVEY_TEST_WEDGE_AT_EXIT";

fn wedge_a_worker() {
    tracing::debug!("{WEDGE_AT_EXIT} is set: a task spins on a worker thread until the process ends");
    tokio::spawn(async {
        loop {
            std::hint::spin_loop();
        }
    });
}

/// Run the command.
pub async fn dispatch(cli: Cli) -> anyhow::Result<()> {
    let db = cli.command.db_arg().cloned().unwrap_or_default().or(cli.db);
    let done = match cli.command {
        Command::Run { args, .. } => run::run(&db, args).await,
        Command::Check(args) => check::check(args).await,
        Command::Resume { args, .. } => resume::resume(&db, args).await,
        Command::Report { args, .. } => report::report(&db, *args).await,
        Command::Import { args, .. } => import::import(&db, args).await,
        Command::Export { args, .. } => export::export(&db, args).await,
        Command::Stats { args, .. } => stats::stats(&db, args).await,
        Command::ModelGap { args, .. } => model_gap::model_gap(&db, args).await,
        Command::Process { args, .. } => process::process(&db, args).await,
        Command::List { args, .. } => list::list(&db, args).await,
        Command::Show { args, .. } => list::show(&db, args).await,
        Command::History { args, .. } => history::history(&db, args).await,
        Command::Due { args, .. } => due::due(&db, args).await,
        Command::Compare { args, .. } => compare::compare(&db, args).await,
        Command::Push { args, .. } => push::push(&db, args).await,
        Command::Serve { args, .. } => serve::serve(&db, args).await,
        Command::Sim(args) => sim::sim(args).await,
        Command::Completions(args) => docs::completions(args),
        Command::Man(args) => docs::man(args),
    };
    // A lab store that went away, refused or timed out: said in words, naming it.
    done.map_err(|e| survey_store::lab::explained_at(&db, e, "reading the lab store"))
}
