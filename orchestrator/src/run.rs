//! `survey run`: acquire a survey on the simulated bench (the embedded
//! default) into the store, then report the ISO 230-2 statistics.

use crate::cli::{CheckArgs, Failure, ReferenceKind, ResumeArgs, RunArgs};
use crate::commands::{stats_json, stats_text};
use crate::config::SurveyConfig;
use crate::engine::{Engine, Outcome, Progress, Reference, Timing};
use crate::instruments::Instruments;
use crate::plan::SurveyPlan;
use crate::store::{NewSurvey, Store, StoreSink, SurveyStatus};
use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};
use survey_drivers::clock::with_timeout;
use survey_drivers::{Clock, SystemClock, VirtualClock};
use survey_processing::Sample;
use survey_processing::iso230::iso230_2;
use survey_processing::model::Model;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::{Preset, SimBench};

/// Everything a simulated survey was made from, stored with it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct SimulatedSetup {
    pub preset: String,
    pub model_file: Option<String>,
    pub reference: ReferenceKind,
    pub seed: u64,
    pub plan: SurveyPlan,
    pub timing: Timing,
    /// Instrument time of one run, which turns the model's drift per run into drift over time.
    pub run_period_s: f64,
}

/// Runs when neither the command line nor the configuration says: ISO 230-2's five.
pub const DEFAULT_RUNS: u32 = 5;

/// What a survey of real instruments was made from, stored with it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ConfiguredSetup {
    pub config: SurveyConfig,
    pub plan: SurveyPlan,
}

/// The stationary measurement time of each simulated reference.
fn measurement_time(reference: ReferenceKind) -> Duration {
    match reference {
        ReferenceKind::Tracker => Duration::from_secs(1),
        ReferenceKind::Autocollimator => Duration::from_millis(200),
    }
}

/// Check the arguments and build the setup, before anything is stored.
fn setup(args: &RunArgs) -> Result<(SimulatedSetup, Preset, Model), Failure> {
    let points = args.points.ok_or_else(|| Failure::usage(anyhow::anyhow!("--points N is required")))?;
    let runs = args.runs.unwrap_or(DEFAULT_RUNS);
    let preset = Preset::by_name(&args.preset)
        .ok_or_else(|| Failure::usage(anyhow::anyhow!("unknown preset '{}'", args.preset)))?;
    let model = match &args.model {
        Some(path) => Model::from_file(path).map_err(Failure::usage)?,
        None => preset.model.clone(),
    };
    let plan = match (args.reference, preset.travel) {
        (ReferenceKind::Autocollimator, Some((lo, hi))) => {
            return Err(Failure::usage(anyhow::anyhow!(
                "the autocollimator reference needs a full revolution, but preset {} travels {lo}..{hi} deg",
                preset.name
            )));
        }
        (_, None) => SurveyPlan::full_circle(points, runs, args.bidirectional),
        (_, Some((lo, hi))) => SurveyPlan::within_travel(lo, hi, points, runs, args.bidirectional),
    }
    .map_err(Failure::usage)?;
    let timing =
        Timing { velocity_deg_s: preset.velocity_deg_s, accel_deg_s2: preset.accel_deg_s2, ..Timing::default() };
    let per_target = preset.settle + timing.dwell + measurement_time(args.reference) + timing.poll_interval;
    let run_period = plan.estimate_run_duration(timing.velocity_deg_s, timing.accel_deg_s2, per_target);
    let setup = SimulatedSetup {
        preset: preset.name.to_string(),
        model_file: args.model.as_ref().map(|p| p.display().to_string()),
        reference: args.reference,
        seed: args.seed,
        plan,
        timing,
        run_period_s: run_period.as_secs_f64(),
    };
    Ok((setup, preset, model))
}

