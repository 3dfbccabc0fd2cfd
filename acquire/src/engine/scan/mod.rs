//! The continuous scan (`survey run --scan continuous`).
//!
//! Each run and direction of the plan is one pass: the axis is brought to a
//! run-up point before the pass's first target (far enough to reach the
//! pass's velocity), set to the velocity, and turned steadily past the last
//! target to a run-out point, while the controller captures its readout at a
//! fixed rate with its own time stamps (or, for a controller without a
//! capture, the engine polls the readout at that rate and stamps each
//! reading with the host's clock) and the tracker measures continuously
//! (emScon's continuous time mode), one point every `stream_period`, stamped
//! by the tracker's clock. Both streams are read every `fetch_interval`,
//! each read noting the host time of its answer.
//!
//! A pass is then paired ([`pass::pair`]): each stream's clock is mapped to
//! the host's ([`survey_plan::pairing::ClockMap`]); for every target, the time the readout
//! passed it ([`survey_plan::pairing::crossing_time`]); the SMR position at that time
//! ([`survey_plan::pairing::position_at`]), the tracker's stamps taken at the middle of each
//! point's integration (half a period before the stamp, which marks its end)
//! and shifted by the latency between the two instruments; the actual angle
//! around the located axis. The sample is stored at the target: readout =
//! target, actual, the fitted SMR position as its raw reading, the crossing
//! time as its timestamp. So the plan's `points` samples come out of every
//! pass, whatever the two streams' rates, their lost items (a gap longer
//! than `max_gap_periods` of a stream around a target makes the pass scanned
//! again), or the velocity's ripple (both streams are read at the same
//! moment, and the position is a quadratic fit in time).
//!
//! The latency ([`survey_plan::pairing::latency`]) is measured, not
//! assumed, before the first run: four short calibration passes
//! ([`survey_plan::calibration_passes`]) turn over the first 60
//! deg of the plan's range forward and back at the scan velocity (the
//! configured one, the positioner's maximum), then at a second velocity
//! (a quarter of it); paired without a latency at the same angles, the
//! difference between the two velocities' errors gives it. They are never
//! stored. Every pass of the plan then turns at the scan velocity and is
//! paired with the latency and stored as it ends. The passes come after the
//! calibration rather than reusing the first run over the arc (a few
//! seconds of motion saved) so that no pass is held in memory and a survey
//! resumes at pass granularity wherever it stopped.
//!
//! # Storage and resume
//!
//! A pass is stored whole in one transaction: its samples, its raw streams
//! and how they were paired (`scan_passes`, `scan_streams`). So a survey
//! stopped or killed during a pass has stored the passes before it, and
//! `survey resume` scans again from the first pass not stored, with the
//! latency read back from the stored passes; with none stored (stopped
//! during the calibration passes, or the first pass) it measures it again.

mod pass;

use super::{Engine, EngineError, Failed, Outcome, Progress, Reference};
use crate::record::SampleSink;
use serde::Serialize;
use survey_plan::pairing::Latency;
use survey_plan::pairing::latency::{self, PassErrors};
use survey_plan::{PassPlan, SurveyPlan, scan_order};
use survey_processing::Direction;

/// What the continuous scan did, for the survey's report.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ScanReport {
    pub passes: u32,
    /// Passes scanned again (a fault, a stream gap).
    pub rescans: u32,
    pub readouts: u64,
    pub points: u64,
    /// Whether the controller captured the readout (else it was polled).
    pub readouts_captured: Option<bool>,
    pub velocity_deg_s: f64,
    pub calibration_velocity_deg_s: f64,
}

/// The engine's continuous-scan state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanState {
    /// The latency, once known (estimated, or read back on a resume).
    pub latency: Option<Latency>,
    pub report: ScanReport,
}

impl Engine {
    /// Whether the tracker's clock keeps this computer's pace, as a
    /// continuous scan needs: its stream read for half a second with the
    /// axis at rest. A usage error when it does not (an instrument simulator
    /// under a time scale); a link or device error as met.
    pub async fn check_scan_clock(&mut self) -> Result<(), survey_drivers::DriverError> {
        pass::probe_pace(self).await
    }
}

