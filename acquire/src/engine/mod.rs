//! The survey engine: locate the axis, then step it forward and back over the
//! runs, reading the positioner and the reference instrument at every target.
//!
//! Every instrument call is bounded by [`with_timeout`]; every failure is
//! classified by [`ErrorKind`], logged, recorded as an event, and handled:
//! link faults and device faults are retried (a positioner fault is cleared,
//! a broken tracker beam is re-acquired) up to `Timing::max_retries` times, bad
//! usage stops the survey at once. When the engine gives up, what was recorded
//! stays recorded and the survey can be resumed from its next step.
//!
//! A stop request ([`Stop`], from a signal) is raced against the moves and
//! reads of a step, never against a write to the sink: the engine drops the
//! step it was measuring, stops the axis, and returns [`EngineError::Stopped`]
//! after the sink was flushed, so the stored samples are exactly those
//! measured, each once.

use super::record::{RawReading, RecordedSample, SampleSink};
use super::settings::{ReferenceKind, SettleModel, Timing};
use super::settle::{SettleStats, TypicalStd, Wait, is_limit};
use crate::stop::{Stop, Stopped};
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::clock::with_timeout;
use survey_drivers::{
    AcReading, Autocollimator, Clock, DriverError, ErrorKind, Positioner, SmrMeasurement, Tracker, TrackerState,
};
use survey_plan::budget::{Component, Ledger};
use survey_plan::{SurveyPlan, locate_readouts, move_time};
use survey_processing::geometry::{AxisFit, GeometryError, fit_axis};
use survey_processing::smrs::SmrMount;
use survey_processing::{Direction, Sample};

/// The independent instrument that measures the actual angle.
#[derive(Debug)]
pub enum Reference {
    /// A tracking laser measuring an SMR on an arm: the axis is located first.
    Tracker(Box<dyn Tracker>),
    /// An autocollimator looking at an N-face polygon: the targets are the
    /// faces; `certificate_arcsec[k]` is face k's calibrated deviation.
    Autocollimator { instrument: Box<dyn Autocollimator>, faces: u32, certificate_arcsec: Vec<f64> },
}

impl Reference {
    pub fn name(&self) -> &str {
        match self {
            Reference::Tracker(t) => t.name(),
            Reference::Autocollimator { instrument, .. } => instrument.name(),
        }
    }
}

/// Why a survey stopped.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// An instrument failed and retries did not help (or the request was bad).
    /// Transparent: `{:#}` says the driver's error once, not twice.
    #[error(transparent)]
    Instrument(#[from] DriverError),
    /// The axis could not be located from the SMR positions.
    #[error("locating the axis failed")]
    Geometry(#[from] GeometryError),
    /// The sample store failed.
    #[error("recording failed: {0:#}")]
    Sink(anyhow::Error),
    /// The plan does not fit the reference instrument.
    #[error("{0}")]
    Plan(String),
    /// A stop was requested (a signal): the axis was stopped.
    #[error(transparent)]
    Stopped(#[from] Stopped),
    /// The survey was suspended and could not go on (the beam stayed lost
    /// past `beam_wait`, the axis met a limit or a fault it could not clear):
    /// the axis holds or was stopped, and the survey is resumable.
    #[error("{0}")]
    Suspended(String),
}

/// Where the survey is, for progress displays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    pub done: u64,
    pub total: u64,
    pub run: u32,
    pub direction: Direction,
    pub instrument_time: Duration,
}

/// Instrument faults met, by kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct FaultCounts {
    pub timeout: u32,
    pub disconnected: u32,
    pub garbled: u32,
    pub device: u32,
    pub usage: u32,
}

impl FaultCounts {
    fn add(&mut self, kind: ErrorKind) {
        let n = match kind {
            ErrorKind::Timeout => &mut self.timeout,
            ErrorKind::Disconnected => &mut self.disconnected,
            ErrorKind::Garbled => &mut self.garbled,
            ErrorKind::Device => &mut self.device,
            ErrorKind::Usage => &mut self.usage,
        };
        *n += 1;
    }

