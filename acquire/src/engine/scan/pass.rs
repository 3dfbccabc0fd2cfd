//! One pass of a continuous scan on the instruments: the axis set to the
//! pass's velocity, the readout captured (or polled) and the tracker
//! streaming while the axis turns from the pass's start to its end, every
//! read noted with the host time of its answer; and its pairing.
//!
//! The scan's velocities, periods and deadlines are on the host's clock, and
//! the instruments' clocks must keep its pace: a tracker whose clock runs at
//! another rate (an instrument simulator under `survey sim --time-scale`,
//! whose axis then turns that much faster too) is refused before a survey on
//! instruments is acquired or resumed ([`probe_pace`]), saying so, rather
//! than failing to pair pass after pass.

use super::super::{Engine, Failed, Reference};
use crate::record::{RawReading, RecordedSample, ScanPassRecord};
use std::time::Duration;
use survey_drivers::clock::with_timeout;
use survey_drivers::{DriverError, ErrorKind, SmrMeasurement, StreamedPoint, Tracker};
use survey_plan::budget::Component;
use survey_plan::pairing::{ClockMap, PairError, crossing_time, position_at};
use survey_plan::{PassPlan, ScanTiming, move_time};
use survey_processing::Sample;
use survey_processing::geometry::AxisFit;
use survey_processing::num::Num;

/// What one pass gathered.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RawPass {
    /// `(stamp, readout)`: the controller's stamps when captured, the
    /// host's (middle of the request) when polled.
    pub readouts: Vec<(f64, f64)>,
    pub captured: bool,
    /// `(stamp of the newest readout, host time of the answer)` per capture read.
    pub readout_fetches: Vec<(f64, f64)>,
    pub points: Vec<StreamedPoint>,
    /// `(stamp of the newest point, host time of the answer)` per stream read.
    pub point_fetches: Vec<(f64, f64)>,
    /// Instrument time the move was commanded and seen to end.
    pub started_s: f64,
    pub ended_s: f64,
}

/// How often the status is read during a pass, in reads of the streams.
const STATUS_EVERY: u32 = 4;

/// How long the tracker's stream is read to check its clock against the
/// host's, host seconds.
const CLOCK_CHECK_S: f64 = 0.5;

/// The tracker's clock seconds per host second a scan accepts. A real
/// tracker's is 1 within parts per million; the fit over half a second of
/// reads is good to a few parts per thousand.
const CLOCK_PACE: std::ops::RangeInclusive<f64> = 0.8..=1.25;

/// The tracker's clock seconds per host second over `fetches` (`(stamp, host
/// time)` per read), once they span [`CLOCK_CHECK_S`] of host time.
fn clock_pace(fetches: &[(f64, f64)]) -> Option<f64> {
    let span = fetches.last()?.1 - fetches.first()?.1;
    if span < CLOCK_CHECK_S {
        return None;
    }
    ClockMap::fit(fetches).map(|m| 1.0 / m.rate)
}

/// Why the tracker `name`, whose clock runs `pace` times the host's, cannot
/// be scanned with (`None`: it can).
fn pace_refused(name: &str, pace: f64) -> Option<DriverError> {
    (!(pace.is_finite() && CLOCK_PACE.contains(&pace))).then(|| {
        DriverError::usage(
            name,
            format!(
                "its clock runs {} times as fast as this computer's (an instrument simulator under survey sim \
                 --time-scale?): a continuous scan turns the axis and pairs the streams in real time, so it needs \
                 instruments in real time; use --scan step, or survey sim without --time-scale",
                Num((pace * 100.0).round() / 100.0)
            ),
        )
    })
}

