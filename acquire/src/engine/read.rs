//! The engine's read of one sample: the readout and the reference at the
//! same time, with the stability checks of adaptive settling
//! ([`crate::settle`]) and the recovery of faults.

use super::{Engine, EngineError, Failed, read_reference};
use crate::record::{RawReading, SampleSink};
use crate::settings::SettleMode;
use survey_drivers::clock::with_timeout;
use survey_plan::budget::Component;
use survey_processing::Direction;

impl Engine {
    /// Read the readout and the reference at `target` (approached in
    /// `direction`) at the same time, retrying faults. A positioner fault
    /// recovered on the way (the fault cleared: the axis may have moved) has
    /// the target approached afresh before the next reading; the reference is
    /// read at the target (an autocollimator's face is the target's). In
    /// adaptive settling the readout is read again when the reference is
    /// done, and the pair is measured again while either shows the axis
    /// moving ([`crate::settle`]).
    pub(super) async fn read_pair(
        &mut self,
        target: f64,
        direction: Direction,
        overrun: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<(f64, RawReading), EngineError> {
        let mut attempt = 0;
        let mut unsteady = 0;
        // The faults this reading's requests retried in place, and how many are recorded.
        let (mut survived, mut recorded): (Vec<survey_drivers::DriverError>, usize) = (Vec::new(), 0);
        loop {
            if self.commanded.is_none() {
                self.approach(target, direction, overrun, sink).await?;
            }
            let clock = self.clock.clone();
            let t = self.timing.clone();
            let pos_name = self.positioner.name().to_string();
            let near = target;
            let turned = self.polygon_turn();
            self.ledger.switch(clock.now(), Component::Measure);
            // Each asked again in place after a link fault (an instrument at
            // rest reads the same a moment later); a device fault, a lost beam
            // among them, is the step's to handle.
            let spent = survived.len();
            let (mut readout_faults, mut reference_faults) = (Vec::new(), Vec::new());
            let readout = async {
                let mut failed = 0u32;
                loop {
                    match with_timeout(&*clock, t.call_timeout, &pos_name, "readout", self.positioner.readout()).await {
                        Err(e) if e.kind.is_link() && crate::settle::again(&e, failed, spent + failed as usize, &t) => {
                            failed += 1;
                            readout_faults.push(e);
                            clock.sleep(t.retry_backoff).await;
                        }
                        other => break other,
                    }
                }
            };
            let reference = async {
                let mut failed = 0u32;
                loop {
                    match read_reference(&*clock, &t, &mut self.reference, near, turned).await {
                        Err(e) if e.kind.is_link() && crate::settle::again(&e, failed, spent + failed as usize, &t) => {
                            failed += 1;
                            reference_faults.push(e);
                            clock.sleep(t.retry_backoff).await;
                        }
                        other => break other,
                    }
                }
            };
            let (readout, reference) = tokio::join!(readout, reference);
            survived.extend(readout_faults.into_iter().chain(reference_faults));
            self.retried_in_place(&survived[recorded..], "reading", sink).await?;
            recorded = survived.len();
            let (error, failed) = match (readout, reference) {
                (Ok(r), Ok(raw)) if t.settle.mode == SettleMode::InPosition => return Ok((r, raw)),
                (Ok(r0), Ok(raw)) => {
                    self.ledger.switch(clock.now(), Component::CommandLatency);
                    let end =
                        with_timeout(&*clock, t.call_timeout, &pos_name, "readout", self.positioner.readout()).await;
                    match end {
                        Ok(r1) => {
                            let w = t.settle.window_deg;
                            let still = (r1 - near).abs() <= w && (r1 - r0).abs() <= w;
                            let std = match raw {
                                RawReading::Smr(m) => m.std_dev_mm.iter().copied().fold(0.0, f64::max),
                                _ => f64::NAN,
                            };
                            let steady = std.is_nan() || self.typical_std.accepts(std, t.settle.reference_std_ratio);
                            if (still && steady) || unsteady >= t.settle.max_remeasure {
                                if !(still && steady) {
                                    let message = format!(
                                        "the axis did not keep still at {near} deg over {} measurements \
                                         (readouts {r0}, {r1}; deviation {std} mm): the last one is kept",
                                        unsteady + 1
                                    );
                                    tracing::warn!(%message);
                                    let now = clock.now().as_secs_f64();
                                    sink.event(now, "warn", &message).await.map_err(EngineError::Sink)?;
                                }
                                if !std.is_nan() {
                                    self.typical_std.add(std);
                                }
                                return Ok((r1, raw));
                            }
                            unsteady += 1;
                            tracing::debug!(r0, r1, std, "not yet still: measuring again");
                            continue;
                        }
                        Err(e) => (e, Failed::Positioner),
                    }
                }
                (Err(e), _) => (e, Failed::Positioner),
                (Ok(_), Err(e)) => (e, Failed::Reference),
            };
            // A lost beam suspends the survey until it is back (not a retry).
            if failed == Failed::Reference && self.beam_lost(&error).await {
                self.suspend_for_beam(error, sink).await?;
                continue;
            }
            let error = self.name_the_face(error, failed);
            attempt += 1;
            self.survive(error, failed, attempt, "reading", sink).await?;
        }
    }
}