    /// Every fault counted.
    pub fn total(&self) -> u32 {
        self.timeout + self.disconnected + self.garbled + self.device + self.usage
    }

    fn since(&self, before: &FaultCounts) -> FaultCounts {
        FaultCounts {
            timeout: self.timeout - before.timeout,
            disconnected: self.disconnected - before.disconnected,
            garbled: self.garbled - before.garbled,
            device: self.device - before.device,
            usage: self.usage - before.usage,
        }
    }
}

/// What a finished (or stopped) pass of the engine did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Outcome {
    pub samples_recorded: u64,
    /// Faults met and retried successfully (recovered).
    pub faults_survived: u32,
    /// Every fault met (recovered or not), by kind.
    pub faults_met: FaultCounts,
    pub instrument_time: Duration,
}

/// The survey engine.
#[derive(Debug)]
pub struct Engine {
    clock: Arc<dyn Clock>,
    positioner: Box<dyn Positioner>,
    reference: Reference,
    timing: Timing,
    axis: Option<AxisFit>,
    /// The arm's nominal radius and tolerance, mm, to check the located axis.
    arm_check: Option<(f64, f64)>,
    /// The last commanded position, to know from which side the next target
    /// is approached.
    commanded: Option<f64>,
    faults_survived: u32,
    faults_met: FaultCounts,
    stop: Stop,
    /// The axis's travel limits, degrees: every commanded move is checked.
    travel: Option<(f64, f64)>,
    /// Where the instrument time goes ([`survey_plan::budget`]).
    ledger: Ledger,
    /// The settling the axis needs, for the bound.
    settle_model: SettleModel,
    /// The reference's integration time per sample, for the bound.
    integration: Option<Duration>,
    /// Settling observed after measured moves (adaptive mode).
    settled: SettleStats,
    /// The typical standard deviation of the tracker's measurements.
    typical_std: TypicalStd,
    /// The continuous scan's state ([`scan`]).
    scan: scan::ScanState,
    /// Drift control: the reference target re-measured every K steps.
    drift: Option<survey_plan::drift::DriftControl>,
    /// What simulated instruments in this process injected, when they are.
    injected: Option<survey_sims::faults::Injected>,
    /// The SMRs on the table (the first one locates the axis), and the
    /// least time to point at one, for the bound ([`smrs`]).
    smrs: Vec<SmrMount>,
    point_bound: Duration,
    /// The stage the polygon stands on, turned between runs ([`polygon`]).
    polygon: Option<PolygonStage>,
}

impl Engine {
    pub fn new(clock: Arc<dyn Clock>, positioner: Box<dyn Positioner>, reference: Reference, timing: Timing) -> Self {
        Self {
            clock,
            positioner,
            reference,
            timing,
            axis: None,
            arm_check: None,
            commanded: None,
            faults_survived: 0,
            faults_met: FaultCounts::default(),
            stop: Stop::never(),
            travel: None,
            ledger: Ledger::default(),
            settle_model: SettleModel::Unknown,
            integration: None,
            settled: SettleStats::default(),
            typical_std: TypicalStd::default(),
            scan: scan::ScanState::default(),
            drift: None,
            injected: None,
            smrs: vec![SmrMount::FIRST],
            point_bound: Duration::ZERO,
            polygon: None,
        }
    }

    /// The settling the axis needs and the reference's integration time per
    /// sample, for the plan's lower bound ([`survey_plan::budget`]).
    pub fn with_physics(mut self, settle: SettleModel, integration: Option<Duration>) -> Self {
        self.settle_model = settle;
        self.integration = integration;
        self
    }

    /// A continuous survey goes on with the latency its calibration passes measured.
    pub fn set_scan_latency(&mut self, latency: Option<survey_plan::pairing::Latency>) {
        self.scan.latency = latency;
    }

    /// The latency between the instruments a continuous survey measured
    /// (or was resumed with).
    pub fn scan_latency(&self) -> Option<survey_plan::pairing::Latency> {
        self.scan.latency
    }

