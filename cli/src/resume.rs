//! `survey resume`: continue an interrupted survey from its first missing step.
//!
//! The survey's acquisition lock is taken first ([`AcquirerLock`]): a survey
//! a live process is acquiring is refused at once, naming that process; a
//! lock left by a dead one is taken over. A survey whose samples are all
//! stored but whose status is not complete (stopped, killed or out of disk
//! space while it was processed: `interrupted`, `running` or `processing`)
//! is finished: statistics and processing, its outputs written (stale
//! temporary files of a killed write removed), exit status 0.

use super::args::UnitsArg;
use super::support::{conclude_and_print, open_existing};
use clap::Args;
use std::path::Path;
use std::time::Duration;
use survey_acquire::Outcome;
use survey_acquire::stop::Stop;
use survey_bench::Bench;
use survey_bench::session::{AcquireOptions, Acquired, acquire};
use survey_lab::conclude::ConcludeOptions;
use survey_lab::error::bad_input;
use survey_store::AcquirerLock;
use survey_store::survey::{SurveySource, SurveyStatus};

#[derive(Debug, Args)]
pub struct ResumeArgs {
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print the summary as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// The survey's configuration with new transport addresses (a
    /// re-plugged adapter's device path, a new port or host); nothing else
    /// may differ from the one it started with.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub config: Option<std::path::PathBuf>,
}

/// `--config FILE` on resume: the survey's setup with the file's transport
/// addresses, and what to say of the change (to be stored with an event
/// once the instruments there are the survey's: `None` when nothing
/// changed); any other difference is refused naming the key (bad input).
/// Every serial port of the configuration is checked to be a serial line
/// before anything opens it, with or without `--config`
/// (`config::readdress`).
fn readdress(record: &mut survey_store::survey::SurveyRecord, config: Option<&Path>) -> anyhow::Result<Option<String>> {
    use survey_store::config::{SurveyConfig, readdress};
    use survey_store::survey::Setup;
    let id = record.id;
    let Setup::Configured(setup) = &mut record.setup else {
        return match config {
            Some(file) => Err(bad_input(format!(
                "--config {}: survey {id} was not acquired on configured instruments (its setup is the simulated                  bench's): resume it without --config",
                file.display()
            ))),
            None => Ok(None),
        };
    };
    if let Some(file) = config {
        let new = SurveyConfig::from_file_to_open(file)?;
        let changes = readdress::address_changes(&setup.config, &new)
            .map_err(|why| bad_input(format!("--config {}: {why}", file.display())))?;
        check_devices(&new, Some(file))?;
        if changes.is_empty() {
            return Ok(None);
        }
        setup.config = new;
        let said = changes.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ");
        // The file by its name: the survey's events are shown on the lab's pages.
        let name = file.file_name().map_or_else(|| file.display().to_string(), |n| n.to_string_lossy().into_owned());
        return Ok(Some(format!("resumed on new addresses from {name}: {said}")));
    }
    check_devices(&setup.config, None)?;
    Ok(None)
}

/// The instruments now at the survey's addresses are the ones it began on:
/// each that identified itself when the survey began ([`survey_lab::identify`])
/// must say the same now. One that says something else, twice in a row (a
/// reply garbled once is not another device), is another instrument (an
/// adapter re-plugged, a device swapped, a path that now names another
/// port): refused, bad input, before anything is stored. One that cannot
/// say now is logged and the survey goes on (its calls survive a fault or
/// not as they do every fault).
async fn same_instruments(record: &survey_store::survey::SurveyRecord, bench: &mut Bench) -> anyhow::Result<()> {
    let began = ["positioner", "reference"].map(|role| record.identified(role).map(str::to_string));
    if began.iter().all(Option::is_none) {
        return Ok(());
    }
    let mut last: Option<serde_json::Value> = None;
    for _ in 0..3 {
        let now = survey_lab::identify::read(&mut bench.engine).await;
        let differs = ["positioner", "reference"].into_iter().zip(&began).find_map(|(role, began)| {
            let (began, said) = (began.as_deref()?, now[role].as_str()?);
            (began != said).then(|| (role, began.to_string(), said.to_string()))
        });
        let Some((role, began, said)) = differs else { return Ok(()) };
        if last.as_ref().is_some_and(|l| l[role] == now[role]) {
            let name = match role {
                "positioner" => bench.engine.positioner_name().to_string(),
                _ => bench.engine.reference_name().to_string(),
            };
            return Err(bad_input(format!(
                "survey {}: the {role} at {name} identifies itself as \"{said}\", but the survey began on one that \
                 identified itself as \"{began}\": another instrument is there (an adapter re-plugged, a device \
                 swapped); nothing was stored. Connect the survey's own {role}, or give its new address with \
                 `survey resume --config FILE`",
                record.id
            )));
        }
        last = Some(now);
    }
    Ok(())
}