/// Build the simulated instruments of a setup on `clock`.
pub fn simulated_engine(setup: &SimulatedSetup, preset: &Preset, model: Model, clock: Arc<VirtualClock>) -> Engine {
    let dyn_clock: Arc<dyn Clock> = clock;
    let mut builder = SimBench::builder(preset, setup.seed, dyn_clock.clone())
        .model(model)
        .drift_run_period(Duration::from_secs_f64(setup.run_period_s));
    if setup.reference == ReferenceKind::Autocollimator {
        let faces = setup.plan.targets_deg.len() as u32;
        builder = builder.autocollimator(AutocollimatorConfig::seeded(faces, survey_sims::derive_seed(setup.seed, 3)));
    }
    let bench = builder.build();
    let reference = match setup.reference {
        ReferenceKind::Tracker => Reference::Tracker(Box::new(bench.tracker)),
        ReferenceKind::Autocollimator => Reference::Autocollimator {
            faces: bench.autocollimator.faces(),
            certificate_arcsec: bench.autocollimator.certificate_arcsec().to_vec(),
            instrument: Box::new(bench.autocollimator),
        },
    };
    Engine::new(dyn_clock, Box::new(bench.positioner), reference, setup.timing.clone())
}

pub async fn run(db: &Path, args: RunArgs) -> Result<(), Failure> {
    // A bad recipe is found before hours of measuring, not after.
    if let Some(path) = &args.recipe {
        survey_processing::recipe::Recipe::from_file(path).map_err(Failure::usage)?;
    }
    if let Some(path) = &args.config {
        return run_configured(db, &args, path).await;
    }
    let (setup, preset, model) = setup(&args)?;
    let plan = setup.plan.clone();
    let clock = Arc::new(VirtualClock::new());
    let mut engine = simulated_engine(&setup, &preset, model.clone(), clock.clone());

    let store = Store::open(db).await.map_err(crate::commands::classify)?;
    let instruments = serde_json::json!({
        "positioner": format!("simulated {} positioner", preset.name),
        "reference": format!("simulated {}", match setup.reference { ReferenceKind::Tracker => "tracker", ReferenceKind::Autocollimator => "autocollimator" }),
    });
    let id = store
        .create_survey(&NewSurvey {
            status: SurveyStatus::Running,
            source: "simulated".into(),
            points: Some(plan.targets_deg.len() as u32),
            runs: Some(plan.runs),
            bidirectional: plan.bidirectional,
            config_json: serde_json::to_string(&setup).expect("setup serialises"),
            model_toml: Some(model.to_toml()),
            instruments_json: instruments.to_string(),
            planned_samples: Some(plan.total_steps()),
        })
        .await
        .map_err(Failure::runtime)?;
    store.set_started(id, clock.now().as_secs_f64()).await.map_err(Failure::runtime)?;
    tracing::info!(survey = id, points = plan.targets_deg.len(), runs = plan.runs, "survey started");
    let estimate = Duration::from_secs_f64(setup.run_period_s * plan.runs as f64);
    eprintln!(
        "survey {id}: {} targets x {} runs{}, simulated {} positioner, {} reference: about {} of instrument time",
        plan.targets_deg.len(),
        plan.runs,
        if plan.bidirectional { " bidirectional" } else { "" },
        preset.name,
        instruments["reference"].as_str().unwrap_or_default().trim_start_matches("simulated "),
        human(estimate)
    );

    let sink = StoreSink::new(store.clone(), id);
    let report = drive(
        &mut engine,
        &plan,
        0,
        sink,
        clock,
        db,
        DriveOptions { json: args.json, crash_after: args.sim_crash_after },
    )
    .await?;
    finalize(&mut engine, &store, id, &plan, report, Finalize::of(&args)).await
}

