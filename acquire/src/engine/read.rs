//! The engine's read of one sample: the readout and the reference at the
//! same time, with the stability checks of adaptive settling
//! ([`crate::settle`]) and the recovery of faults.
//!
//! A read refused or lost is asked again in place: the axis is at rest at
//! the target, so nothing is moved; the readout and the reference are read
//! again **together** (both halves, even when one of them answered), so the
//! sample's readout is always the one read with its reference measurement,
//! never one from a moment before or after it. Up to `max_retries` reads of
//! the pair in a row, within the step's budget ([`crate::settle::again`]);
//! then the fault is the step's (the target approached afresh, with
//! recovery). What is asked again in place: a link fault of either half, a
//! refusal of the readout (a Modbus exception, an SDO abort), and a refusal
//! of a tracker's measurement whose beam is not broken (emScon's
//! `ES_RS_SensorNotStable`). A lost beam suspends the survey
//! ([`super::suspend`]); an autocollimator's device fault (no reflection)
//! is the step's, its face named.

use super::{Engine, EngineError, Failed, Reference, read_reference};
use crate::record::{RawReading, SampleSink};
use crate::settings::SettleMode;
use survey_drivers::clock::with_timeout;
use survey_drivers::{DriverError, ErrorKind};
use survey_plan::budget::Component;
use survey_processing::Direction;

/// What a reading's failed request gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ReadFault {
    /// Asked again in place (the pair read again), within the bounds.
    InPlace,
    /// The step's: retried as a whole, with recovery.
    Step,
    /// The tracker's beam is broken: the survey is suspended.
    BeamLost,
}

impl Engine {
    /// What a reading's request that failed with `e` on `failed` gets (see
    /// the module documentation). A tracker's refusal asks the tracker's
    /// status once, to tell a lost beam from a refusal.
    pub(super) async fn read_fault(&mut self, e: &DriverError, failed: Failed) -> ReadFault {
        match (e.kind, failed) {
            (k, _) if k.is_link() => ReadFault::InPlace,
            (ErrorKind::Device, Failed::Positioner) => ReadFault::InPlace,
            (ErrorKind::Device, Failed::Reference) if matches!(self.reference, Reference::Tracker(_)) => {
                if self.beam_lost(e).await { ReadFault::BeamLost } else { ReadFault::InPlace }
            }
            _ => ReadFault::Step,
        }
    }

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
        // The reads of the pair that failed in a row, each asked again in place.
        let mut in_a_row = 0u32;
        // The faults this reading's requests retried in place (the step's budget).
        let mut survived: Vec<DriverError> = Vec::new();
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
            let (readout, reference) = tokio::join!(
                with_timeout(&*clock, t.call_timeout, &pos_name, "readout", self.positioner.readout()),
                read_reference(&*clock, &t, &mut self.reference, near, turned),
            );
            // The pair, and in adaptive settling the readout at its end; or what failed.
            let read = match (readout, reference) {
                (Ok(r0), Ok(raw)) if t.settle.mode == SettleMode::InPosition => Ok((r0, raw, None)),
                (Ok(r0), Ok(raw)) => {
                    self.ledger.switch(clock.now(), Component::CommandLatency);
                    let end =
                        with_timeout(&*clock, t.call_timeout, &pos_name, "readout", self.positioner.readout()).await;
                    match end {
                        Ok(r1) => Ok((r0, raw, Some(r1))),
                        Err(e) => Err(vec![(e, Failed::Positioner)]),
                    }
                }
                (readout, reference) => Err(readout
                    .err()
                    .map(|e| (e, Failed::Positioner))
                    .into_iter()
                    .chain(reference.err().map(|e| (e, Failed::Reference)))
                    .collect()),
            };
            let (error, failed, fault) = match read {
                Ok((r0, raw, None)) => return Ok((r0, raw)),
                Ok((r0, raw, Some(r1))) => {
                    in_a_row = 0;
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
                Err(faults) => {
                    let mut classes = Vec::with_capacity(faults.len());
                    for (e, f) in &faults {
                        classes.push(self.read_fault(e, *f).await);
                    }
                    let again = classes.iter().all(|c| *c == ReadFault::InPlace)
                        && faults
                            .iter()
                            .enumerate()
                            .all(|(k, (e, _))| crate::settle::again(e, in_a_row, survived.len() + k, &t));
                    if again {
                        // The pair is read again, both halves: the sample's
                        // readout is the one read with its measurement.
                        in_a_row += 1;
                        let errors: Vec<DriverError> = faults.into_iter().map(|(e, _)| e).collect();
                        for e in &errors {
                            tracing::debug!(error = %e, in_a_row, "reading the pair again in place");
                        }
                        self.retried_in_place(&errors, "reading", sink).await?;
                        survived.extend(errors);
                        self.ledger.switch(clock.now(), Component::Recovery);
                        clock.sleep(t.retry_backoff).await;
                        continue;
                    }
                    // The step's: a lost beam first, then the readout's fault;
                    // any other fault of this read is counted as met.
                    let pick = classes.iter().position(|c| *c == ReadFault::BeamLost).unwrap_or(0);
                    let mut picked = None;
                    for (k, ((e, f), c)) in faults.into_iter().zip(classes).enumerate() {
                        if k == pick {
                            picked = Some((e, f, c));
                        } else {
                            self.faults_met.add(e.kind);
                            tracing::warn!(error = %e, kind = %e.kind, "instrument fault in the same reading (the step's)");
                        }
                    }
                    picked.expect("a failed read has a fault")
                }
            };
            in_a_row = 0;
            // A lost beam suspends the survey until it is back (not a retry).
            if fault == ReadFault::BeamLost {
                self.suspend_for_beam(error, sink).await?;
                continue;
            }
            let error = self.name_the_face(error, failed);
            attempt += 1;
            self.survive(error, failed, attempt, "reading", sink).await?;
        }
    }
}