    /// What the continuous scan did in this acquisition.
    pub fn scan_report(&self) -> &scan::ScanReport {
        &self.scan.report
    }

    /// The settling model the bound uses.
    pub fn settle_model(&self) -> &SettleModel {
        &self.settle_model
    }

    /// The reference's integration time per sample, when known.
    pub fn integration(&self) -> Option<Duration> {
        self.integration
    }

    /// The timing.
    pub fn timing(&self) -> &Timing {
        &self.timing
    }

    /// The instrument time spent so far, by component.
    pub fn spent(&self) -> survey_plan::budget::Spent {
        self.ledger.spent(self.clock.now())
    }

    /// The settling observed after measured moves.
    pub fn settle_stats(&self) -> SettleStats {
        self.settled
    }

    /// The count of faults that in-process simulated instruments inject.
    pub fn set_injected(&mut self, injected: Option<survey_sims::faults::Injected>) {
        self.injected = injected;
    }

    /// What the in-process simulated instruments injected so far (`None` on
    /// instruments this process does not simulate).
    pub fn injected(&self) -> Option<&survey_sims::faults::Injected> {
        self.injected.as_ref()
    }

    /// Re-measure the reference target every K steps ([`survey_plan::drift`]).
    pub fn set_drift_control(&mut self, drift: Option<survey_plan::drift::DriftControl>) {
        self.drift = drift;
    }

    /// Stop (between writes, see the module documentation) when `stop` fires.
    pub fn with_stop(mut self, stop: Stop) -> Self {
        self.stop = stop;
        self
    }

    /// Enforce travel limits (degrees): a plan whose targets, overrun
    /// included, or locate points leave them is refused before the first
    /// move, and every move the engine commands is checked against them.
    pub fn with_travel(mut self, travel: Option<(f64, f64)>) -> Self {
        self.travel = travel;
        self
    }

    /// The travel limits enforced, degrees.
    pub fn travel(&self) -> Option<(f64, f64)> {
        self.travel
    }

    /// [`Engine::with_travel`] on an engine in place.
    pub fn set_travel(&mut self, travel: Option<(f64, f64)>) {
        self.travel = travel;
    }

    /// The plan's moves (targets with their overruns, and the locate points
    /// when the axis is to be located) within the travel, or why not.
    fn check_plan_travel(&self, plan: &SurveyPlan) -> Result<(), EngineError> {
        let Some((lo, hi)) = self.travel else { return Ok(()) };
        let first = plan.targets_deg.first().copied().unwrap_or(0.0) - plan.overrun_deg;
        let last = plan.targets_deg.last().copied().unwrap_or(0.0) + plan.overrun_deg;
        if first < lo || last > hi {
            return Err(EngineError::Plan(format!(
                "the plan moves from {first} to {last} deg (targets and overrun), outside the travel {lo}..{hi} deg: \
                 refused before the first move"
            )));
        }
        self.check_drift_travel(lo, hi, plan.overrun_deg)?;
        if matches!(self.reference, Reference::Tracker(_)) && self.axis.is_none() {
            let locate = locate_readouts(plan, self.timing.locate_points);
            if let Some(bad) = locate.iter().find(|r| **r < lo || **r > hi) {
                return Err(EngineError::Plan(format!(
                    "locating the axis would move to {bad} deg, outside the travel {lo}..{hi} deg"
                )));
            }
        }
        Ok(())
    }

    /// The stop request the engine obeys.
    pub fn stop(&self) -> &Stop {
        &self.stop
    }

    /// [`Engine::with_stop`] on an engine in place.
    pub fn set_stop(&mut self, stop: Stop) {
        self.stop = stop;
    }

    /// Stop the axis after a stop request, and say why the survey stopped.
    async fn halt(&mut self, why: Stopped) -> EngineError {
        let clock = self.clock.clone();
        let name = self.positioner.name().to_string();
        tracing::warn!(%why, "stopping the axis");
        if let Err(e) = with_timeout(&*clock, self.timing.call_timeout, &name, "stop", self.positioner.stop()).await {
            tracing::warn!(%e, "stopping the axis failed");
        }
        // The axis stopped wherever it was: approach the next target afresh.
        self.commanded = None;
        EngineError::Stopped(why)
    }

