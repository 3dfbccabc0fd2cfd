//! A reading refused by an instrument (issue 51): the positioner's readout
//! refused (a Modbus exception 4), the tracker's measurement refused with
//! the beam unbroken (emScon's `ES_RS_SensorNotStable`). Each is asked again
//! in place, the pair read again together, up to `max_retries` in a row;
//! beyond that the step is retried as a whole, with recovery. Scripted on
//! the simulated bench (a virtual clock: milliseconds of real time).

use super::*;
use crate::settings::SettleMode;
use std::ops::Range;
use survey_sims::SimTracker;

/// emScon's `ES_RS_SensorNotStable` (`ES_API_ERROR_OFFSET + 13`), as the
/// emScon driver reports a refused measurement.
const CODE_SENSOR_NOT_STABLE: i64 = 10013;

/// The simulated tracker, refusing the measurements (counted from 1) in
/// `refuse` without passing them on; its status stays what it is (the beam
/// is not broken).
#[derive(Debug)]
struct Refusing {
    inner: SimTracker,
    refuse: Range<usize>,
    measures: usize,
    /// This many measurements refused after the first pointing (at SMR 2).
    after_pointing: usize,
    pointed: usize,
}

#[async_trait::async_trait]
impl Tracker for Refusing {
    fn name(&self) -> &str {
        self.inner.name()
    }
    async fn measure(&mut self) -> survey_drivers::Result<SmrMeasurement> {
        self.measures += 1;
        let at_second = self.pointed == 1 && self.after_pointing > 0;
        if at_second {
            self.after_pointing -= 1;
        }
        if self.refuse.contains(&self.measures) || at_second {
            return Err(DriverError::device(self.inner.name(), CODE_SENSOR_NOT_STABLE, "sensor not stable (injected)"));
        }
        self.inner.measure().await
    }
    async fn status(&mut self) -> survey_drivers::Result<TrackerState> {
        self.inner.status().await
    }
    async fn reacquire(&mut self) -> survey_drivers::Result<()> {
        self.inner.reacquire().await
    }
    fn can_point(&self) -> bool {
        self.inner.can_point()
    }
    async fn point_at(&mut self, xyz_mm: [f64; 3]) -> survey_drivers::Result<()> {
        self.pointed += 1;
        self.inner.point_at(xyz_mm).await
    }
}

/// A tracker rig in `mode`, its positioner refusing the readouts in
/// `readouts` and its tracker the measurements in `measures`.
fn refusing_rig(mode: SettleMode, readouts: Range<usize>, measures: Range<usize>) -> Rig {
    rig_on(builder(&fig8(), 7, &new_clock()), mode, readouts, measures, 0)
}

fn rig_on(b: SimBenchBuilder, mode: SettleMode, readouts: Range<usize>, measures: Range<usize>, after: usize) -> Rig {
    let bench = b.build();
    let cfg = bench.positioner.config();
    let mut timing = Timing { velocity_deg_s: cfg.velocity_deg_s, accel_deg_s2: cfg.accel_deg_s2, ..Timing::default() };
    timing.settle.mode = mode;
    let log = Arc::new(Mutex::new(SpyLog::default()));
    let spy = Spy {
        truth: bench.positioner.truth(),
        inner: bench.positioner,
        clock: bench.clock.clone(),
        log: log.clone(),
        refuse_after_moves: None,
        refuse_readouts: readouts,
        readouts: 0,
    };
    let tracker = Refusing { inner: bench.tracker, refuse: measures, measures: 0, after_pointing: after, pointed: 0 };
    let engine = Engine::new(bench.clock, Box::new(spy), Reference::Tracker(Box::new(tracker)), timing);
    Rig { engine, log }
}

fn plan4() -> SurveyPlan {
    SurveyPlan::full_circle(4, 2, false).unwrap()
}

/// Every sample once, and what the run met and did.
async fn survey(rig: &mut Rig) -> (Outcome, MemorySink) {
    let plan = plan4();
    let mut sink = MemorySink::default();
    let outcome = run_all(rig, &plan, 0, &mut sink).await.unwrap_or_else(|e| panic!("{e}"));
    assert_steps(&sink.samples, &plan, 0);
    (outcome, sink)
}

fn count(sink: &MemorySink, level: &str, part: &str) -> usize {
    events(sink, level).iter().filter(|m| m.contains(part)).count()
}

fn calls_of(rig: &Rig, call: Call) -> usize {
    rig.calls().iter().filter(|c| **c == call).count()
}

/// In position, the first readout is the first locate move's (from an
/// unknown position); the second is the first reading's. Refused up to
/// `max_retries` (3) times, it is asked again in place: no fault cleared, no
/// step retried, every refusal a device fault counted and survived.
#[tokio::test]
async fn a_readout_refused_up_to_max_retries_times_is_asked_again_in_place() {
    for n in 1..=3usize {
        let mut rig = refusing_rig(SettleMode::InPosition, 2..2 + n, 0..0);
        let (outcome, sink) = survey(&mut rig).await;
        assert_eq!(outcome.faults_met, FaultCounts { device: n as u32, ..FaultCounts::default() }, "{n}");
        assert_eq!(outcome.faults_survived, n as u32, "{n}");
        assert_eq!(count(&sink, "warn", "(asked again)"), n, "{n}: {:?}", sink.events);
        assert_eq!(count(&sink, "warn", "retrying"), 0, "{n}: {:?}", sink.events);
        assert_eq!(calls_of(&rig, Call::ClearFault), 0, "{n}: not the step's");
    }
}

