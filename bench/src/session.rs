//! One acquisition session: the engine runs the plan (or what is left of
//! it) into the store, with a progress bar, and the survey is marked
//! `processing` (every sample stored: its outputs come next, and mark it
//! complete) or interrupted. A signal reaches the engine through its [`survey_acquire::stop::Stop`]:
//! it stops the axis between writes, the measured samples are committed, the
//! survey is marked interrupted with the reason "stopped by signal", and the
//! command ends with exit status 1. `survey run`, `survey resume` and the
//! verification of `survey run --verify` all acquire through [`acquire`].

use crate::output::human;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::time::{Duration, Instant};
use survey_acquire::{Engine, EngineError, Outcome, Progress};
use survey_plan::SurveyPlan;
use survey_sims::PlanProgress;
use survey_store::survey::SurveyStatus;
use survey_store::{Store, StoreSink};

/// How an acquisition shows itself, the simulated bench's drift clock, and
/// the simulated power loss of tests.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AcquireOptions {
    /// Draw a progress bar on stderr.
    pub progress: bool,
    /// Abort the process (like a power loss: no flush, no status update) once
    /// this many steps are done. For crash tests of the simulated bench.
    pub crash_after: Option<u64>,
    /// Send this process SIGTERM once this many steps are done (a stop
    /// request through the real signal path, at a known step). For tests.
    pub signal_after: Option<u64>,
    /// The simulated positioner's drift clock ([`Bench::plan_progress`](crate::Bench)):
    /// set to the next step before each step's moves.
    pub plan_progress: Option<PlanProgress>,
}

/// What an acquisition did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Acquired {
    /// The engine's outcome.
    pub outcome: Outcome,
    /// Real (wall-clock) time it took.
    pub real: Duration,
}

/// Acquire `plan` from step `from_seq` into survey `id` and mark the survey:
/// `processing` when the engine finished (the caller marks it complete once
/// its outputs are written), interrupted (with the reason in its events) when
/// it stopped. Samples measured before a stop are stored.
pub async fn acquire(
    store: &Store,
    id: i64,
    engine: &mut Engine,
    plan: &SurveyPlan,
    from_seq: u64,
    options: AcquireOptions,
) -> anyhow::Result<Acquired> {
    let started = Instant::now();
    let mut sink = StoreSink::new(store.clone(), id);
    let outcome = run_engine(engine, plan, from_seq, &mut sink, &options).await;
    // Where this acquisition's instrument time went, added to the survey's.
    if let Err(e) = store.add_survey_time(id, &engine.spent()).await {
        tracing::warn!(error = %survey_store::error::said(&e), "the instrument time by component could not be stored");
    }
    if options.signal_after.is_some_and(|n| n <= plan.total_steps()) {
        // The test hook raised SIGTERM: do not go on before the stop request
        // is seen, so what follows is the same on every run.
        engine.stop().clone().wait().await;
    }
    let now = engine.clock().now();
    let status = if outcome.is_ok() { SurveyStatus::Processing } else { SurveyStatus::Interrupted };
    if let Err(e) = &outcome {
        let level = if matches!(e, EngineError::Stopped(_)) { "warn" } else { "error" };
        // A full disk in words (which file, that it is full), not SQLite's codes.
        let why = survey_store::error::engine_said(e);
        let _ = store.log_event(id, now.as_secs_f64(), level, &why).await;
        let stored =
            store.sample_count(id).await.map(|n| format!("{n} samples are stored")).unwrap_or_else(|e| {
                format!("the samples stored could not be counted ({})", survey_store::error::said(&e))
            });
        crate::say!("survey {id} stopped: {why}\n{stored}; continue with `survey resume --survey {id}`");
    }
    let marked = store.set_status(id, status, Some(now.as_secs_f64())).await;
    if let Err(e) = &marked {
        // A full disk refuses the status too; the samples on disk are what
        // `resume` goes by, so the survey stays resumable.
        let why = survey_store::error::said(e);
        tracing::error!(error = %why, "the survey's status could not be stored");
        crate::say!(
            "survey {id}: its status could not be stored ({why}); `survey resume --survey {id}` works all the same"
        );
    }
    if outcome.is_ok() {
        marked?;
    }
    let outcome = outcome.map_err(|e| match e {
        EngineError::Stopped(why) => anyhow::Error::new(why),
        other => anyhow::Error::new(other),
    })?;
    Ok(Acquired { outcome, real: started.elapsed() })
}

/// The `--json` document of an acquisition that stopped before its end: the
/// survey, its status as stored, the samples stored of those planned, and why.
pub async fn stopped_doc(store: &Store, id: i64, error: &anyhow::Error) -> serde_json::Value {
    let record = store.survey(id).await.ok();
    serde_json::json!({
        "survey_id": id,
        "status": record.as_ref().map_or("interrupted", |r| r.status.as_str()),
        "samples": record.as_ref().map(|r| r.sample_count),
        "planned_samples": record.as_ref().and_then(|r| r.planned_samples),
        "reason": format!("{error:#}"),
    })
}

/// Run the engine with a progress bar. The engine flushes the sink before it
/// returns, also when it stopped or failed (a failed flush is its error).
async fn run_engine(
    engine: &mut Engine,
    plan: &SurveyPlan,
    from_seq: u64,
    sink: &mut StoreSink,
    options: &AcquireOptions,
) -> Result<Outcome, EngineError> {
    let bar = ProgressBar::with_draw_target(Some(plan.total_steps()), ProgressDrawTarget::stderr());
    if !options.progress {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar.set_style(
        ProgressStyle::with_template("{bar:32} {pos}/{len} targets  {msg}  time left {eta}").expect("valid template"),
    );
    bar.set_position(from_seq);
    let crash_after = options.crash_after;
    let mut signal_after = options.signal_after;
    let plan_progress = options.plan_progress.clone();
    if let Some(next) = &plan_progress {
        next.set_next_step(from_seq);
    }
    let stop = engine.stop().clone();
    let mut on_progress = |p: &Progress| {
        if let Some(next) = &plan_progress {
            next.set_next_step(p.done);
        }
        if crash_after.is_some_and(|n| p.done >= n) {
            // A simulated power loss: no flush, no status update, no cleanup.
            std::process::abort();
        }
        if signal_after.is_some_and(|n| p.done >= n) {
            signal_after = None;
            if let Err(e) = nix::sys::signal::raise(nix::sys::signal::Signal::SIGTERM) {
                tracing::error!(%e, "could not raise SIGTERM");
            }
            // The listener runs on a worker thread (the command runs on the
            // main one): hold this step until it has seen the signal, so the
            // stop lands after the same step on every machine.
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
            while stop.requested().is_none() && std::time::Instant::now() < deadline {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        bar.set_position(p.done);
        bar.set_message(format!("run {} {} · instrument time {}", p.run, p.direction, human(p.instrument_time)));
    };
    let result = engine.run(plan, from_seq, sink, &mut on_progress).await;
    bar.finish_and_clear();
    result
}