/// Read the tracker's stream for [`CLOCK_CHECK_S`] with the axis at rest and
/// check its clock's pace: a usage error when a scan cannot pair it; a link
/// or device error as met (the stream is stopped either way).
pub(super) async fn probe_pace(engine: &mut Engine) -> Result<(), DriverError> {
    let clock = engine.clock.clone();
    let t = engine.timing.clone();
    let name = tracker(engine).map_err(|e| e.0)?.name().to_string();
    let start = tracker(engine).map_err(|e| e.0)?.start_stream(t.scan.stream_period);
    with_timeout(&*clock, t.measure_timeout, &name, "start stream", start).await?;
    let started = clock.now();
    let mut fetches = Vec::new();
    let verdict = loop {
        clock.sleep(t.scan.fetch_interval).await;
        let read = tracker(engine).map_err(|e| e.0)?.read_stream();
        match with_timeout(&*clock, t.call_timeout, &name, "read stream", read).await {
            Ok(got) => {
                if let Some(last) = got.last() {
                    fetches.push((last.device_time_s, clock.now().as_secs_f64()));
                }
            }
            Err(e) => break Err(e),
        }
        if let Some(pace) = clock_pace(&fetches) {
            break pace_refused(&name, pace).map_or(Ok(()), Err);
        }
        if clock.now() - started > t.measure_timeout {
            break Err(DriverError::new(
                ErrorKind::Timeout,
                name.clone(),
                format!("its stream gave no points to time for {:?}", t.measure_timeout),
            ));
        }
    };
    let stop = tracker(engine).map_err(|e| e.0)?.stop_stream();
    if let Err(e) = with_timeout(&*clock, t.call_timeout, &name, "stop stream", stop).await {
        tracing::debug!(%e, "stopping the stream after its clock's check");
    }
    verdict
}

fn tracker(engine: &mut Engine) -> Result<&mut Box<dyn Tracker>, (DriverError, Failed)> {
    match &mut engine.reference {
        Reference::Tracker(t) => Ok(t),
        Reference::Autocollimator { instrument, .. } => Err((
            DriverError::usage(instrument.name(), "a continuous scan needs a tracker that streams"),
            Failed::Reference,
        )),
    }
}

