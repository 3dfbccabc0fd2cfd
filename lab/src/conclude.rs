//! What follows an acquisition, like the paper's full process: the ISO 230-2
//! statistics, then the processing (a recipe replayed when given), then with
//! `--verify` the corrected accuracy measured with the table applied. The
//! survey's samples are read once, here, for all three: around the refitted
//! axis of a tracker survey ([`crate::load`] with `Axis::Refitted`, as every
//! command), which the output names (`"axis"`).
//!
//! The survey comes here `processing` (every sample stored) and is marked
//! `complete` once its outputs (the table and the files beside it, after the
//! check points that decide its doubts) are written. A processing that fails
//! at run time (a full disk) or is stopped marks it `interrupted`, and `survey
//! resume` finishes it; a kill, or check points that could not be measured,
//! leave it `processing`, which `resume` finishes too. Data that cannot make
//! a table (bad input: nothing more can be made of it) marks it complete,
//! saying so.

use crate::load::Loaded;
use crate::process::{ProcessOptions, ProcessOutcome, default_table_path, process_survey};
use crate::refit::AxisUsed;
use anyhow::Context as _;
use std::path::{Path, PathBuf};
use survey_acquire::stop::{Stop, Stopped};
use survey_acquire::{Engine, Outcome};
use survey_bench::output::{Output, Units, human, iso_json, iso_text};
use survey_bench::session::{AcquireOptions, Acquired};
use survey_plan::SurveyPlan;
use survey_processing::Sample;
use survey_processing::iso230::{Iso230, iso230_2};
use survey_store::Store;
use survey_store::survey::{SurveyRecord, SurveyStatus};

/// What to do after the acquisition.
#[derive(Debug, Clone, Default)]
pub struct ConcludeOptions {
    /// Replay this recipe in the processing.
    pub recipe: Option<PathBuf>,
    /// Verify the table in the loop, measuring this plan (see
    /// [`crate::verify::VerifyPlan`]).
    pub verify: Option<crate::verify::VerifyPlan>,
    /// How the verification's acquisition shows itself.
    pub acquire: AcquireOptions,
    /// A stop request (a signal) ends the conclusion between its phases.
    pub stop: Stop,
    /// For tests: abort once the outputs are staged, before they are renamed
    /// ([`ProcessOptions::crash_when_staged`]).
    pub crash_when_staged: bool,
    /// The unit of the errors in the text (`--units`; the JSON stays in degrees).
    pub units: Units,
}

/// The output, and whether everything after the acquisition succeeded: the
/// output is worth printing even when the processing or the verification failed.
#[derive(Debug)]
pub struct Concluded {
    /// What to print.
    pub output: Output,
    /// The processing's or the verification's failure, if any.
    pub result: anyhow::Result<()>,
}

/// Statistics, processing and verification of survey `id`, just acquired
/// with `engine` (see the module documentation). `db` names the database in
/// the output.
pub async fn conclude(
    store: &Store,
    id: i64,
    engine: &mut Engine,
    acquired: &Acquired,
    db: &Path,
    options: ConcludeOptions,
) -> anyhow::Result<Concluded> {
    // With a tracker, the figures and the table are of the axis fitted from every SMR position.
    let loaded = crate::load::load(store, Some(id.into()), crate::load::Axis::Refitted).await?;
    let samples = loaded.analysed();
    let iso = iso230_2(&samples).context("ISO 230-2 statistics")?;
    // An acquired survey always has its plan stored.
    let plan = loaded.survey.plan().cloned().with_context(|| format!("survey {id} has no stored plan"))?;
    let survey = Concluding { store, id, db, loaded: &loaded, samples: &samples, axis: loaded.axis_used(), plan };
    let mut output = statistics(&survey, engine, acquired, &iso, options.units).await;

    if let Err(why) = options.stop.check() {
        return stopped(store, id, why, output, true).await;
    }
    if let Some(native) = loaded.survey.resolves {
        // Check points finished by `survey resume`: folded into the survey
        // they resolve, which takes them in when processed.
        crate::resolving::fold(store, id, native).await?;
        output.text += &format!(
            "check points of survey {native}, stored with it: `survey process --survey {native}` (and its report) take \
             them in\n"
        );
        return Ok(Concluded { output, result: Ok(()) });
    }
    let processed = match process(&survey, engine, &options, &mut output).await {
        Ok(p) => p,
        Err(Unprocessed::Failed(e)) => return not_processed(store, id, e, output).await,
        Err(Unprocessed::ChecksNotMeasured(e)) => return Ok(Concluded { output, result: Err(e) }),
    };
    complete(&survey, engine, &processed, options.units, &mut output).await?;
    if let Err(why) = options.stop.check() {
        // The survey is complete: only the verification is not made.
        return stopped(store, id, why, output, false).await;
    }
    let result = match &options.verify {
        Some(verify_plan) => verification(&survey, engine, verify_plan, &processed, &options, &mut output).await,
        None => Ok(()),
    };
    Ok(Concluded { output, result })
}