/// `survey run --config FILE`: a survey of real instruments.
async fn run_configured(db: &Path, args: &RunArgs, path: &Path) -> Result<(), Failure> {
    let cfg = SurveyConfig::from_file(path).map_err(Failure::usage)?;
    let points = args.points.or(cfg.survey.points).ok_or_else(|| {
        Failure::usage(anyhow::anyhow!(
            "--points N is required (or `points` in the [survey] section of {})",
            path.display()
        ))
    })?;
    let runs = args.runs.or(cfg.survey.runs).unwrap_or(DEFAULT_RUNS);
    let bidirectional = args.bidirectional || cfg.survey.bidirectional.unwrap_or(false);
    let mut plan = match cfg.survey.travel_deg {
        Some([lo, hi]) => SurveyPlan::within_travel(lo, hi, points, runs, bidirectional),
        None => SurveyPlan::full_circle(points, runs, bidirectional),
    }
    .map_err(Failure::usage)?;
    if let Some(overrun) = cfg.survey.overrun_deg {
        plan.overrun_deg = overrun;
    }
    if let Some([lo, hi]) = cfg.survey.travel_deg {
        plan.check_travel(lo, hi).map_err(Failure::usage)?;
    }
    let clock: Arc<dyn Clock> = Arc::new(SystemClock::new());
    let setup = ConfiguredSetup { config: cfg.clone(), plan: plan.clone() };
    let mut engine = configured_engine(&cfg, clock.clone());
    let store = Store::open(db).await.map_err(crate::commands::classify)?;
    let instruments = serde_json::json!({
        "config_file": path.display().to_string(),
        "positioner": engine_names(&engine).0,
        "reference": engine_names(&engine).1,
    });
    let id = store
        .create_survey(&NewSurvey {
            status: SurveyStatus::Running,
            source: "instruments".into(),
            points: Some(plan.targets_deg.len() as u32),
            runs: Some(plan.runs),
            bidirectional: plan.bidirectional,
            config_json: serde_json::to_string(&setup).expect("setup serialises"),
            model_toml: None,
            instruments_json: instruments.to_string(),
            planned_samples: Some(plan.total_steps()),
        })
        .await
        .map_err(Failure::runtime)?;
    store.set_started(id, clock.now().as_secs_f64()).await.map_err(Failure::runtime)?;
    let per_target = engine_per_target(&cfg);
    let estimate = plan.estimate_duration(cfg.timing().velocity_deg_s, cfg.timing().accel_deg_s2, per_target);
    eprintln!(
        "survey {id}: {} targets x {} runs{}, {} against {}: about {}",
        plan.targets_deg.len(),
        plan.runs,
        if plan.bidirectional { " bidirectional" } else { "" },
        instruments["positioner"].as_str().unwrap_or_default(),
        instruments["reference"].as_str().unwrap_or_default(),
        human(estimate)
    );
    let sink = StoreSink::new(store.clone(), id);
    let report =
        drive(&mut engine, &plan, 0, sink, clock, db, DriveOptions { json: args.json, crash_after: None }).await?;
    finalize(&mut engine, &store, id, &plan, report, Finalize::of(args)).await
}

/// The engine on the configured instruments.
fn configured_engine(cfg: &SurveyConfig, clock: Arc<dyn Clock>) -> Engine {
    let mut engine = Instruments::from_config(cfg).into_engine(clock, cfg);
    if let Some(arm) = &cfg.arm {
        engine = engine.with_arm_check(arm.radius_mm, arm.radius_tolerance_mm);
    }
    engine
}

fn engine_names(engine: &Engine) -> (String, String) {
    (engine.positioner_name().to_string(), engine.reference_name().to_string())
}

/// Time spent at each target besides the move, for the duration estimate.
fn engine_per_target(cfg: &SurveyConfig) -> Duration {
    let t = cfg.timing();
    let measure =
        if cfg.reference() == ReferenceKind::Tracker { Duration::from_secs(1) } else { Duration::from_millis(200) };
    t.dwell + measure + t.poll_interval
}

/// `survey check --config FILE`.
pub async fn check(args: CheckArgs) -> Result<(), Failure> {
    let cfg = SurveyConfig::from_file(&args.config).map_err(Failure::usage)?;
    let clock = SystemClock::new();
    let lines = crate::instruments::check(&cfg, &clock).await;
    let failed = lines.iter().filter(|l| !l.ok).count();
    if args.json {
        let doc = serde_json::json!({ "ok": failed == 0, "instruments": lines });
        crate::cli::emit(&format!("{doc}\n"));
    } else {
        let mut text = String::new();
        for l in &lines {
            text += &format!("{:<15} {:<28} {:<20} {}\n", l.instrument, l.address, l.verdict, l.detail);
        }
        crate::cli::emit(&text);
    }
    if failed > 0 {
        return Err(Failure::runtime(anyhow::anyhow!(
            "{failed} of {} instruments failed the check: fix them before starting a survey",
            lines.len()
        )));
    }
    Ok(())
}

