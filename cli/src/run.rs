//! `survey run`: acquire a survey on the simulated bench (the embedded
//! default) or on the instruments of `--config`, then the statistics, the
//! processing and, with `--verify`, the corrected accuracy.

use super::args::{UnitsArg, whole};
use super::support::{conclude_and_print, emit};
use clap::{Args, CommandFactory as _, ValueEnum};
use std::path::{Path, PathBuf};
use survey_acquire::ReferenceKind;
use survey_acquire::stop::Stop;
use survey_bench::output::human;
use survey_bench::session::{AcquireOptions, acquire};
use survey_bench::{Bench, PlanOverrides, SimulatedRequest, default_polygon_faces};
use survey_lab::conclude::ConcludeOptions;
use survey_lab::correction;
use survey_lab::life::check::{CheckRequest, PlanSize, run_check};
use survey_lab::verify::VerifyPlan;
use survey_plan::ScanMode;
use survey_store::Store;

/// What a calibration does with a correction the positioner applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CorrectionArg {
    /// Switch it off through the driver first (recorded with the survey).
    Off,
    /// Keep it on: measure the corrected axis on purpose (no calibration).
    Keep,
}

/// What `--correction` asks of a calibration (refuse without it).
fn correction_choice(arg: Option<CorrectionArg>) -> correction::Choice {
    match arg {
        None => correction::Choice::Refuse,
        Some(CorrectionArg::Off) => correction::Choice::Off,
        Some(CorrectionArg::Keep) => correction::Choice::Keep,
    }
}

/// The reference instrument of the simulated bench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ReferenceArg {
    /// A tracking laser measuring an SMR on an arm (the axis is located first).
    Tracker,
    /// An autocollimator on a polygon: the targets are the faces (--points = faces).
    Autocollimator,
}

impl From<ReferenceArg> for ReferenceKind {
    fn from(r: ReferenceArg) -> Self {
        match r {
            ReferenceArg::Tracker => ReferenceKind::Tracker,
            ReferenceArg::Autocollimator => ReferenceKind::Autocollimator,
        }
    }
}

/// How the plan is acquired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScanArg {
    /// Stop at every target and measure at rest.
    Step,
    /// Turn steadily while the reference streams; pair samples by time.
    Continuous,
}