/// The survey being concluded: where it is stored, as loaded once (see the
/// module documentation), its samples as analysed, the axis they are
/// around, and its plan.
struct Concluding<'a> {
    store: &'a Store,
    id: i64,
    /// The database, as the output names it.
    db: &'a Path,
    loaded: &'a Loaded,
    samples: &'a [Sample],
    axis: AxisUsed,
    plan: SurveyPlan,
}

/// The acquisition's output: the ISO 230-2 statistics, the faults met and
/// survived, the instrument time against the plan's bound, a continuous
/// scan's latency, the drift measured, and where the data is.
async fn statistics(
    survey: &Concluding<'_>,
    engine: &Engine,
    acquired: &Acquired,
    iso: &Iso230,
    units: Units,
) -> Output {
    let (store, id, db, axis, plan) = (survey.store, survey.id, survey.db, survey.axis, &survey.plan);
    let (record, drift) = (&survey.loaded.survey, &survey.loaded.drift);
    let samples = survey.samples;
    let outcome = &acquired.outcome;
    let mut doc = iso_json(id, iso);
    doc["status"] = record.status.as_str().into();
    doc["axis"] = axis.as_str().into();
    doc["samples"] = samples.len().into();
    doc["real_time_s"] = acquired.real.as_secs_f64().into();
    doc["faults_survived"] = outcome.faults_survived.into();
    doc["faults"] = faults_json(engine, outcome);
    doc["environment"] = match crate::environment::Environment::of(store, record).await {
        Ok(e) => e.json(),
        Err(e) => serde_json::json!({"source": "none", "error": format!("{e:#}")}),
    };
    let budget = budget(store, id, engine, plan, (outcome.instrument_time, record.setup.time_scale())).await;
    doc["instrument_time_s"] = budget.instrument_time_s.into();
    doc["time_scale"] = budget.time_scale.into();
    doc["bound_s"] = budget.bound.total().into();
    doc["time_budget"] = budget.json();
    if plan.continuous() {
        doc["scan"] = serde_json::json!({
            "mode": plan.scan.as_str(),
            "latency_s": engine.scan_latency().map(|l| l.delta_s),
            "latency_se_s": engine.scan_latency().map(|l| l.se_s),
            "bound_at_max_velocity_s": budget.at_max_velocity.map(|(_, b)| b),
            "this_acquisition": engine.scan_report(),
        });
    }
    if !drift.is_empty() {
        doc["drift"] = crate::drift::json(record, drift);
    }
    doc["db"] = db.display().to_string().into();
    let correction = correction_said(store, record, iso.a, &mut doc).await;
    let mut text = format!(
        "survey {id}: {} samples in {} of instrument time (acquired in {:.2} s){}\n",
        samples.len(),
        human(std::time::Duration::from_secs_f64(budget.instrument_time_s)),
        acquired.real.as_secs_f64(),
        if outcome.faults_survived > 0 {
            format!(", {} faults survived", outcome.faults_survived)
        } else {
            String::new()
        }
    );
    text += &budget.text();
    if let Some(l) = engine.scan_latency().filter(|_| plan.continuous()) {
        text += &format!(
            "latency between the instruments: {:.3} ms (+/- {:.3} ms), removed from every sample\n",
            l.delta_s * 1e3,
            l.se_s * 1e3
        );
    }
    text += &correction;
    text += &iso_text(id, iso, units);
    text += axis.text();
    text += "\n";
    text +=
        &format!("data: {} (survey {id}); `survey export --csv FILE --survey {id}` writes it as CSV\n", db.display());
    Output { doc, text }
}