/// `survey resume`: continue an interrupted survey from its first missing step.
pub async fn resume(db: &Path, args: ResumeArgs) -> Result<(), Failure> {
    let store = crate::commands::open_existing(db).await?;
    let row = store.resolve(args.survey).await.map_err(crate::commands::classify)?;
    let id = row.id;
    match row.status {
        SurveyStatus::Interrupted | SurveyStatus::Running | SurveyStatus::Failed => {}
        SurveyStatus::Complete => {
            return Err(Failure::usage(anyhow::anyhow!("survey {id} is complete: there is nothing to resume")));
        }
        SurveyStatus::Imported => {
            return Err(Failure::usage(anyhow::anyhow!(
                "survey {id} was imported, not acquired: it cannot be resumed"
            )));
        }
    }
    let stored = row.sample_count;
    let next = store.last_seq(id).await.map_err(Failure::runtime)?.map_or(0, |s| s + 1);
    if next != stored {
        return Err(Failure::runtime(anyhow::anyhow!(
            "survey {id}: {stored} samples stored but the last step is {next}: the survey is not a dense prefix of its plan"
        )));
    }
    // Instrument time goes on from where the survey stopped (drift continues).
    let samples = store.samples(id).await.map_err(Failure::runtime)?;
    let last_time = samples.iter().filter_map(|r| r.sample.timestamp_s).fold(row.started_at_s.unwrap_or(0.0), f64::max);
    let resume_at = Duration::from_secs_f64(last_time.max(0.0));
    let (plan, mut engine, clock): (SurveyPlan, Engine, Arc<dyn Clock>) = match row.source.as_str() {
        "simulated" => {
            let setup: SimulatedSetup = serde_json::from_str(&row.config_json)
                .with_context(|| format!("survey {id}: its stored configuration cannot be read"))
                .map_err(Failure::runtime)?;
            let preset = Preset::by_name(&setup.preset)
                .ok_or_else(|| Failure::runtime(anyhow::anyhow!("survey {id}: unknown preset '{}'", setup.preset)))?;
            let model = match &row.model_toml {
                Some(text) => Model::parse(text, &format!("survey {id} model")).map_err(Failure::runtime)?,
                None => preset.model.clone(),
            };
            // The simulators draw new noise rather than replaying the first steps'.
            let mut resumed = setup.clone();
            resumed.seed = survey_sims::derive_seed(setup.seed, 0x5e5u64 + next);
            let clock = Arc::new(VirtualClock::starting_at(resume_at));
            (setup.plan, simulated_engine(&resumed, &preset, model, clock.clone()), clock)
        }
        "instruments" => {
            let setup: ConfiguredSetup = serde_json::from_str(&row.config_json)
                .with_context(|| format!("survey {id}: its stored configuration cannot be read"))
                .map_err(Failure::runtime)?;
            let clock: Arc<dyn Clock> = Arc::new(SystemClock::starting_at(resume_at));
            (setup.plan, configured_engine(&setup.config, clock.clone()), clock)
        }
        other => {
            return Err(Failure::usage(anyhow::anyhow!("survey {id} came from '{other}': it cannot be resumed")));
        }
    };
    if next >= plan.total_steps() {
        store.set_status(id, SurveyStatus::Complete, None).await.map_err(Failure::runtime)?;
        return Err(Failure::usage(anyhow::anyhow!("survey {id} already holds all {next} samples: marked complete")));
    }
    if let Some(axis) = &row.axis_json {
        let axis = serde_json::from_str(axis).context("the stored axis cannot be read").map_err(Failure::runtime)?;
        engine = engine.with_axis(axis);
    }
    store.set_status(id, SurveyStatus::Running, None).await.map_err(Failure::runtime)?;
    let message = format!("resumed at step {next} of {}", plan.total_steps());
    store.log_event(id, last_time, "info", &message).await.map_err(Failure::runtime)?;
    eprintln!("survey {id}: {message}");
    let sink = StoreSink::new(store.clone(), id);
    let report =
        drive(&mut engine, &plan, next, sink, clock, db, DriveOptions { json: args.json, crash_after: None }).await?;
    let finish = Finalize { json: args.json, recipe: None, verify: false };
    finalize(&mut engine, &store, id, &plan, report, finish).await
}

