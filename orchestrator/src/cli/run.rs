//! `survey run`: acquire a survey on the simulated bench (the embedded
//! default) or on the instruments of `--config`, then the statistics, the
//! processing and, with `--verify`, the corrected accuracy.

use super::support::conclude_and_print;
use crate::acquire::ReferenceKind;
use crate::bench::{Bench, PlanOverrides, SimulatedRequest};
use crate::conclude::ConcludeOptions;
use crate::output::human;
use crate::session::{AcquireOptions, acquire};
use crate::stop::Stop;
use crate::store::Store;
use crate::verify::VerifyPlan;
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};
use survey_processing::plan::ScanMode;

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
    #[arg(long, value_name = "FILE", conflicts_with_all = ["model", "preset", "reference", "seed", "fault_rates"])]
    pub config: Option<PathBuf>,
    /// Positioner model file (TOML) for the simulated positioner, instead of the preset's.
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// Simulated positioner: one of the paper's positioners.
    #[arg(long, value_name = "NAME", default_value = "fig8", value_parser = ["fig1", "fig4", "fig8"])]
    pub preset: String,
    /// Reference instrument of the simulated bench.
    #[arg(long, value_enum, default_value_t = ReferenceArg::Tracker)]
    pub reference: ReferenceArg,
    /// Seed of every random draw of the simulated instruments.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
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
    /// Print the summary as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Process with this recipe (TOML) at the end, as the last calibration did.
    #[arg(long, value_name = "FILE")]
    pub recipe: Option<PathBuf>,
    /// After processing, load the table into the positioner, apply it in the
    /// feedback path and measure the corrected accuracy with a new survey,
    /// half a step from the calibration targets (between them, where the table
    /// interpolates).
    #[arg(long)]
    pub verify: bool,
    /// With --verify: measure at N targets evenly over the span, offset by half
    /// their own step (none may fall on a calibration target) [default: one
    /// between each pair of calibration targets].
    #[arg(long, value_name = "N", requires = "verify")]
    pub verify_points: Option<u32>,
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

pub async fn run(db: &Path, args: RunArgs) -> anyhow::Result<()> {
    // A bad recipe is found before hours of measuring, not after.
    if let Some(path) = &args.recipe {
        crate::inputs::read_recipe(path)?;
    }
    let mut bench = match &args.config {
        Some(path) => Bench::configured(
            path,
            PlanOverrides {
                points: args.points,
                runs: args.runs,
                bidirectional: args.bidirectional,
                scan: args.scan.map(Into::into),
            },
        )?,
        None => Bench::simulated(&SimulatedRequest {
            points: args.points,
            runs: args.runs,
            bidirectional: args.bidirectional,
            preset: args.preset.clone(),
            model_file: args.model.clone(),
            reference: args.reference.into(),
            seed: args.seed,
            scan: args.scan.map_or(ScanMode::Step, Into::into),
            faults: match &args.fault_rates {
                Some(spec) => Some(
                    survey_sims::faults::FaultRates::default()
                        .parse_over(spec)
                        .map_err(|e| crate::error::bad_input(format!("--fault-rates: {e}")))?,
                ),
                None => None,
            },
        })?,
    };
    // A verification that cannot be measured is refused before the survey.
    let verify = match args.verify {
        true => Some(VerifyPlan::new(&bench.plan, bench.engine.reference_kind(), args.verify_points)?),
        false => None,
    };
    if args.config.is_some() && bench.plan.continuous() {
        scan_clock_keeps_pace(&mut bench.engine).await?;
    }
    // From here on a signal stops the survey cleanly instead of killing the process.
    let stop = Stop::on_signals();
    bench.engine.set_stop(stop.clone());
    let store = match args.sim_db_max_pages {
        Some(n) => Store::open_limited(db, n).await?,
        None => Store::open(db).await?,
    };
    let (id, lock) = store.create_acquired_survey(&bench.new_survey()).await?;
    store.set_started(id, bench.clock.now().as_secs_f64()).await?;
    let plan = bench.plan.clone();
    tracing::info!(survey = id, points = plan.targets_deg.len(), runs = plan.runs, "survey started");
    eprintln!(
        "survey {id}: {} targets x {} runs{}, {} scan, {}: about {} of instrument time",
        plan.targets_deg.len(),
        plan.runs,
        if plan.bidirectional { " bidirectional" } else { "" },
        plan.scan.as_str(),
        bench.describe(),
        human(bench.estimate)
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
    };
    let done = conclude_and_print(store, id, &mut bench.engine, acquired, (finish, db, args.json)).await;
    drop(lock);
    done
}

/// A continuous scan on instruments: a tracker whose clock it cannot keep
/// pace with (an instrument simulator under a time scale) is bad input,
/// refused before anything is stored; a fault met while checking is left to
/// the acquisition, which survives it.
pub(super) async fn scan_clock_keeps_pace(engine: &mut crate::acquire::Engine) -> anyhow::Result<()> {
    match engine.check_scan_clock().await {
        Err(e) if e.kind == survey_drivers::ErrorKind::Usage => {
            Err(crate::error::bad_input(format!("--scan continuous: {e}")))
        }
        Err(e) => {
            tracing::warn!(%e, "the tracker's clock could not be checked before the scan");
            Ok(())
        }
        Ok(()) => Ok(()),
    }
}
