//! One acquisition session: the engine runs the plan (or what is left of
//! it) into the store, with a progress bar, stopping cleanly on Ctrl-C or
//! SIGTERM, and the survey is marked complete or interrupted. `survey run`,
//! `survey resume` and the verification of `survey run --verify` all acquire
//! through [`acquire`].

use crate::engine::{Engine, Outcome, Progress};
use crate::output::human;
use crate::plan::SurveyPlan;
use crate::record::SampleSink as _;
use crate::store::{Store, StoreSink};
use crate::survey::SurveyStatus;
use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::time::{Duration, Instant};

/// How an acquisition shows itself, and the simulated power loss of tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AcquireOptions {
    /// Draw a progress bar on stderr.
    pub progress: bool,
    /// Abort the process (like a power loss: no flush, no status update) once
    /// this many steps are done. For crash tests of the simulated bench.
    pub crash_after: Option<u64>,
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
/// complete when the engine finished, interrupted (with the reason in its
/// events) when it stopped. Samples measured before a stop are stored.
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
    let outcome = run_engine(engine, plan, from_seq, &mut sink, options).await;
    let now = engine.clock().now();
    let status = if outcome.is_ok() { SurveyStatus::Complete } else { SurveyStatus::Interrupted };
    if let Err(e) = &outcome {
        let _ = store.log_event(id, now.as_secs_f64(), "error", &format!("{e:#}")).await;
        eprintln!(
            "survey {id} stopped: {e:#}\nwhat was measured is stored; continue with `survey resume --survey {id}`"
        );
    }
    store.set_status(id, status, Some(now.as_secs_f64())).await?;
    Ok(Acquired { outcome: outcome?, real: started.elapsed() })
}

/// Run the engine with a progress bar; Ctrl-C and SIGTERM stop it cleanly
/// (what was measured is flushed and the survey can be resumed).
async fn run_engine(
    engine: &mut Engine,
    plan: &SurveyPlan,
    from_seq: u64,
    sink: &mut StoreSink,
    options: AcquireOptions,
) -> anyhow::Result<Outcome> {
    let bar = ProgressBar::with_draw_target(Some(plan.total_steps()), ProgressDrawTarget::stderr());
    if !options.progress {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar.set_style(
        ProgressStyle::with_template("{bar:32} {pos}/{len} targets  {msg}  time left {eta}").expect("valid template"),
    );
    bar.set_position(from_seq);
    let crash_after = options.crash_after;
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
        sink.flush().await.context("saving the samples measured before the failure")?;
    }
    result
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