/// The correction at the positioner when the survey started, as stored
/// with it (`"correction"`; none for a survey from before it was read), and
/// with it unknown, whether the error is so far below the asset's last
/// calibration that the axis may have been corrected (`"correction_note"`):
/// the lines to print.
async fn correction_said(store: &Store, record: &SurveyRecord, a_deg: f64, doc: &mut serde_json::Value) -> String {
    let stored = record.instruments.get("correction").and_then(|v| v.as_str());
    let Some(before) = stored.and_then(crate::correction::Before::from_stored) else {
        return String::new();
    };
    doc["correction"] = before.as_str().into();
    let mut text = format!("{}\n", before.text());
    if matches!(before, crate::correction::Before::Unknown(_)) {
        match crate::correction::maybe_corrected(store, record, a_deg).await {
            Ok(Some(note)) => {
                text += &format!("note: {note}\n");
                doc["correction_note"] = note.into();
            }
            Ok(None) => {}
            Err(e) => tracing::warn!(error = %format!("{e:#}"), "the asset's last calibration could not be read"),
        }
    }
    text
}

/// What the engine met and survived (`"faults"`). `injected` is what the
/// simulators injected where they run in this process (null on other
/// instruments; a separate `survey sim` prints its own counts when it
/// stops).
fn faults_json(engine: &Engine, outcome: &Outcome) -> serde_json::Value {
    let injected = engine.injected().map(|i| {
        let by_kind: serde_json::Map<String, serde_json::Value> =
            i.by_kind().into_iter().map(|(k, n)| (k.to_string(), n.into())).collect();
        (i.total(), by_kind)
    });
    serde_json::json!({
        "injected": injected.as_ref().map(|(n, _)| *n),
        "injected_by_kind": injected.map(|(_, k)| k),
        "met": outcome.faults_met.total(),
        "recovered": outcome.faults_survived,
        "by_kind": outcome.faults_met,
    })
}

/// Why the processing made no table: it failed ([`not_processed`] marks the
/// survey), or the check points that decide its doubts could not be
/// measured (the survey stays `processing`).
enum Unprocessed {
    Failed(anyhow::Error),
    ChecksNotMeasured(anyhow::Error),
}

/// The processing (a recipe replayed when given). Lines left in doubt, and
/// a tracker that can measure between the targets: check points decide
/// them, the survey is processed again and `output` says what they decided
/// (`"resolving"`).
async fn process(
    survey: &Concluding<'_>,
    engine: &mut Engine,
    options: &ConcludeOptions,
    output: &mut Output,
) -> Result<ProcessOutcome, Unprocessed> {
    let record = &survey.loaded.survey;
    let table_out = Some(default_table_path(survey.db, survey.id));
    let mut uncertainty = crate::refit::uncertainty_inputs(record, survey.loaded.refit.as_ref(), None);
    survey.loaded.complete_reference(&mut uncertainty);
    let processing = ProcessOptions {
        recipe: options.recipe.clone(),
        design: None,
        table_out,
        make_folder: true,
        uncertainty,
        crash_when_staged: options.crash_when_staged,
        uncorrected_drift_deg: survey.loaded.uncorrected_drift_deg(),
        ..ProcessOptions::default()
    };
    // Check points already stored with it (a survey finished by `survey
    // resume` after they were measured): processed with them, none measured again.
    if !survey.loaded.checks.is_empty() {
        let points = survey.loaded.checks.len();
        let with = ProcessOptions { checks: survey.loaded.checks_corrected(&survey.loaded.checks), ..processing };
        let processed = process_survey(record, survey.samples, with).map_err(Unprocessed::Failed)?;
        let o = crate::resolving::output(points, &processed);
        output.doc["resolving"] = o.doc;
        output.text += "\n";
        output.text += &o.text;
        return Ok(processed);
    }
    // Quiet: when check points follow, what this processing would note is
    // not yet decided; the final processing says its own notes.
    let first = ProcessOptions { quiet: true, ..processing.clone() };
    let processed = process_survey(record, survey.samples, first).map_err(Unprocessed::Failed)?;
    let Some(checks) = crate::resolving::checks_plan(&survey.plan, engine.reference_kind(), &processed) else {
        crate::process::say_notes(&processed);
        return Ok(processed);
    };
    let left = &processed.processed.left;
    let measured =
        crate::resolving::measure(engine, survey.store, record, &checks, left, options.acquire.clone()).await;
    let check_samples = measured.map_err(Unprocessed::ChecksNotMeasured)?;
    let points = check_samples.len();
    let processed = process_survey(
        record,
        survey.samples,
        ProcessOptions { checks: survey.loaded.checks_corrected(&check_samples), ..processing },
    )
    .map_err(Unprocessed::Failed)?;
    let o = crate::resolving::output(points, &processed);
    output.doc["resolving"] = o.doc;
    output.text += "\n";
    output.text += &o.text;
    Ok(processed)
}

