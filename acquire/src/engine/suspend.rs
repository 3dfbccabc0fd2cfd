//! Suspending a survey, as an experiment engine (Bluesky's `RunEngine`)
//! suspends a scan when a condition fails and resumes it when the condition
//! is back, instead of failing the run.
//!
//! - **A lost beam** (the tracker's measurement failed with a device fault and
//!   the tracker says the beam is broken) suspends the survey: the axis holds
//!   where it is (nothing is commanded), the event is logged, and the tracker
//!   re-acquires the SMR (`Tracker::reacquire`: emScon's `GoLastMeasuredPoint`,
//!   then `FindReflector`) every `Timing::beam_retry` until it locks again;
//!   then the point is measured again and the survey goes on. A beam lost for
//!   longer than `Timing::beam_wait` ends the survey `interrupted` (resumable,
//!   never `failed`). The wait does not use up the retries of `max_retries`:
//!   it is bounded by time, as an operator walking through the beam is.
//! - **A positioner limit switch** stops the axis at once and ends the survey
//!   `interrupted`, the limit named; **a positioner fault** that clearing and
//!   retrying does not cure (after `max_retries`) stops the axis the same way.
//!   `survey resume` continues from the next step when the cause is removed.
//! - **An autocollimator out of range** (no reflection) is measured again, as
//!   every device fault is, up to `max_retries`; every event names the face
//!   and its nominal angle, and the survey ends `interrupted` with the face
//!   named when it stays out of range.

use super::{Engine, EngineError, Failed, Reference};
use crate::record::SampleSink;
use std::time::Duration;
use survey_drivers::clock::with_timeout;
use survey_drivers::{DriverError, ErrorKind, TrackerState};

impl Engine {
    /// Whether a failed reference reading means a lost beam: a device fault
    /// of the tracker, whose status then says the beam is broken.
    pub(super) async fn beam_lost(&mut self, error: &DriverError) -> bool {
        if error.kind != ErrorKind::Device {
            return false;
        }
        let Reference::Tracker(tracker) = &mut self.reference else { return false };
        let name = tracker.name().to_string();
        let state = with_timeout(&*self.clock, self.timing.call_timeout, &name, "status", tracker.status()).await;
        matches!(state, Ok(TrackerState::BeamBroken))
    }

    /// Suspend until the beam is back (see the module documentation): Ok to
    /// measure the point again, or the survey's end, interrupted.
    pub(super) async fn suspend_for_beam(
        &mut self,
        error: DriverError,
        sink: &mut dyn SampleSink,
    ) -> Result<(), EngineError> {
        let clock = self.clock.clone();
        let t = self.timing.clone();
        let since = clock.now();
        let at = self.commanded.map_or("the current position".to_string(), |c| format!("{c} deg"));
        self.faults_met.add(ErrorKind::Device);
        let message = format!(
            "beam lost at {at} ({error}): survey suspended, the axis holds; re-acquiring the SMR every {:?} for up to {:?}",
            t.beam_retry, t.beam_wait
        );
        tracing::warn!("{message}");
        sink.event(since.as_secs_f64(), "warn", &message).await.map_err(EngineError::Sink)?;
        let mut attempts = 0u32;
        let mut last_logged = since;
        loop {
            attempts += 1;
            let Reference::Tracker(tracker) = &mut self.reference else {
                return Err(EngineError::Plan("a beam is lost only with a tracker".into()));
            };
            let name = tracker.name().to_string();
            let found = with_timeout(&*clock, t.measure_timeout * 3, &name, "re-acquire", tracker.reacquire()).await;
            let waited = clock.now().saturating_sub(since);
            match found {
                Ok(()) => {
                    self.faults_survived += 1;
                    let message = format!(
                        "beam re-acquired after {:.1} s ({attempts} attempts): resuming, the point is measured again",
                        waited.as_secs_f64()
                    );
                    tracing::info!("{message}");
                    sink.event(clock.now().as_secs_f64(), "info", &message).await.map_err(EngineError::Sink)?;
                    return Ok(());
                }
                Err(e) => tracing::info!(%e, waited_s = waited.as_secs_f64(), "the beam is still lost"),
            }
            if waited >= t.beam_wait {
                let message = format!(
                    "the beam stayed lost for {:.1} s ({attempts} attempts to re-acquire it, beam_wait_s = {}): the \
                     survey is interrupted where it was; clear the beam and `survey resume`",
                    waited.as_secs_f64(),
                    t.beam_wait.as_secs_f64()
                );
                tracing::error!("{message}");
                let _ = sink.event(clock.now().as_secs_f64(), "error", &message).await;
                return Err(EngineError::Suspended(message));
            }
            // Say it is still waiting, about once a minute of instrument time.
            if clock.now().saturating_sub(last_logged) >= Duration::from_secs(60) {
                last_logged = clock.now();
                let message = format!(
                    "still waiting for the beam: {:.0} s of {:.0} s",
                    waited.as_secs_f64(),
                    t.beam_wait.as_secs_f64()
                );
                sink.event(last_logged.as_secs_f64(), "info", &message).await.map_err(EngineError::Sink)?;
            }
            clock.sleep(t.beam_retry.min(t.beam_wait.saturating_sub(waited)).max(Duration::from_millis(1))).await;
        }
    }

    /// An autocollimator's device fault names the face the axis is at.
    pub(super) fn name_the_face(&self, mut error: DriverError, failed: Failed) -> DriverError {
        if let (Failed::Reference, ErrorKind::Device, Reference::Autocollimator { faces, .. }) =
            (failed, error.kind, &self.reference)
        {
            let near = self.commanded.unwrap_or(0.0);
            let face = self.face_at(near, *faces);
            let place = (near / 360.0 * *faces as f64).round().rem_euclid(*faces as f64);
            let nominal = place * 360.0 / *faces as f64;
            error.message = format!("face {face} (nominal {nominal} deg) out of range: {}", error.message);
        }
        error
    }

    /// Stop the axis after `error` (a limit switch), record why, and end the
    /// survey interrupted.
    pub(super) async fn stop_axis(&mut self, error: DriverError, what: &str, sink: &mut dyn SampleSink) -> EngineError {
        self.faults_met.add(error.kind);
        let message = format!("{what}: {error}: the axis is stopped and the survey interrupted (resumable)");
        tracing::error!("{message}");
        let _ = sink.event(self.clock.now().as_secs_f64(), "error", &message).await;
        self.stop_axis_after(EngineError::Suspended(message)).await
    }

    /// Stop the axis once the engine gave up on a positioner fault; returns
    /// the reason unchanged.
    pub(super) async fn stop_axis_after(&mut self, why: EngineError) -> EngineError {
        let clock = self.clock.clone();
        let name = self.positioner.name().to_string();
        if let Err(e) = with_timeout(&*clock, self.timing.call_timeout, &name, "stop", self.positioner.stop()).await {
            tracing::warn!(%e, "stopping the axis failed");
        }
        self.commanded = None;
        why
    }
}

#[cfg(test)]
mod tests;