/// Scan pass `p` from where the axis is (its start).
pub(super) async fn acquire(engine: &mut Engine, p: &PassPlan) -> Result<RawPass, (DriverError, Failed)> {
    let clock = engine.clock.clone();
    let t = engine.timing.clone();
    let pos = |e: DriverError| (e, Failed::Positioner);
    let refe = |e: DriverError| (e, Failed::Reference);
    let pname = engine.positioner.name().to_string();
    let tname = tracker(engine)?.name().to_string();
    engine.ledger.switch(clock.now(), Component::CommandLatency);
    with_timeout(&*clock, t.call_timeout, &pname, "set velocity", engine.positioner.set_velocity(p.speed))
        .await
        .map_err(pos)?;
    let captured = engine.positioner.can_capture();
    if captured {
        let start = engine.positioner.start_capture(t.scan.capture_period);
        with_timeout(&*clock, t.call_timeout, &pname, "start capture", start).await.map_err(pos)?;
    }
    let start = tracker(engine)?.start_stream(t.scan.stream_period);
    with_timeout(&*clock, t.measure_timeout, &tname, "start stream", start).await.map_err(refe)?;
    with_timeout(&*clock, t.call_timeout, &pname, "move command", engine.positioner.move_to(p.end))
        .await
        .map_err(pos)?;
    let started = clock.now();
    engine.commanded = None;
    engine.ledger.switch(started, Component::Scan);
    let expected = Duration::from_secs_f64(move_time(p.end - p.start, p.speed, t.accel_deg_s2));
    let deadline = started + expected + t.move_margin;
    let mut raw = RawPass {
        readouts: Vec::new(),
        captured,
        readout_fetches: Vec::new(),
        points: Vec::new(),
        point_fetches: Vec::new(),
        started_s: started.as_secs_f64(),
        ended_s: f64::NAN,
    };
    let mut reads = 0u32;
    let mut over = false;
    loop {
        let tick = clock.now();
        if captured {
            let got = with_timeout(&*clock, t.call_timeout, &pname, "read capture", engine.positioner.read_capture())
                .await
                .map_err(pos)?;
            if let Some(last) = got.last() {
                raw.readout_fetches.push((last.device_time_s, clock.now().as_secs_f64()));
            }
            raw.readouts.extend(got.iter().map(|r| (r.device_time_s, r.readout_deg)));
        } else {
            // Poll the readout at a fixed rate for one fetch interval.
            loop {
                let asked = clock.now();
                let r = with_timeout(&*clock, t.call_timeout, &pname, "readout", engine.positioner.readout())
                    .await
                    .map_err(pos)?;
                let answered = clock.now();
                raw.readouts.push(((asked.as_secs_f64() + answered.as_secs_f64()) / 2.0, r));
                if answered - tick + t.scan.capture_period > t.scan.fetch_interval {
                    break;
                }
                clock.sleep(t.scan.capture_period.saturating_sub(answered - asked)).await;
            }
        }
        let got = with_timeout(&*clock, t.call_timeout, &tname, "read stream", tracker(engine)?.read_stream())
            .await
            .map_err(refe)?;
        if let Some(last) = got.last() {
            raw.point_fetches.push((last.device_time_s, clock.now().as_secs_f64()));
        }
        raw.points.extend(got);
        if over {
            break;
        }
        reads += 1;
        if reads.is_multiple_of(STATUS_EVERY) || clock.now() >= started + expected {
            let s = with_timeout(&*clock, t.call_timeout, &pname, "status", engine.positioner.status())
                .await
                .map_err(pos)?;
            if let Some(f) = s.fault {
                return Err(pos(DriverError::device(pname, f.code, f.text)));
            }
            if !s.moving && clock.now() >= started + expected {
                raw.ended_s = clock.now().as_secs_f64();
                // One more read of each stream: what was measured up to the end.
                over = true;
                continue;
            }
        }
        if clock.now() > deadline {
            return Err(pos(DriverError::new(
                ErrorKind::Timeout,
                pname,
                format!("the scan to {} deg did not end within {:?}", p.end, expected + t.move_margin),
            )));
        }
        if captured {
            clock.sleep(t.scan.fetch_interval.saturating_sub(clock.now() - tick)).await;
        }
    }
    engine.ledger.switch(clock.now(), Component::CommandLatency);
    if captured {
        with_timeout(&*clock, t.call_timeout, &pname, "stop capture", engine.positioner.stop_capture())
            .await
            .map_err(pos)?;
    }
    let stop = tracker(engine)?.stop_stream();
    with_timeout(&*clock, t.call_timeout, &tname, "stop stream", stop).await.map_err(refe)?;
    let restore = engine.positioner.set_velocity(t.velocity_deg_s);
    with_timeout(&*clock, t.call_timeout, &pname, "set velocity", restore).await.map_err(pos)?;
    engine.commanded = Some(p.end);
    Ok(raw)
}

/// After a failed or stopped pass: stop the axis and both streams, set the
/// velocity back (each as far as it goes; failures are logged).
pub(super) async fn abandon(engine: &mut Engine) {
    let clock = engine.clock.clone();
    let t = engine.timing.clone();
    let pname = engine.positioner.name().to_string();
    let steps: [(&str, Result<(), DriverError>); 1] =
        [("stop", with_timeout(&*clock, t.call_timeout, &pname, "stop", engine.positioner.stop()).await)];
    for (what, r) in steps {
        if let Err(e) = r {
            tracing::warn!(%e, what, "after a failed pass");
        }
    }
    if let Err(e) =
        with_timeout(&*clock, t.call_timeout, &pname, "stop capture", engine.positioner.stop_capture()).await
    {
        tracing::debug!(%e, "stopping the capture after a failed pass");
    }
    if let Ok(tr) = tracker(engine) {
        let name = tr.name().to_string();
        if let Err(e) = with_timeout(&*clock, t.call_timeout, &name, "stop stream", tr.stop_stream()).await {
            tracing::debug!(%e, "stopping the stream after a failed pass");
        }
    }
    let restore = engine.positioner.set_velocity(t.velocity_deg_s);
    if let Err(e) = with_timeout(&*clock, t.call_timeout, &pname, "set velocity", restore).await {
        tracing::warn!(%e, "setting the velocity back after a failed pass");
    }
    engine.commanded = None;
}