/// The survey marked complete, and its processing in the output: the
/// document (`"process"`, with the axis and any refit), the refit (also
/// recorded with the survey) and the summary.
async fn complete(
    survey: &Concluding<'_>,
    engine: &Engine,
    processed: &ProcessOutcome,
    units: Units,
    output: &mut Output,
) -> anyhow::Result<()> {
    let (store, id) = (survey.store, survey.id);
    let Output { doc, text } = output;
    store.set_status(id, SurveyStatus::Complete, None).await?;
    doc["status"] = SurveyStatus::Complete.as_str().into();
    doc["process"] = processed.json();
    doc["process"]["axis"] = survey.axis.as_str().into();
    *text += "\n";
    if let Some(r) = &survey.loaded.refit {
        doc["process"]["axis_refit"] = serde_json::to_value(r).unwrap_or_default();
        doc["process"]["reference_error"] = serde_json::to_value(&r.reference_error).unwrap_or_default();
        doc["process"]["error_motions"] = r.motions_json();
        *text += &units.text(&r.text());
        *text += &r.motions_text();
        // Recorded with the survey (`survey show` lists it); a failed write
        // loses only this line, the refit is made again from the raw readings.
        let at = engine.clock().now().as_secs_f64();
        if let Err(e) = store.log_event(id, at, "info", &r.text().trim_end().replace('\n', "; ")).await {
            tracing::warn!(error = %format!("{e:#}"), "the axis refit could not be recorded");
        }
    }
    if let Some(p) = &survey.loaded.polygon {
        p.put_in(&mut doc["process"]);
        *text += &p.text();
    }
    doc["process"]["gross_readings"] = serde_json::to_value(&survey.loaded.gross).unwrap_or_default();
    doc["process"]["drift_in_time"] = serde_json::to_value(&survey.loaded.time_drift).unwrap_or_default();
    *text += &survey.loaded.time_drift.as_ref().map(|d| d.text()).unwrap_or_default();
    for note in survey.loaded.gross.notes() {
        *text += &format!("{note}\n");
    }
    *text += &processed.text(units);
    Ok(())
}

/// With `--verify`: the corrected accuracy measured with the table applied
/// ([`crate::verify`]), added to `output`. An error when the verification
/// failed, or when it does not confirm the prediction (then also said on
/// stderr): not a result, and the survey and the table stay stored.
async fn verification(
    survey: &Concluding<'_>,
    engine: &mut Engine,
    verify_plan: &crate::verify::VerifyPlan,
    processed: &ProcessOutcome,
    options: &ConcludeOptions,
    output: &mut Output,
) -> anyhow::Result<()> {
    let id = survey.id;
    let v = crate::verify::verify(
        engine,
        survey.store,
        &survey.loaded.survey,
        survey.samples,
        verify_plan,
        processed,
        options.acquire.clone(),
        options.units,
    )
    .await?;
    let mut result = Ok(());
    if !v.confirmed() {
        survey_bench::say!(
            "warning: survey {}: the verification does not confirm the prediction: {}",
            v.id,
            v.judged.reason
        );
        result = Err(anyhow::anyhow!(
            "the verification (survey {}) does not confirm the table of survey {id}: not a result; the survey and the \
             table stay stored",
            v.id
        ));
    }
    output.doc["verify"] = v.output.doc;
    output.text += "\n";
    output.text += &v.output.text;
    result
}