    /// Refuse a located axis whose radius differs from the arm's `radius_mm`
    /// by more than `tolerance_mm` (the SMR is not where the arm puts it).
    pub fn with_arm_check(mut self, radius_mm: f64, tolerance_mm: f64) -> Self {
        self.arm_check = Some((radius_mm, tolerance_mm));
        self
    }

    /// Use an axis located earlier (resuming a survey).
    pub fn with_axis(mut self, axis: AxisFit) -> Self {
        self.axis = Some(axis);
        self
    }

    pub fn axis(&self) -> Option<&AxisFit> {
        self.axis.as_ref()
    }

    pub fn positioner_name(&self) -> &str {
        self.positioner.name()
    }

    pub fn reference_name(&self) -> &str {
        self.reference.name()
    }

    /// Which kind of reference measures the actual angle.
    pub fn reference_kind(&self) -> ReferenceKind {
        match self.reference {
            Reference::Tracker(_) => ReferenceKind::Tracker,
            Reference::Autocollimator { .. } => ReferenceKind::Autocollimator,
        }
    }

    pub fn positioner_mut(&mut self) -> &mut dyn Positioner {
        self.positioner.as_mut()
    }

    pub fn reference_mut(&mut self) -> &mut Reference {
        &mut self.reference
    }

    pub fn clock(&self) -> &Arc<dyn Clock> {
        &self.clock
    }

    /// Locate the rotary axis with the tracker: SMR positions at
    /// `Timing::locate_points` readouts spread over the plan's span (a full
    /// revolution or the partial range), a plane and circle fit. Does nothing
    /// for an autocollimator reference.
    pub async fn locate_axis(
        &mut self,
        plan: &SurveyPlan,
        sink: &mut dyn SampleSink,
    ) -> Result<Option<AxisFit>, EngineError> {
        if !matches!(self.reference, Reference::Tracker(_)) {
            return Ok(None);
        }
        let readouts = locate_readouts(plan, self.timing.locate_points);
        let mut points = Vec::with_capacity(readouts.len());
        self.ledger.hold(self.clock.now(), Component::Locate);
        for &target in &readouts {
            if let Err(e) = self.approach(target, Direction::Forward, plan.overrun_deg, sink).await {
                self.ledger.release(self.clock.now());
                return Err(e);
            }
            let read = self.read_pair(target, Direction::Forward, plan.overrun_deg, sink).await;
            let (readout, raw) = match read {
                Ok(r) => r,
                Err(e) => {
                    self.ledger.release(self.clock.now());
                    return Err(e);
                }
            };
            let RawReading::Smr(m) = raw else { unreachable!("tracker reference gives SMR readings") };
            points.push((readout, m));
        }
        // The way to the plan's first approach belongs to the locate too.
        let t = &self.timing;
        let start = survey_plan::start_deg(plan, t.velocity_deg_s, t.accel_deg_s2, &t.scan);
        if self.commanded.is_some_and(|c| c != start) {
            let back = self.move_to(start, false, sink).await;
            if let Err(e) = back {
                self.ledger.release(self.clock.now());
                return Err(e);
            }
        }
        self.ledger.release(self.clock.now());
        let xyz: Vec<[f64; 3]> = points.iter().map(|(_, m)| m.xyz()).collect();
        let ro: Vec<f64> = points.iter().map(|(r, _)| *r).collect();
        let fit = fit_axis(&xyz, &ro)?;
        if let Some((radius, tolerance)) = self.arm_check
            && (fit.radius_mm - radius).abs() > tolerance
        {
            return Err(EngineError::Plan(format!(
                "the SMR moves on a circle of radius {:.3} mm but the arm is {radius} mm (tolerance {tolerance} mm): \
                 is the SMR on the arm, and the arm on the turntable?",
                fit.radius_mm
            )));
        }
        tracing::info!(
            radius_mm = fit.radius_mm,
            plane_rms_mm = fit.plane_rms_mm,
            circle_rms_mm = fit.circle_rms_mm,
            "axis located from {} SMR positions",
            points.len()
        );
        sink.axis_located(&points, &fit).await.map_err(EngineError::Sink)?;
        self.axis = Some(fit.clone());
        Ok(Some(fit))
    }