/// Every serial port of `config` is a serial line (checked without opening
/// it), or bad input naming the key and what the path is.
fn check_devices(config: &survey_store::config::SurveyConfig, file: Option<&Path>) -> anyhow::Result<()> {
    for (key, path) in survey_store::config::readdress::device_paths(config) {
        // Nothing there: nothing to open by mistake (the driver says it cannot connect).
        if !Path::new(&path).exists() {
            continue;
        }
        if let Err(why) = survey_store::config::readdress::serial_line(Path::new(&path)) {
            let from = match file {
                Some(f) => format!("--config {}", f.display()),
                None => "the survey's configuration".to_string(),
            };
            return Err(bad_input(format!(
                "{from}: {key} = {path}: {why}; nothing was opened (a re-plugged adapter has a new path: `survey \
                 resume --config FILE` with it)"
            )));
        }
    }
    Ok(())
}

pub async fn resume(db: &Path, args: ResumeArgs) -> anyhow::Result<()> {
    let store = open_existing(db).await?;
    let mut id = store.resolve_any(args.survey).await?.id;
    // A survey whose check points were stopped before they were folded into
    // it: they are resumed first, and it is finished with them.
    if let Some(checks) = store.list().await?.iter().find(|r| r.resolves == Some(id)).map(|r| r.id) {
        survey_bench::say!("survey {id}: its check points were stopped before they were all measured: resuming them");
        id = checks;
    }
    // One acquirer per survey: refused at once while a live process holds it.
    let lock = AcquirerLock::acquire(store.path(), id)?;
    let stop = Stop::on_signals();
    // Read under the lock: the survey may have changed while it was held.
    let mut record = store.survey(id).await?;
    match record.status {
        SurveyStatus::Interrupted | SurveyStatus::Running | SurveyStatus::Processing | SurveyStatus::Failed => {}
        SurveyStatus::Complete => {
            return Err(bad_input(format!("survey {id} is complete: there is nothing to resume")));
        }
        SurveyStatus::Imported => {
            return Err(bad_input(format!("survey {id} was imported, not acquired: it cannot be resumed")));
        }
    }
    // Check points (a survey of source `resolving`) belong to the survey
    // they resolve: its lock too, and it is finished with them.
    let native = record.resolves;
    let _native_lock = native.map(|n| AcquirerLock::acquire(store.path(), n)).transpose()?;
    let label = match native {
        Some(n) => format!("survey {n}: its check points"),
        None => format!("survey {id}"),
    };
    if let Some(previous) = &lock.took_over {
        survey_bench::say!("{label}: the last acquirer ({previous}) is gone; taking over");
    }
    let stored = record.sample_count;
    let next = store.last_seq(id).await?.map_or(0, |s| s + 1);
    if next != stored {
        return Err(anyhow::anyhow!(
            "survey {id}: {stored} samples stored but the last step is {next}: the survey is not a dense prefix of its plan"
        ));
    }
    // Instrument time goes on from where the survey stopped (drift continues).
    let last_time = store.last_sample_time(id).await?.unwrap_or(0.0).max(record.started_at_s.unwrap_or(0.0));
    let moved = readdress(&mut record, args.config.as_deref())?;
    let mut bench = Bench::resume(&record, Duration::from_secs_f64(last_time.max(0.0)), next)?;
    same_instruments(&record, &mut bench).await?;
    if let Some(message) = moved {
        store.readdress(id, &record.setup, last_time, &message).await?;
        survey_bench::say!("survey {id}: {message}");
    }
    bench.engine.set_stop(stop.clone());
    let plan = bench.plan.clone();
    if plan.continuous() {
        // The latency between the instruments, measured by the calibration
        // passes (none stored: measured again).
        bench.engine.set_scan_latency(store.scan_latency(id).await?);
        if record.source == SurveySource::Instruments && next < plan.total_steps() {
            super::run::scan_clock_keeps_pace(&mut bench.engine).await?;
        }
    }
    let options = AcquireOptions {
        progress: !args.json,
        crash_after: None,
        signal_after: None,
        plan_progress: bench.plan_progress.clone(),
    };
    let acquired = if next >= plan.total_steps() {
        // Every sample is stored (the survey stopped after its acquisition):
        // finish it, statistics and processing.
        let message = format!("all {next} samples are stored: finishing (statistics and processing)");
        store.log_event(id, last_time, "info", &message).await?;
        store.set_status(id, SurveyStatus::Processing, None).await?;
        survey_bench::say!("{label}: {message}");
        let instrument_time = Duration::from_secs_f64(last_time.max(0.0));
        Ok(Acquired { outcome: Outcome { instrument_time, ..Outcome::default() }, real: Duration::ZERO })
    } else {
        if record.source == SurveySource::Verification {
            let table = record.verification.as_ref().and_then(|v| v.correction.as_ref()).ok_or_else(|| {
                bad_input(format!("survey {id} verifies a table that was not stored with it: it cannot be resumed"))
            })?;
            survey_lab::verify::apply_correction(&mut bench.engine, table).await?;
        }
        store.set_status(id, SurveyStatus::Running, None).await?;
        let message = format!("resumed at step {next} of {}", plan.total_steps());
        store.log_event(id, last_time, "info", &message).await?;
        survey_bench::say!("{label}: {message}");
        acquire(&store, id, &mut bench.engine, &plan, next, options.clone()).await
    };
    let finish = ConcludeOptions {
        recipe: None,
        verify: None,
        acquire: options,
        stop,
        crash_when_staged: false,
        units: args.units.units(),
    };
    let done = match native {
        None => conclude_and_print(store, id, &mut bench.engine, acquired, (finish, db, args.json)).await,
        Some(n) => finish_resolved(store, (id, n), &mut bench.engine, acquired, (finish, db, args.json)).await,
    };
    drop(lock);
    done
}