/// A pass paired: its samples, each target's error, and the clock maps.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Paired {
    pub samples: Vec<RecordedSample>,
    pub errors: Vec<f64>,
    pub readout_clock: ClockMap,
    pub tracker_clock: ClockMap,
}

/// Pair pass `p` with the latency `delta_s` removed (see the module documentation of [`super`]).
pub(super) fn pair(
    raw: &RawPass,
    p: &PassPlan,
    axis: &AxisFit,
    t: &ScanTiming,
    delta_s: f64,
) -> Result<Paired, PairError> {
    let readout_clock = if raw.captured {
        ClockMap::fit(&raw.readout_fetches).ok_or(PairError::NoClock { stream: "readout" })?
    } else {
        ClockMap::HOST
    };
    let tracker_clock = ClockMap::fit(&raw.point_fetches).ok_or(PairError::NoClock { stream: "tracker" })?;
    let mut readouts: Vec<(f64, f64)> = raw.readouts.iter().map(|(s, r)| (readout_clock.host(*s), *r)).collect();
    readouts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (rt, rv): (Vec<f64>, Vec<f64>) = readouts.into_iter().unzip();
    let mut points: Vec<(f64, [f64; 3])> =
        raw.points.iter().filter(|q| q.status == 0).map(|q| (tracker_clock.host(q.device_time_s), q.xyz_mm)).collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (pt, pxyz): (Vec<f64>, Vec<[f64; 3]>) = points.into_iter().unzip();
    let period = t.stream_period.as_secs_f64();
    let readout_gap = t.max_gap_periods * t.capture_period.as_secs_f64();
    let point_gap = t.max_gap_periods * period;
    let half_width = t.fit_half_width_periods * period;
    let sign = p.direction.sign();
    let mut samples = Vec::with_capacity(p.targets.len());
    let mut errors = Vec::with_capacity(p.targets.len());
    for &(seq, target) in &p.targets {
        let at = crossing_time(&rt, &rv, target, sign, readout_gap)?;
        // A point stamped at the end of its integration shows the middle of it.
        let stamp = at + period / 2.0 + delta_s;
        let xyz = position_at(&pt, &pxyz, stamp, half_width, point_gap, target)?;
        let actual = axis.angle_deg(xyz, target);
        errors.push(target - actual);
        let sample = Sample {
            run: p.run,
            direction: p.direction,
            target_deg: target,
            readout_deg: target,
            actual_deg: actual,
            timestamp_s: Some(at),
        };
        let raw = RawReading::Smr(SmrMeasurement {
            x_mm: xyz[0],
            y_mm: xyz[1],
            z_mm: xyz[2],
            std_dev_mm: [f64::NAN; 3],
            measurement_time_s: period,
            environment: None,
        });
        samples.push(RecordedSample { seq, sample, raw, others: Vec::new() });
    }
    Ok(Paired { samples, errors, readout_clock, tracker_clock })
}

/// What the store keeps of a pass.
pub(super) fn record(p: &PassPlan, raw: &RawPass, paired: Paired, latency: (f64, f64)) -> ScanPassRecord {
    ScanPassRecord {
        pass: p.index,
        run: p.run,
        direction: p.direction,
        velocity_deg_s: p.speed,
        latency_s: latency.0,
        latency_se_s: latency.1,
        readout_clock: (paired.readout_clock.offset_s, paired.readout_clock.rate),
        tracker_clock: (paired.tracker_clock.offset_s, paired.tracker_clock.rate),
        readout_captured: raw.captured,
        started_at_s: raw.started_s,
        ended_at_s: raw.ended_s,
        samples: paired.samples,
        readouts: raw.readouts.iter().map(|(s, r)| [*s, *r]).collect(),
        readout_fetches: raw.readout_fetches.iter().map(|(d, h)| [*d, *h]).collect(),
        points: raw
            .points
            .iter()
            .map(|q| [q.device_time_s, q.xyz_mm[0], q.xyz_mm[1], q.xyz_mm[2], f64::from(q.status)])
            .collect(),
        point_fetches: raw.point_fetches.iter().map(|(d, h)| [*d, *h]).collect(),
    }
}