    /// Acquire the plan's steps from `from_seq` on (0 for a new survey),
    /// recording each sample into `sink`. The sink is flushed at the end of
    /// every pass and before returning, also on failure.
    pub async fn run(
        &mut self,
        plan: &SurveyPlan,
        from_seq: u64,
        sink: &mut dyn SampleSink,
        progress: &mut (dyn FnMut(&Progress) + Send),
    ) -> Result<Outcome, EngineError> {
        let result = self.run_steps(plan, from_seq, sink, progress).await;
        let flushed = sink.flush().await.map_err(EngineError::Sink);
        let outcome = result?;
        flushed?;
        Ok(outcome)
    }

    async fn run_steps(
        &mut self,
        plan: &SurveyPlan,
        from_seq: u64,
        sink: &mut dyn SampleSink,
        progress: &mut (dyn FnMut(&Progress) + Send),
    ) -> Result<Outcome, EngineError> {
        if let Reference::Autocollimator { faces, .. } = &self.reference {
            check_polygon_plan(plan, *faces)?;
        } else if self.polygon.is_some() {
            return Err(EngineError::Plan(
                "a polygon's stage turns the polygon an autocollimator reads: the reference is a tracker".into(),
            ));
        }
        if plan.continuous() && self.polygon.is_some() {
            return Err(EngineError::Plan(
                "a polygon is read at its faces, a step at a time: a continuous scan has no faces (use --scan step)"
                    .into(),
            ));
        }
        self.check_plan_travel(plan)?;
        if plan.continuous() && self.drift.is_some() {
            return Err(EngineError::Plan(
                "drift control measures its reference target between the steps of a step scan; a continuous scan \
                 has none (its passes are short): remove [drift_control] or use --scan step"
                    .into(),
            ));
        }
        self.ledger.start(self.clock.now());
        let faults_before = self.faults_survived;
        let met_before = self.faults_met;
        if matches!(self.reference, Reference::Tracker(_)) && self.axis.is_none() {
            let mut stop = self.stop.clone();
            let located = tokio::select! {
                biased;
                why = stop.wait() => Err(why),
                r = self.locate_axis(plan, sink) => Ok(r),
            };
            match located {
                Ok(r) => {
                    r?;
                }
                Err(why) => return Err(self.halt(why).await),
            }
        }
        if plan.continuous() {
            let mut outcome = scan::run(self, plan, from_seq, sink, progress).await?;
            outcome.faults_survived = self.faults_survived - faults_before;
            outcome.faults_met = self.faults_met.since(&met_before);
            outcome.instrument_time = self.clock.now();
            return Ok(outcome);
        }
        let steps = plan.steps();
        let total = steps.len() as u64;
        let mut outcome = Outcome::default();
        let mut previous: Option<(u32, Direction)> = None;
        for step in steps.into_iter().skip(from_seq as usize) {
            if previous.is_some_and(|p| p != (step.run, step.direction)) {
                sink.flush().await.map_err(EngineError::Sink)?;
            }
            previous = Some((step.run, step.direction));
            if let Err(why) = self.stop.check() {
                return Err(self.halt(why).await);
            }
            self.turn_polygon_for(step.run, sink).await?;
            // The moves and reads of a step race the stop request; the write
            // of its sample below does not.
            let stop = self.stop.waiter();
            let measured = tokio::select! {
                biased;
                why = stop => Err(why),
                r = async {
                    let drift = self.drift_reference(step.seq, from_seq, plan.overrun_deg, sink).await?;
                    let pair = self.measure(step.target_deg, step.direction, plan.overrun_deg, sink).await?;
                    let others = self.read_other_smrs(step.target_deg, sink).await?;
                    Ok::<_, EngineError>((drift, pair, others))
                } => Ok(r),
            };
            let (drift, (readout, raw), others) = match measured {
                Ok(r) => r?,
                Err(why) => return Err(self.halt(why).await),
            };
            if let Some(m) = drift {
                sink.drift_measured(&m).await.map_err(EngineError::Sink)?;
            }
            let actual = self.actual_deg(step.target_deg, &raw)?;
            let sample = Sample {
                run: step.run,
                direction: step.direction,
                target_deg: step.target_deg,
                readout_deg: readout,
                actual_deg: actual,
                timestamp_s: Some(self.clock.now().as_secs_f64()),
            };
            sink.record(RecordedSample { seq: step.seq, sample, raw, others }).await.map_err(EngineError::Sink)?;
            outcome.samples_recorded += 1;
            progress(&Progress {
                done: step.seq + 1,
                total,
                run: step.run,
                direction: step.direction,
                instrument_time: self.clock.now(),
            });
        }
        // Drift control closes the pass with a last reference measurement.
        self.drift_closing(total, from_seq, plan.overrun_deg, sink).await?;
        outcome.faults_survived = self.faults_survived - faults_before;
        outcome.faults_met = self.faults_met.since(&met_before);
        outcome.instrument_time = self.clock.now();
        Ok(outcome)
    }