impl From<ScanArg> for ScanMode {
    fn from(s: ScanArg) -> Self {
        match s {
            ScanArg::Step => ScanMode::Step,
            ScanArg::Continuous => ScanMode::Continuous,
        }
    }
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Targets per revolution (or over the travel of a partial-range axis);
    /// with an autocollimator, the polygon's faces [default with --config:
    /// `points` in its [survey], else its polygon's faces; with --reference
    /// autocollimator: the simulated polygon's 24 faces].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = whole::<2, u32>)]
    pub points: Option<u32>,
    /// Measure the reverse pass too (needed for hysteresis and the reversal value).
    #[arg(long)]
    pub bidirectional: bool,
    /// Runs, at least 2 (repeatability needs two) [default: 5, as ISO 230-2 asks].
    #[arg(long, value_name = "R", allow_negative_numbers = true, value_parser = whole::<2, u32>)]
    pub runs: Option<u32>,
    /// Survey real instruments described in this configuration file (TOML).
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath, conflicts_with_all = ["model", "preset", "reference", "seed", "fault_rates"])]
    pub config: Option<PathBuf>,
    /// Positioner model file (TOML) for the simulated positioner, instead of the preset's.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub model: Option<PathBuf>,
    /// Simulated positioner: one of the paper's positioners.
    #[arg(long, value_name = "NAME", default_value = "fig8", value_parser = ["fig1", "fig4", "fig8"])]
    pub preset: String,
    /// Reference instrument of the simulated bench.
    #[arg(long, value_enum, default_value_t = ReferenceArg::Tracker)]
    pub reference: ReferenceArg,
    /// Seed of every random draw of the simulated instruments.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true, value_parser = whole::<0, u64>)]
    pub seed: u64,
    /// SMRs on the table at equal spacing, each measured at every target (the
    /// tracker pointed at each in turn), so that the tracker's own error is
    /// separated from the axis's: 2 to 12 [default: the configuration's or
    /// the model file's [smrs], else 1].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = whole::<1, u32>)]
    pub smrs: Option<u32>,
    /// The polygon stands on an indexing stage that turns it by these faces
    /// relative to the table in run 1, 2, … (repeated), so that the survey
    /// measures the polygon's face errors in place instead of trusting its
    /// certificate (closure): e.g. `0,1`. The autocollimator reference of the
    /// simulated bench; with a configuration, its [polygon] turns (turned by
    /// hand).
    #[arg(long, value_name = "FACES,...", value_delimiter = ',', value_parser = whole::<0, u32>)]
    pub polygon_turns: Vec<u32>,
    /// Stop at every target (step, the default) or turn steadily while the
    /// reference streams (continuous) [default: step, or `scan` in the
    /// configuration's [survey]].
    #[arg(long, value_enum, value_name = "MODE")]
    pub scan: Option<ScanArg>,
    /// Faults the simulated instruments inject, per kind: `kind=rate,...`
    /// (timeout, garbled, disconnect, device, move, beam; beam_hold_s=S).
    /// A stall needs a wire: `survey sim --fault-rates`.
    #[arg(long, value_name = "SPEC")]
    pub fault_rates: Option<String>,
    /// The asset (the axis measured) the survey belongs to [default: [asset] id
    /// of the configuration, or sim-PRESET on the simulated bench].
    #[arg(long, value_name = "ID", value_parser = survey_store::asset::asset_id)]
    pub asset: Option<String>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print the summary as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Process with this recipe (TOML) at the end, as the last calibration did.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub recipe: Option<PathBuf>,
    /// After processing, load the table into the positioner, apply it in the
    /// feedback path and measure the corrected accuracy with a new survey,
    /// half a step from the calibration targets (between them, where the table
    /// interpolates).
    #[arg(long)]
    pub verify: bool,
    /// When the positioner applies a correction table (read through its
    /// driver before a calibration): `off` switches it off first (recorded
    /// with the survey); `keep` measures the corrected axis on purpose (the
    /// survey is then no calibration). Without it such a calibration is
    /// refused (exit 2).
    #[arg(long, value_enum, value_name = "WHAT")]
    pub correction: Option<CorrectionArg>,
    /// With --verify: measure at N targets evenly over the span, offset by half
    /// their own step (none may fall on a calibration target) [default: one
    /// between each pair of calibration targets, or the fewest that leave no
    /// plausible alias of the table's lines hidden].
    #[arg(long, value_name = "N", requires = "verify", allow_negative_numbers = true, value_parser = whole::<2, u32>)]
    pub verify_points: Option<u32>,
    /// The recalibration loop: a short check survey (both ways, 2 runs, its
    /// targets designed to see the lines of the table in force; --points N
    /// sets them) compared with the asset's calibration in force; a full
    /// survey with that calibration's plan only when the table no longer
    /// holds or a change exceeds the asset's tolerance (an asset without a
    /// calibration gets one, with the plan of --points, --runs,
    /// --bidirectional). Exit status 0: in tolerance, or changed within a
    /// table that holds; 3: a full survey was made (recalibrated, or the
    /// asset's first calibration); 1: failure, or a line in force the check
    /// could not see; 2: bad input.
    #[arg(long, conflicts_with_all = ["verify", "sim_crash_after", "sim_signal_after", "sim_db_max_pages"])]
    pub check: bool,
    /// With --check: check only when the asset's next check is due (`survey
    /// due`: its interval's method, ILAC-G24); otherwise measure nothing and
    /// exit 0 saying when it is due. A cron line or systemd timer running
    /// `survey run --check --due` for each asset's configuration checks
    /// exactly the due assets.
    #[arg(long, requires = "check")]
    pub due: bool,
    /// Fault injection for tests: the process aborts (like a power loss)
    /// once N samples have been measured on the simulated bench.
    #[arg(long, value_name = "N", hide = true, conflicts_with = "config")]
    pub sim_crash_after: Option<u64>,
    /// For tests: the process sends itself SIGTERM once N samples have been
    /// measured (N = all of them: while it processes).
    #[arg(long, value_name = "N", hide = true)]
    pub sim_signal_after: Option<u64>,
    /// For tests: the process aborts (like a power loss) while it writes the
    /// survey's outputs: every file written to its temporary name, none
    /// renamed into place yet.
    #[arg(long, hide = true)]
    pub sim_crash_in_outputs: bool,
    /// For tests: limit the database to N pages (SQLite's max_page_count), so
    /// writes fail as on a full disk.
    #[arg(long, value_name = "N", hide = true)]
    pub sim_db_max_pages: Option<u32>,
}