/// Acquire `plan` (continuous) from step `from_seq` (a pass boundary).
pub(super) async fn run(
    engine: &mut Engine,
    plan: &SurveyPlan,
    from_seq: u64,
    sink: &mut dyn SampleSink,
    progress: &mut (dyn FnMut(&Progress) + Send),
) -> Result<Outcome, EngineError> {
    if !matches!(engine.reference, Reference::Tracker(_)) {
        return Err(EngineError::Plan(
            "a continuous scan needs a tracker that measures continuously: an autocollimator sees the polygon's \
             faces only at rest (use --scan step)"
                .into(),
        ));
    }
    let n = plan.targets_deg.len() as u64;
    if !from_seq.is_multiple_of(n) {
        return Err(EngineError::Plan(format!(
            "a continuous survey goes on from a pass's first step; step {from_seq} is inside a pass of {n}"
        )));
    }
    let t = engine.timing.clone();
    let (cal, scan) = t.scan.speeds(t.velocity_deg_s);
    if (cal - scan).abs() < 1e-9 || cal <= 0.0 || scan <= 0.0 {
        return Err(EngineError::Plan(format!(
            "the latency's calibration passes and the scan need two different positive velocities, got {cal} and \
             {scan} deg/s"
        )));
    }
    let all = scan_order(plan, t.velocity_deg_s, t.accel_deg_s2, &t.scan);
    if let Some((lo, hi)) = engine.travel()
        && let Some(p) = all.iter().find(|p| p.start.min(p.end) < lo || p.start.max(p.end) > hi)
    {
        return Err(EngineError::Plan(format!(
            "{} turns from {} to {} deg (with its run-up), outside the travel {lo}..{hi} deg",
            label(p),
            p.start,
            p.end
        )));
    }
    engine.scan.report.velocity_deg_s = scan;
    engine.scan.report.calibration_velocity_deg_s = cal;
    let axis = engine.axis.clone().ok_or_else(|| EngineError::Plan("the axis has not been located".into()))?;
    let (calibration, survey): (Vec<PassPlan>, Vec<PassPlan>) = all.into_iter().partition(|p| p.calibration);
    let latency = match engine.scan.latency {
        Some(l) => l,
        None => {
            let l = calibrate(engine, &calibration, &axis, sink).await?;
            tracing::info!(delta_s = l.delta_s, se_s = l.se_s, "latency between the instruments");
            engine.scan.latency = Some(l);
            l
        }
    };
    let total = plan.total_steps();
    let mut outcome = Outcome::default();
    for p in survey.iter().skip((from_seq / n) as usize) {
        if let Err(why) = engine.stop.check() {
            return Err(engine.halt(why).await);
        }
        let (raw, paired) = acquire(engine, p, &axis, latency.delta_s, sink).await?;
        let record = pass::record(p, &raw, paired, (latency.delta_s, latency.se_s));
        engine.scan.report.passes += 1;
        engine.scan.report.readouts += raw.readouts.len() as u64;
        engine.scan.report.points += raw.points.len() as u64;
        sink.record_pass(record).await.map_err(EngineError::Sink)?;
        outcome.samples_recorded += n;
        let last = p.targets.last().map_or(0, |(seq, _)| *seq);
        progress(&Progress {
            done: last + 1,
            total,
            run: p.run,
            direction: p.direction,
            instrument_time: engine.clock.now(),
        });
    }
    Ok(outcome)
}

/// How a pass is named in messages.
fn label(p: &PassPlan) -> String {
    if p.calibration {
        format!("the latency's calibration pass at {} deg/s ({})", p.speed, p.direction.as_str())
    } else {
        format!("pass {}", p.index)
    }
}

/// Scan the calibration passes and estimate the latency from them, paired
/// without one (the passes are not stored).
async fn calibrate(
    engine: &mut Engine,
    calibration: &[PassPlan],
    axis: &survey_processing::geometry::AxisFit,
    sink: &mut dyn SampleSink,
) -> Result<Latency, EngineError> {
    let mut errors = Vec::new();
    for p in calibration {
        if let Err(why) = engine.stop.check() {
            return Err(engine.halt(why).await);
        }
        let (_, paired) = acquire(engine, p, axis, 0.0, sink).await?;
        let mut by_angle = paired.errors;
        if p.direction == Direction::Reverse {
            by_angle.reverse();
        }
        errors.push((p.speed, p.direction, PassErrors { speed_deg_s: p.speed, errors: by_angle }));
    }
    let (_, scan) = engine.timing.scan.speeds(engine.timing.velocity_deg_s);
    let get = |fast: bool, d: Direction| {
        errors.iter().find(|e| ((e.0 - scan).abs() < 1e-12) == fast && e.1 == d).map(|e| &e.2)
    };
    let (f1, f2) = (get(true, Direction::Forward), get(false, Direction::Forward));
    let reverse = get(true, Direction::Reverse).zip(get(false, Direction::Reverse));
    f1.zip(f2)
        .and_then(|(f1, f2)| latency::estimate(f1, f2, reverse))
        .ok_or_else(|| EngineError::Plan("the latency could not be estimated from the calibration passes".into()))
}

/// Scan one pass and pair it with the latency `delta_s`, again after a
/// fault or a gap that leaves a target unpaired, up to the retry limit; a
/// stop request ends it.
async fn acquire(
    engine: &mut Engine,
    p: &PassPlan,
    axis: &survey_processing::geometry::AxisFit,
    delta_s: f64,
    sink: &mut dyn SampleSink,
) -> Result<(pass::RawPass, pass::Paired), EngineError> {
    let mut attempt = 0;
    loop {
        let mut stop = engine.stop.clone();
        let positioned = tokio::select! {
            biased;
            why = stop.wait() => Err(why),
            r = engine.move_to(p.start, false, sink) => Ok(r),
        };
        match positioned {
            Err(why) => return Err(engine.halt(why).await),
            Ok(r) => r?,
        }
        let mut stop = engine.stop.clone();
        let scanned = tokio::select! {
            biased;
            why = stop.wait() => Err(why),
            r = pass::acquire(engine, p) => Ok(r),
        };
        let failure = match scanned {
            Err(why) => {
                pass::abandon(engine).await;
                return Err(engine.halt(why).await);
            }
            Ok(Ok(raw)) => match pass::pair(&raw, p, axis, &engine.timing.scan, delta_s) {
                Ok(paired) => {
                    engine.scan.report.readouts_captured = Some(raw.captured);
                    return Ok((raw, paired));
                }
                Err(e) => (
                    survey_drivers::DriverError::device(
                        engine.reference.name(),
                        0,
                        format!("{} could not be paired: {e}", label(p)),
                    ),
                    Failed::Reference,
                ),
            },
            Ok(Err(failure)) => failure,
        };
        pass::abandon(engine).await;
        engine.scan.report.rescans += 1;
        attempt += 1;
        let (error, failed) = failure;
        engine.survive(error, failed, attempt, &format!("scan {}", label(p)), sink).await?;
    }
}