    /// The actual angle from a reference reading.
    fn actual_deg(&self, target_deg: f64, raw: &RawReading) -> Result<f64, EngineError> {
        match (raw, &self.reference) {
            (RawReading::Smr(m), _) => {
                let axis =
                    self.axis.as_ref().ok_or_else(|| EngineError::Plan("the axis has not been located".into()))?;
                Ok(axis.angle_deg(m.xyz(), target_deg))
            }
            (
                RawReading::Autocollimator { face, reading },
                Reference::Autocollimator { faces, certificate_arcsec, .. },
            ) => {
                // The face's place on the table: turned by the stage's faces.
                let place = (*face + self.polygon_turn()) % *faces;
                let nominal = place as f64 * 360.0 / *faces as f64;
                let nominal = nominal + ((target_deg - nominal) / 360.0).round() * 360.0;
                let cert = certificate_arcsec.get(*face as usize).copied().unwrap_or(0.0);
                Ok(nominal + (reading.x_arcsec + cert) / 3600.0)
            }
            _ => Err(EngineError::Plan("reading does not match the reference instrument".into())),
        }
    }

    /// Approach `target` and read the pair there.
    async fn measure(
        &mut self,
        target: f64,
        direction: Direction,
        overrun: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<(f64, RawReading), EngineError> {
        self.approach(target, direction, overrun, sink).await?;
        self.read_pair(target, direction, overrun, sink).await
    }

    /// Bring the axis to `target` approaching in `direction`: when the axis is
    /// on the wrong side (or at the target), go past it by the overrun first.
    async fn approach(
        &mut self,
        target: f64,
        direction: Direction,
        overrun: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<(), EngineError> {
        let wrong_side = self.commanded.is_none_or(|c| (target - c) * direction.sign() <= 0.0);
        if wrong_side {
            self.move_to(target - direction.sign() * overrun, false, sink).await?;
        }
        self.move_to(target, true, sink).await?;
        if !self.timing.dwell.is_zero() {
            self.ledger.switch(self.clock.now(), Component::Dwell);
            self.clock.sleep(self.timing.dwell).await;
        }
        Ok(())
    }

    /// Move and wait until the axis is at rest (`measured`: a sample is
    /// taken there, so it must have settled), retrying faults.
    async fn move_to(&mut self, target: f64, measured: bool, sink: &mut dyn SampleSink) -> Result<(), EngineError> {
        let mut attempt = 0;
        // Every fault the step's requests retried in place (its budget), and how many are recorded.
        let (mut survived, mut recorded) = (Vec::new(), 0);
        loop {
            let moved = self.try_move(target, measured, &mut survived).await;
            self.retried_in_place(&survived[recorded..], &format!("move to {target} deg"), sink).await?;
            recorded = survived.len();
            match moved {
                Ok(()) => {
                    self.commanded = Some(target);
                    return Ok(());
                }
                Err(e) => {
                    if is_limit(&e) {
                        return Err(self.stop_axis(e, &format!("move to {target} deg"), sink).await);
                    }
                    attempt += 1;
                    if let Err(gave_up) =
                        self.survive(e, Failed::Positioner, attempt, &format!("move to {target} deg"), sink).await
                    {
                        return Err(self.stop_axis_after(gave_up).await);
                    }
                }
            }
        }
    }

    /// One try of a move: each request retried in place (`survived` gets the
    /// faults it met), the move commanded once unless its command fails.
    async fn try_move(
        &mut self,
        target: f64,
        measured: bool,
        survived: &mut Vec<DriverError>,
    ) -> Result<(), DriverError> {
        if let Some((lo, hi)) = self.travel
            && !(lo..=hi).contains(&target)
        {
            return Err(DriverError::usage(
                self.positioner.name(),
                format!("a move to {target} deg would leave the travel {lo}..{hi} deg: not commanded"),
            ));
        }
        let clock = self.clock.clone();
        let t = &self.timing;
        let name = self.positioner.name().to_string();
        // After a start, a resume or a fault the axis may be anywhere: ask it.
        let from = match self.commanded {
            Some(c) => c,
            None => crate::settle::retried!(&*clock, t, &name, "readout", survived, self.positioner.readout())?,
        };
        self.ledger.switch(clock.now(), Component::CommandLatency);
        crate::settle::retried!(&*clock, t, &name, "move command", survived, self.positioner.move_to(target))?;
        let started = clock.now();
        self.ledger.switch(started, Component::Move);
        let expected = Duration::from_secs_f64(move_time(target - from, t.velocity_deg_s, t.accel_deg_s2));
        let wait = Wait {
            positioner: self.positioner.as_mut(),
            clock: &*clock,
            timing: t,
            ledger: &mut self.ledger,
            target,
            end: started + expected,
            deadline: started + expected + t.move_margin,
            measured,
            survived,
        };
        if let Some(settled) = wait.run().await? {
            self.settled.add(settled.as_secs_f64());
        }
        Ok(())
    }

    /// The faults a step's requests met and retried in place
    /// ([`crate::settle::retried`]): each logged, recorded as an event and
    /// counted as survived, as [`Engine::survive`] does a step's.
    async fn retried_in_place(
        &mut self,
        survived: &[DriverError],
        what: &str,
        sink: &mut dyn SampleSink,
    ) -> Result<(), EngineError> {
        let now = self.clock.now().as_secs_f64();
        for error in survived {
            self.faults_met.add(error.kind);
            self.faults_survived += 1;
            tracing::warn!(%error, what, kind = %error.kind, "instrument fault, request asked again");
            sink.event(now, "warn", &format!("{what}: {error} (asked again)")).await.map_err(EngineError::Sink)?;
        }
        Ok(())
    }

    /// Handle a failed operation: log it, record it, recover the instrument,
    /// and say whether to retry (Ok) or give up (Err).
    async fn survive(
        &mut self,
        error: DriverError,
        failed: Failed,
        attempt: u32,
        what: &str,
        sink: &mut dyn SampleSink,
    ) -> Result<(), EngineError> {
        let now = self.clock.now().as_secs_f64();
        self.faults_met.add(error.kind);
        let give_up = error.kind == ErrorKind::Usage || attempt > self.timing.max_retries;
        if give_up {
            tracing::error!(%error, attempt, what, "giving up");
            let _ = sink.event(now, "error", &format!("{what}: {error} (attempt {attempt}, giving up)")).await;
            return Err(EngineError::Instrument(error));
        }
        tracing::warn!(%error, attempt, what, kind = %error.kind, "instrument fault, retrying");
        sink.event(now, "warn", &format!("{what}: {error} (attempt {attempt}, retrying)"))
            .await
            .map_err(EngineError::Sink)?;
        self.faults_survived += 1;
        self.ledger.switch(self.clock.now(), Component::Recovery);
        self.clock.sleep(self.timing.retry_backoff).await;
        if error.kind == ErrorKind::Device
            && let Err(stuck) = self.recover_device(failed).await
        {
            // The instrument says its fault cannot be cleared from here (and
            // what to do): retrying would only meet it again.
            tracing::error!(error = %stuck, what, "the fault cannot be recovered here: giving up");
            let _ = sink.event(self.clock.now().as_secs_f64(), "error", &format!("{what}: {stuck} (giving up)")).await;
            return Err(EngineError::Instrument(stuck));
        }
        Ok(())
    }

    /// After a device fault: clear a positioner fault, re-acquire a broken
    /// beam. A positioner that refuses the fault clear as bad usage (a
    /// latched fault it has no command for) is the error returned; any other
    /// failure of the recovery is logged, and the retry meets what is left.
    async fn recover_device(&mut self, failed: Failed) -> Result<(), DriverError> {
        let clock = self.clock.clone();
        let t = self.timing.clone();
        if failed == Failed::Positioner {
            let name = self.positioner.name().to_string();
            // The axis may have stopped anywhere: approach the next target afresh.
            self.commanded = None;
            match with_timeout(&*clock, t.call_timeout, &name, "clear fault", self.positioner.clear_fault()).await {
                Err(e) if e.kind == ErrorKind::Usage => return Err(e),
                Err(e) => tracing::warn!(%e, "clearing the positioner fault failed"),
                Ok(()) => {}
            }
        }
        if let (Failed::Reference, Reference::Tracker(tracker)) = (failed, &mut self.reference) {
            let name = tracker.name().to_string();
            let state = with_timeout(&*clock, t.call_timeout, &name, "status", tracker.status()).await;
            if matches!(state, Ok(TrackerState::BeamBroken) | Ok(TrackerState::NotReady)) {
                tracing::info!("re-acquiring the SMR");
                if let Err(e) =
                    with_timeout(&*clock, t.measure_timeout * 3, &name, "re-acquire", tracker.reacquire()).await
                {
                    tracing::warn!(%e, "re-acquiring the SMR failed");
                }
            }
        }
        Ok(())
    }
}

/// Which instrument an operation failed on: decides the recovery.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Failed {
    Positioner,
    Reference,
}

/// One reading of the reference instrument.
async fn read_reference(
    clock: &dyn Clock,
    t: &Timing,
    reference: &mut Reference,
    near_deg: f64,
    turned: u32,
) -> Result<RawReading, DriverError> {
    match reference {
        Reference::Tracker(tracker) => {
            let name = tracker.name().to_string();
            let m: SmrMeasurement =
                with_timeout(clock, t.measure_timeout, &name, "measurement", tracker.measure()).await?;
            Ok(RawReading::Smr(m))
        }
        Reference::Autocollimator { instrument, faces, .. } => {
            let name = instrument.name().to_string();
            let reading: AcReading =
                with_timeout(clock, t.measure_timeout, &name, "reading", instrument.read()).await?;
            let face = polygon::face_seen(near_deg, *faces, turned);
            Ok(RawReading::Autocollimator { face, reading })
        }
    }
}

/// With a polygon reference, every target must be a face.
fn check_polygon_plan(plan: &SurveyPlan, faces: u32) -> Result<(), EngineError> {
    let pitch = 360.0 / faces as f64;
    for &t in &plan.targets_deg {
        let k = t / pitch;
        if (k - k.round()).abs() > 1e-6 {
            return Err(EngineError::Plan(format!(
                "target {t} deg is not a face of the {faces}-face polygon (faces every {pitch} deg): use --points {faces}"
            )));
        }
    }
    Ok(())
}

mod drift;
mod polygon;
mod read;
mod scan;
mod smrs;
mod suspend;

pub use polygon::PolygonStage;
pub use scan::ScanReport;

#[cfg(test)]
mod tests;