/// The bench of the command line's flags, with a plan of `size`.
fn bench(args: &RunArgs, size: PlanSize) -> anyhow::Result<Bench> {
    Ok(match &args.config {
        Some(_) if !args.polygon_turns.is_empty() => {
            return Err(survey_lab::error::bad_input(
                "--polygon-turns is the simulated bench's: with a configuration, the turns are its [polygon] turns \
                 (the operator turns the polygon between runs)",
            ));
        }
        Some(path) => Bench::configured(
            path,
            PlanOverrides {
                points: size.points,
                runs: size.runs,
                bidirectional: size.bidirectional,
                scan: args.scan.map(Into::into),
                smrs: args.smrs,
            },
        )?,
        None => Bench::simulated(&SimulatedRequest {
            points: simulated_points(size.points, args.reference)?,
            runs: size.runs,
            bidirectional: size.bidirectional,
            preset: args.preset.clone(),
            model_file: args.model.clone(),
            reference: args.reference.into(),
            seed: args.seed,
            scan: args.scan.map_or(ScanMode::Step, Into::into),
            smrs: args.smrs.unwrap_or(0),
            polygon_turns: args.polygon_turns.clone(),
            faults: match &args.fault_rates {
                Some(spec) => Some(
                    survey_sims::faults::FaultRates::default()
                        .parse_over(spec)
                        .map_err(|e| survey_lab::error::bad_input(format!("--fault-rates: {e}")))?,
                ),
                None => None,
            },
        })?,
    })
}

pub async fn run(db: &Path, args: RunArgs) -> anyhow::Result<()> {
    // A bad recipe is found before hours of measuring, not after.
    if let Some(path) = &args.recipe {
        survey_bench::inputs::read_recipe(path)?;
    }
    if args.check {
        let (asset, polygon) = match &args.config {
            Some(path) => {
                let cfg = survey_store::config::SurveyConfig::from_file_to_open(path)?;
                let asset = cfg.asset.as_ref().map(|a| a.id.clone());
                (asset, cfg.reference() == ReferenceKind::Autocollimator)
            }
            None => (
                Some(survey_store::asset::simulated_asset(&args.preset)),
                args.reference == ReferenceArg::Autocollimator,
            ),
        };
        let req = CheckRequest {
            asset: args.asset.clone().or(asset).unwrap_or_else(|| survey_store::asset::UNASSIGNED.to_string()),
            polygon,
            size: PlanSize { points: args.points, runs: args.runs, bidirectional: args.bidirectional },
            json: args.json,
            recipe: args.recipe.clone(),
            units: args.units.units(),
            correction: correction_choice(args.correction),
            only_due: args.due,
            at: None,
        };
        let outcome = run_check(db, &req, &|size| bench(&args, size)).await?;
        emit(&outcome.output.render(args.json));
        return outcome.result();
    }
    let size = PlanSize { points: args.points, runs: args.runs, bidirectional: args.bidirectional };
    let mut bench = bench(&args, size)?;
    if args.verify && args.correction == Some(CorrectionArg::Keep) {
        return Err(survey_lab::error::bad_input(
            "--correction keep measures the corrected axis, which makes no table to verify: leave out --verify (or \
             use --correction off to calibrate the native axis and verify its table)",
        ));
    }
    // A verification that cannot be measured is refused before the survey.
    let verify = match args.verify {
        true => Some(VerifyPlan::new(&bench.plan, bench.engine.reference_kind(), args.verify_points)?),
        false => None,
    };
    if args.config.is_some() && bench.plan.continuous() {
        scan_clock_keeps_pace(&mut bench.engine).await?;
    }
    // A calibration measures the native axis: refused (before anything is
    // stored) when the positioner applies a correction, unless --correction says.
    let before = correction::before_calibration(&mut bench.engine, correction_choice(args.correction)).await?;
    // From here on a signal stops the survey cleanly instead of killing the process.
    let stop = Stop::on_signals();
    bench.engine.set_stop(stop.clone());
    let store = match args.sim_db_max_pages {
        Some(n) => Store::open_limited(db, n).await?,
        None => Store::open(db).await?,
    };
    let mut new = bench.new_survey();
    new.instruments["correction"] = before.as_str().into();
    new.instruments["identified"] = survey_lab::identify::read(&mut bench.engine).await;
    if let Some(asset) = &args.asset {
        new.asset = asset.clone();
    } else if new.asset == survey_store::asset::UNASSIGNED {
        survey_bench::say!(
            "note: the survey belongs to no asset (`unassigned`): give [asset] id in the configuration or --asset"
        );
    }
    let (id, lock) = store.create_acquired_survey(&new).await?;
    store.set_started(id, bench.clock.now().as_secs_f64()).await?;
    if before == correction::Before::SwitchedOff {
        let at = bench.clock.now().as_secs_f64();
        store.log_event(id, at, "info", "the positioner applied a correction: switched off before the survey").await?;
    }
    let plan = bench.plan.clone();
    tracing::info!(survey = id, points = plan.targets_deg.len(), runs = plan.runs, "survey started");
    let scale = bench.setup.time_scale();
    survey_bench::say!(
        "survey {id}: {} targets x {} runs{}, {} scan, {}: about {} of instrument time{}",
        plan.targets_deg.len(),
        plan.runs,
        if plan.bidirectional { " bidirectional" } else { "" },
        plan.scan.as_str(),
        bench.describe(),
        human(bench.estimate),
        match scale {
            1.0 => String::new(),
            x => format!(" (about {} at {x}x real time)", human(bench.estimate.div_f64(x))),
        }
    );
    let options = AcquireOptions {
        progress: !args.json,
        crash_after: args.sim_crash_after,
        signal_after: args.sim_signal_after,
        plan_progress: bench.plan_progress.clone(),
    };
    let acquired = acquire(&store, id, &mut bench.engine, &plan, 0, options.clone()).await;
    let finish = ConcludeOptions {
        recipe: args.recipe.clone(),
        verify,
        acquire: options,
        stop,
        crash_when_staged: args.sim_crash_in_outputs,
        units: args.units.units(),
    };
    let done = conclude_and_print(store, id, &mut bench.engine, acquired, (finish, db, args.json)).await;
    drop(lock);
    done
}