/// One refusal more than the bound: the reading's fault is the step's (the
/// fault cleared, the target approached afresh, read again); every refusal
/// still counted once.
#[tokio::test]
async fn a_readout_refused_more_than_max_retries_times_is_the_steps() {
    let mut rig = refusing_rig(SettleMode::InPosition, 2..6, 0..0);
    let (outcome, sink) = survey(&mut rig).await;
    assert_eq!(outcome.faults_met, FaultCounts { device: 4, ..FaultCounts::default() });
    assert_eq!(outcome.faults_survived, 4);
    assert_eq!(count(&sink, "warn", "(asked again)"), 3, "{:?}", sink.events);
    assert_eq!(count(&sink, "warn", "reading: sim-positioner"), 4, "{:?}", sink.events);
    assert_eq!(count(&sink, "warn", "(attempt 1, retrying)"), 1, "{:?}", sink.events);
    assert_eq!(calls_of(&rig, Call::ClearFault), 1, "the step's recovery");
    // Refused at every attempt of the step: the survey stops, interrupted, on the device fault.
    let mut rig = refusing_rig(SettleMode::InPosition, 2..usize::MAX, 0..0);
    let mut sink = MemorySink::default();
    let e = run_all(&mut rig, &plan4(), 0, &mut sink).await.unwrap_err();
    assert!(matches!(&e, EngineError::Instrument(d) if d.kind == ErrorKind::Device), "{e}");
    assert!(sink.samples.is_empty());
}

/// A tracker's refusal (the beam unbroken) is asked again in place: the pair
/// is read again together (a readout with each measurement, so the
/// sample's readout is the one read with its measurement); one more than the
/// bound is the step's. In adaptive settling too (its closing readout).
#[tokio::test]
async fn a_measurement_refused_is_read_again_with_its_readout() {
    for mode in [SettleMode::InPosition, SettleMode::Adaptive] {
        let mut clean = refusing_rig(mode, 0..0, 0..0);
        let _ = survey(&mut clean).await;
        let readouts = calls_of(&clean, Call::Readout);
        for n in 1..=3usize {
            let mut rig = refusing_rig(mode, 0..0, 1..1 + n);
            let (outcome, sink) = survey(&mut rig).await;
            assert_eq!(outcome.faults_met, FaultCounts { device: n as u32, ..FaultCounts::default() }, "{mode:?} {n}");
            assert_eq!(count(&sink, "warn", "(asked again)"), n, "{mode:?} {n}: {:?}", sink.events);
            assert_eq!(count(&sink, "warn", "retrying"), 0, "{mode:?} {n}");
            // One readout more with each measurement read again (in adaptive
            // settling the closing readout comes only after a measurement).
            assert_eq!(calls_of(&rig, Call::Readout), readouts + n, "{mode:?} {n}");
        }
        let mut rig = refusing_rig(mode, 0..0, 1..5);
        let (outcome, sink) = survey(&mut rig).await;
        assert_eq!(outcome.faults_met, FaultCounts { device: 4, ..FaultCounts::default() }, "{mode:?}");
        assert_eq!(count(&sink, "warn", "(attempt 1, retrying)"), 1, "{mode:?}: {:?}", sink.events);
    }
}

/// Two SMRs: the second's measurement, refused after the tracker was
/// pointed at it, is measured again in place (the tracker stays on it, not
/// pointed again) up to the bound; once more is the SMR's step (pointed again).
#[tokio::test]
async fn another_smrs_measurement_refused_is_measured_again_in_place() {
    let second = survey_sims::tracker::SmrMount { phase_deg: 120.0, height_mm: 0.0 };
    let arm = survey_sims::ArmGeometry { smrs: vec![SmrMount::FIRST, second], ..Default::default() };
    for (n, retried) in [(3, 0), (4, 1)] {
        let b = builder(&fig8(), 7, &new_clock()).arm(arm.clone());
        let mut rig = rig_on(b, SettleMode::InPosition, 0..0, 0..0, n);
        rig.engine = rig.engine.with_smrs(vec![SmrMount::FIRST, second], Duration::ZERO);
        let (outcome, sink) = survey(&mut rig).await;
        assert_eq!(outcome.faults_met, FaultCounts { device: n as u32, ..FaultCounts::default() }, "{n}");
        assert_eq!(count(&sink, "warn", "SMR 2 at 0 deg"), n, "{n}: {:?}", sink.events);
        assert_eq!(count(&sink, "warn", "(asked again)"), 3, "{n}: {:?}", sink.events);
        assert_eq!(count(&sink, "warn", "(attempt 1, retrying)"), retried, "{n}: {:?}", sink.events);
        assert!(sink.samples.iter().all(|s| s.others.len() == 1), "every sample with the second SMR's reading");
    }
}