/// The survey's instrument time beside its plan's bound, on the
/// instruments' clock: what this process measured times `time_scale`.
async fn budget(
    store: &Store,
    id: i64,
    engine: &Engine,
    plan: &SurveyPlan,
    (instrument_time, time_scale): (std::time::Duration, f64),
) -> survey_bench::output::Budget {
    let t = engine.timing();
    let tracker = engine.reference_kind() == survey_acquire::ReferenceKind::Tracker;
    let d = survey_plan::budget::Dynamics {
        velocity_deg_s: t.velocity_deg_s,
        accel_deg_s2: t.accel_deg_s2,
        integration_s: engine.integration().map_or(0.0, |i| i.as_secs_f64()),
        locate_points: if tracker { t.locate_points } else { 0 },
        other_smrs: engine.smrs().len().saturating_sub(1) as u32,
        point_s: engine.point_bound().as_secs_f64(),
    };
    let measured = store.survey_time(id).await.unwrap_or_else(|e| {
        tracing::warn!(error = %format!("{e:#}"), "the stored instrument time could not be read");
        survey_plan::budget::Spent::default()
    });
    let mut spent = survey_plan::budget::Spent::default();
    for (c, s) in measured.entries() {
        spent.add(c, s * time_scale);
    }
    survey_bench::output::Budget {
        instrument_time_s: instrument_time.as_secs_f64() * time_scale,
        bound: survey_plan::budget::plan_bound(plan, &d, engine.settle_model(), &t.scan),
        at_max_velocity: plan.continuous().then(|| {
            let at = survey_plan::budget::scan_bound_at_max_velocity(plan, &d, engine.settle_model(), &t.scan);
            (t.velocity_deg_s, at.total())
        }),
        spent,
        settle_observed: engine.settle_stats().summary().map(|(n, mean, max)| (n, mean * time_scale, max * time_scale)),
        settle_poll_s: t.settle.poll.as_secs_f64() * time_scale,
        scan: plan.scan.as_str(),
        time_scale,
    }
}

/// A stop request arrived after the acquisition. Before the outputs were
/// written (`mark`), the survey (all of its samples stored) is marked
/// interrupted, so `survey resume` finishes it.
async fn stopped(store: &Store, id: i64, why: Stopped, mut output: Output, mark: bool) -> anyhow::Result<Concluded> {
    if mark {
        let now = store.last_sample_time(id).await?.unwrap_or(f64::NAN);
        let message = format!("{why} while processing; every sample is stored, `survey resume` finishes it");
        store.log_event(id, now, "warn", &message).await?;
        store.set_status(id, SurveyStatus::Interrupted, None).await?;
        output.doc["status"] = SurveyStatus::Interrupted.as_str().into();
        survey_bench::say!("survey {id} {message}");
    }
    Ok(Concluded { output, result: Err(why.into()) })
}

/// The processing failed. At run time (a full disk), the survey is marked
/// interrupted: `survey resume` writes its outputs. Data that cannot make a
/// table (bad input) is as complete as it will ever be: it is marked complete.
async fn not_processed(store: &Store, id: i64, e: anyhow::Error, mut output: Output) -> anyhow::Result<Concluded> {
    let (status, message) = match crate::error::is_bad_input(&e) {
        true => (SurveyStatus::Complete, "no table can be made of these samples"),
        false => (
            SurveyStatus::Interrupted,
            "its outputs could not be written; every sample is stored, `survey resume` writes them",
        ),
    };
    let now = store.last_sample_time(id).await.ok().flatten().unwrap_or(f64::NAN);
    // On a full disk these writes may fail too: the survey then stays
    // `processing`, which `resume` finishes all the same.
    let marked = match store.log_event(id, now, "warn", &format!("{message}: {e:#}")).await {
        Ok(()) => store.set_status(id, status, None).await,
        Err(e) => Err(e),
    };
    match marked {
        Ok(()) => output.doc["status"] = status.as_str().into(),
        Err(e) => tracing::warn!(error = %format!("{e:#}"), "the survey's status could not be stored"),
    }
    if status == SurveyStatus::Interrupted {
        survey_bench::say!("survey {id}: {message}");
    }
    Ok(Concluded { output, result: Err(e) })
}