/// What happens after the acquisition.
#[derive(Debug, Clone)]
struct Finalize {
    json: bool,
    recipe: Option<std::path::PathBuf>,
    verify: bool,
}

impl Finalize {
    fn of(args: &RunArgs) -> Self {
        Self { json: args.json, recipe: args.recipe.clone(), verify: args.verify }
    }
}

/// The end of `survey run` (and `resume`), like the paper's full process:
/// statistics, then processing (the recipe replayed when given), then with
/// `--verify` the corrected accuracy measured with the table applied.
async fn finalize(
    engine: &mut Engine,
    store: &Store,
    id: i64,
    plan: &SurveyPlan,
    mut report: Report,
    f: Finalize,
) -> Result<(), Failure> {
    let options = crate::process::ProcessOptions { recipe: f.recipe.clone(), design: None, table_out: None };
    let result = match crate::process::process_survey(store, id, options).await {
        Ok(processed) => {
            report.doc["process"] = processed.json();
            report.text += "\n";
            report.text += &processed.summary();
            if f.verify {
                match verify(engine, store, id, plan, &processed, f.json).await {
                    Ok(v) => {
                        report.doc["verify"] = v.doc;
                        report.text += "\n";
                        report.text += &v.text;
                        Ok(())
                    }
                    Err(e) => Err(e),
                }
            } else {
                Ok(())
            }
        }
        Err(e) => Err(e),
    };
    report.emit(f.json);
    store.clone().close().await;
    result
}

/// How `drive` reports, and the simulated power loss of `--sim-crash-after`.
#[derive(Debug, Clone, Copy)]
struct DriveOptions {
    json: bool,
    crash_after: Option<u64>,
}

/// Acquire from `from_seq`, mark the survey, and print the summary.
async fn drive(
    engine: &mut Engine,
    plan: &SurveyPlan,
    from_seq: u64,
    mut sink: StoreSink,
    clock: Arc<dyn Clock>,
    db: &Path,
    options: DriveOptions,
) -> Result<Report, Failure> {
    let DriveOptions { json, crash_after } = options;
    let store = sink.store().clone();
    let id = sink.survey_id();
    let started = Instant::now();
    let outcome = acquire(engine, plan, from_seq, &mut sink, !json, crash_after).await;
    let real = started.elapsed();
    finish(&store, id, &outcome, clock.now()).await?;
    let outcome = outcome.map_err(Failure::runtime)?;
    drop(sink);
    summarise(&store, id, db, &outcome, real).await
}