/// The check points `id` of survey `native`, acquired: folded into it, then
/// the survey they resolve finished with them (statistics, its processing
/// with the check points, its outputs written, `complete`), as `survey run`
/// would have finished it had it not been stopped. What is printed is that
/// survey's: the check points' own survey no longer exists once folded.
async fn finish_resolved(
    store: survey_store::Store,
    (id, native): (i64, i64),
    engine: &mut survey_acquire::Engine,
    acquired: anyhow::Result<Acquired>,
    finish: (ConcludeOptions, &Path, bool),
) -> anyhow::Result<()> {
    let acquired = match acquired {
        Ok(a) => a,
        Err(e) => return conclude_and_print(store, id, engine, Err(e), finish).await,
    };
    let (options, db, json) = finish;
    let folded = survey_lab::conclude::conclude(&store, id, engine, &acquired, db, options.clone()).await;
    if let Err(e) = folded {
        store.close().await;
        return Err(e);
    }
    let at = store.last_sample_time(native).await?.unwrap_or(0.0);
    let message = "its check points stored with it: finishing (statistics and processing with them)";
    store.log_event(native, at, "info", message).await?;
    store.set_status(native, SurveyStatus::Processing, None).await?;
    survey_bench::say!("survey {native}: {message}");
    let instrument_time = Duration::from_secs_f64(at.max(0.0));
    let done = Acquired { outcome: Outcome { instrument_time, ..Outcome::default() }, real: Duration::ZERO };
    conclude_and_print(store, native, engine, Ok(done), (options, db, json)).await
}