/// The usage line of `survey run`: the ways the count of targets is known.
pub const USAGE: &str = "survey run --points <N> [OPTIONS]
       survey run --config <FILE> [OPTIONS]
       survey run --reference autocollimator [OPTIONS]";

/// The simulated bench's targets: `points` (`--points`), else the simulated polygon's
/// faces with the autocollimator; the tracker bench has no count of its own,
/// so it is asked for as clap asks for a missing argument, usage and all.
fn simulated_points(points: Option<u32>, reference: ReferenceArg) -> anyhow::Result<u32> {
    match (points, reference) {
        (Some(n), _) => Ok(n),
        (None, ReferenceArg::Autocollimator) => Ok(default_polygon_faces()),
        (None, ReferenceArg::Tracker) => {
            let mut cli = super::Cli::command();
            cli.build();
            let run = cli.find_subcommand_mut("run").expect("survey run is a command");
            Err(run
                .error(
                    clap::error::ErrorKind::MissingRequiredArgument,
                    "--points N is required: how many targets per revolution to measure (a configuration's \
                     [survey] points gives it with --config, the polygon's faces with --reference autocollimator)",
                )
                .into())
        }
    }
}

/// A continuous scan on instruments: a tracker whose clock it cannot keep
/// pace with (an instrument simulator under a time scale) is bad input,
/// refused before anything is stored; a fault met while checking is left to
/// the acquisition, which survives it.
pub(super) async fn scan_clock_keeps_pace(engine: &mut survey_acquire::Engine) -> anyhow::Result<()> {
    match engine.check_scan_clock().await {
        Err(e) if e.kind == survey_drivers::ErrorKind::Usage => {
            Err(survey_lab::error::bad_input(format!("--scan continuous: {e}")))
        }
        Err(e) => {
            tracing::warn!(%e, "the tracker's clock could not be checked before the scan");
            Ok(())
        }
        Ok(()) => Ok(()),
    }
}