/// Run the engine with a progress bar; Ctrl-C stops it cleanly (what was
/// measured is flushed and the survey can be resumed).
pub async fn acquire(
    engine: &mut Engine,
    plan: &SurveyPlan,
    from_seq: u64,
    sink: &mut StoreSink,
    show_progress: bool,
    crash_after: Option<u64>,
) -> anyhow::Result<Outcome> {
    let bar = ProgressBar::with_draw_target(Some(plan.total_steps()), ProgressDrawTarget::stderr());
    if !show_progress {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar.set_style(
        ProgressStyle::with_template("{bar:32} {pos}/{len} targets  {msg}  time left {eta}").expect("valid template"),
    );
    bar.set_position(from_seq);
    let mut on_progress = |p: &Progress| {
        if crash_after.is_some_and(|n| p.done >= n) {
            // A simulated power loss: no flush, no status update, no cleanup.
            std::process::abort();
        }
        bar.set_position(p.done);
        bar.set_message(format!("run {} {} · instrument time {}", p.run, p.direction, human(p.instrument_time)));
    };
    let result = tokio::select! {
        r = engine.run(plan, from_seq, sink, &mut on_progress) => r.map_err(anyhow::Error::from),
        _ = tokio::signal::ctrl_c() => Err(anyhow::anyhow!("interrupted (Ctrl-C)")),
        _ = terminated() => Err(anyhow::anyhow!("terminated (SIGTERM)")),
    };
    bar.finish_and_clear();
    if result.is_err() {
        // Keep what was measured: the engine flushes on its own paths, but an
        // interrupted future may have left samples in the buffer.
        use crate::record::SampleSink as _;
        sink.flush().await.context("saving the samples measured before the failure")?;
    }
    result
}

/// Mark the survey complete or interrupted.
async fn finish(store: &Store, id: i64, outcome: &anyhow::Result<Outcome>, now: Duration) -> Result<(), Failure> {
    let status = if outcome.is_ok() { SurveyStatus::Complete } else { SurveyStatus::Interrupted };
    if let Err(e) = outcome {
        let _ = store.log_event(id, now.as_secs_f64(), "error", &format!("{e:#}")).await;
        eprintln!(
            "survey {id} stopped: {e:#}\nwhat was measured is stored; continue with `survey resume --survey {id}`"
        );
    }
    store.set_status(id, status, Some(now.as_secs_f64())).await.map_err(Failure::runtime)?;
    Ok(())
}

async fn summarise(store: &Store, id: i64, db: &Path, outcome: &Outcome, real: Duration) -> Result<Report, Failure> {
    let samples: Vec<Sample> =
        store.samples(id).await.map_err(Failure::runtime)?.into_iter().map(|r| r.sample).collect();
    let iso = iso230_2(&samples).context("ISO 230-2 statistics").map_err(Failure::runtime)?;
    let mut doc = stats_json(id, &iso);
    doc["samples"] = samples.len().into();
    doc["instrument_time_s"] = outcome.instrument_time.as_secs_f64().into();
    doc["real_time_s"] = real.as_secs_f64().into();
    doc["faults_survived"] = outcome.faults_survived.into();
    doc["db"] = db.display().to_string().into();
    let mut text = format!(
        "survey {id}: {} samples in {} of instrument time (acquired in {:.2} s){}",
        samples.len(),
        human(outcome.instrument_time),
        real.as_secs_f64(),
        if outcome.faults_survived > 0 {
            format!(", {} faults survived", outcome.faults_survived)
        } else {
            String::new()
        }
    );
    text += "\n";
    text += &stats_text(id, &iso);
    text +=
        &format!("data: {} (survey {id}); `survey export --csv FILE --survey {id}` writes it as CSV\n", db.display());
    Ok(Report { doc, text })
}

/// What a command prints: one JSON document or text.
#[derive(Debug)]
pub struct Report {
    pub doc: serde_json::Value,
    pub text: String,
}

impl Report {
    fn emit(&self, json: bool) {
        if json {
            crate::cli::emit(&format!("{}\n", self.doc));
        } else {
            crate::cli::emit(&self.text);
        }
    }
}

/// Peak of `|error - mean error|` over every sample: the "+/-" figure of the
/// paper, as processing's prediction computes it.
fn peak_deg(samples: &[Sample]) -> f64 {
    let errors: Vec<f64> = samples.iter().map(Sample::error_deg).collect();
    survey_processing::correction::ErrorFigures::of(&errors, None).peak_deg
}

/// Peak of the systematic error: the mean error per target and direction over
/// the runs, less the overall mean (the noise averages down by sqrt(runs)).
fn systematic_peak_deg(samples: &[Sample]) -> f64 {
    let mut groups: std::collections::BTreeMap<(u64, survey_processing::Direction), (f64, usize)> = Default::default();
    for s in samples {
        let g = groups.entry((s.target_deg.to_bits(), s.direction)).or_default();
        g.0 += s.error_deg();
        g.1 += 1;
    }
    let means: Vec<f64> = groups.values().map(|(sum, n)| sum / *n as f64).collect();
    let mean = means.iter().sum::<f64>() / means.len().max(1) as f64;
    means.iter().map(|m| (m - mean).abs()).fold(0.0, f64::max)
}

/// `survey run --verify`: load the table into the positioner through the
/// driver trait, apply it in the feedback path, and measure the corrected
/// accuracy with a new survey of the same plan.
async fn verify(
    engine: &mut Engine,
    store: &Store,
    native_id: i64,
    plan: &SurveyPlan,
    processed: &crate::process::ProcessOutcome,
    json: bool,
) -> Result<Report, Failure> {
    let table = &processed.processed.built.table;
    let clock = engine.clock().clone();
    let name = engine.positioner_name().to_string();
    let timing = Timing::default();
    let p = engine.positioner_mut();
    with_timeout(&*clock, timing.call_timeout * 30, &name, "load correction table", p.load_correction_table(table))
        .await
        .map_err(Failure::runtime)?;
    with_timeout(&*clock, timing.call_timeout, &name, "enable correction", p.enable_correction(true))
        .await
        .map_err(Failure::runtime)?;
    let native_row = store.survey(native_id).await.map_err(Failure::runtime)?;
    let id = store
        .create_survey(&NewSurvey {
            status: SurveyStatus::Running,
            source: "verification".into(),
            points: native_row.points,
            runs: native_row.runs,
            bidirectional: native_row.bidirectional,
            config_json: native_row.config_json.clone(),
            model_toml: native_row.model_toml.clone(),
            instruments_json: serde_json::json!({
                "verifies_survey": native_id,
                "table": processed.files.table_csv.display().to_string(),
                "rows": table.len(),
                "directional": table.is_directional(),
            })
            .to_string(),
            planned_samples: Some(plan.total_steps()),
        })
        .await
        .map_err(Failure::runtime)?;
    eprintln!("survey {id}: verifying the correction table of survey {native_id} in the positioner's feedback path");
    let mut sink = StoreSink::new(store.clone(), id);
    let outcome = acquire(engine, plan, 0, &mut sink, !json, None).await;
    finish(store, id, &outcome, clock.now()).await?;
    outcome.map_err(Failure::runtime)?;
    let native: Vec<Sample> =
        store.samples(native_id).await.map_err(Failure::runtime)?.into_iter().map(|r| r.sample).collect();
    let corrected: Vec<Sample> =
        store.samples(id).await.map_err(Failure::runtime)?.into_iter().map(|r| r.sample).collect();
    let iso = iso230_2(&corrected).context("ISO 230-2 statistics of the verification").map_err(Failure::runtime)?;
    let (native_peak, corrected_peak) = (peak_deg(&native), peak_deg(&corrected));
    let predicted = processed.processed.prediction.corrected_peak_deg;
    let doc = serde_json::json!({
        "survey_id": id,
        "verifies_survey": native_id,
        "native_peak_deg": native_peak,
        "corrected_peak_deg": corrected_peak,
        "predicted_corrected_peak_deg": predicted,
        "improvement": native_peak / corrected_peak,
        "native_systematic_peak_deg": systematic_peak_deg(&native),
        "corrected_systematic_peak_deg": systematic_peak_deg(&corrected),
        "directional": table.is_directional(),
        "iso230_2": stats_json(id, &iso)["iso230_2"].clone(),
    });
    let text = format!(
        "verification (survey {id}): measured with the table applied in the feedback path\n  \
         native peak +/-{native_peak:.5} deg, corrected +/-{corrected_peak:.5} deg (predicted +/-{predicted:.5}), {:.1}x better\n  \
         systematic part (mean over the runs): native +/-{:.5} deg, corrected +/-{:.5} deg\n{}",
        native_peak / corrected_peak,
        systematic_peak_deg(&native),
        systematic_peak_deg(&corrected),
        stats_text(id, &iso)
    );
    Ok(Report { doc, text })
}

/// `3h 12m`, `4m 05s`, `12.3 s`.
pub fn human(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 3600 {
        format!("{}h {:02}m", s / 3600, (s % 3600) / 60)
    } else if s >= 60 {
        format!("{}m {:02}s", s / 60, s % 60)
    } else {
        format!("{:.1} s", d.as_secs_f64())
    }
}

/// Resolves when the process is asked to terminate (SIGTERM on Unix).
async fn terminated() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    }
    #[cfg(not(unix))]
    std::future::pending::<()>().await
}
