//! Suspend paths on the virtual clock: a beam lost for minutes and waited
//! out, one lost past `beam_wait` (the survey ends interrupted and a resume
//! finishes it), a limit switch and an uncured drive fault (the axis is
//! stopped), an autocollimator out of range (measured again, the face named).

use super::super::*;
use crate::record::MemorySink;
use std::sync::Mutex;
use survey_drivers::{Limit, PositionerStatus, VirtualClock};
use survey_processing::table::CorrectionTable;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::{PositionerFaults, Preset, SimBench, SimBenchBuilder, SimPositioner, Turntable};

fn builder(seed: u64, clock: &Arc<VirtualClock>) -> SimBenchBuilder {
    let clock: Arc<dyn Clock> = clock.clone();
    SimBench::builder(&Preset::default(), seed, clock)
}

/// A positioner that counts its stops, and after `limit_after` accepted
/// moves never arrives: it rests at the upper limit switch.
#[derive(Debug)]
struct Watched {
    inner: SimPositioner,
    limit_after: Option<usize>,
    stops: Arc<Mutex<usize>>,
    /// Whether its fault clear is refused as bad usage (a controller with no
    /// command for it, that says what to do).
    no_clear: bool,
}

#[async_trait::async_trait]
impl Positioner for Watched {
    fn name(&self) -> &str {
        self.inner.name()
    }
    async fn move_to(&mut self, target_deg: f64) -> survey_drivers::Result<()> {
        self.inner.move_to(target_deg).await
    }
    async fn readout(&mut self) -> survey_drivers::Result<f64> {
        self.inner.readout().await
    }
    async fn status(&mut self) -> survey_drivers::Result<PositionerStatus> {
        let mut s = self.inner.status().await?;
        if self.limit_after.is_some_and(|n| self.inner.moves() > n) {
            s = PositionerStatus { moving: false, in_position: false, limit: Some(Limit::Upper), ..s };
        }
        Ok(s)
    }
    async fn stop(&mut self) -> survey_drivers::Result<()> {
        *self.stops.lock().unwrap() += 1;
        self.inner.stop().await
    }
    async fn set_velocity(&mut self, v: f64) -> survey_drivers::Result<()> {
        self.inner.set_velocity(v).await
    }
    async fn clear_fault(&mut self) -> survey_drivers::Result<()> {
        if self.no_clear {
            return Err(DriverError::usage("watched", "the fault stays latched: clear it at the controller"));
        }
        self.inner.clear_fault().await
    }
    async fn load_correction_table(&mut self, t: &CorrectionTable) -> survey_drivers::Result<()> {
        self.inner.load_correction_table(t).await
    }
    async fn enable_correction(&mut self, on: bool) -> survey_drivers::Result<()> {
        self.inner.enable_correction(on).await
    }
    async fn correction_state(&mut self) -> survey_drivers::Result<Option<bool>> {
        self.inner.correction_state().await
    }
}

struct Rig {
    engine: Engine,
    truth: Turntable,
    stops: Arc<Mutex<usize>>,
}

fn make_rig(b: SimBenchBuilder, autocollimator: bool, timing: Timing, limit_after: Option<usize>) -> Rig {
    make_rig_with(b, autocollimator, timing, limit_after, false)
}

fn make_rig_with(
    b: SimBenchBuilder,
    autocollimator: bool,
    timing: Timing,
    limit_after: Option<usize>,
    no_clear: bool,
) -> Rig {
    let bench = b.build();
    let cfg = bench.positioner.config();
    let timing = Timing { velocity_deg_s: cfg.velocity_deg_s, accel_deg_s2: cfg.accel_deg_s2, ..timing };
    let stops = Arc::new(Mutex::new(0));
    let truth = bench.positioner.truth();
    let positioner = Watched { inner: bench.positioner, limit_after, stops: stops.clone(), no_clear };
    let reference = if autocollimator {
        Reference::Autocollimator {
            faces: bench.autocollimator.faces(),
            certificate_arcsec: bench.autocollimator.certificate_arcsec().to_vec(),
            instrument: Box::new(bench.autocollimator),
        }
    } else {
        Reference::Tracker(Box::new(bench.tracker))
    };
    Rig { engine: Engine::new(bench.clock, Box::new(positioner), reference, timing), truth, stops }
}

fn plan12() -> SurveyPlan {
    SurveyPlan::full_circle(12, 2, true).unwrap()
}

fn events(sink: &MemorySink, level: &str) -> Vec<String> {
    sink.events.iter().filter(|(_, l, _)| l == level).map(|(_, _, m)| m.clone()).collect()
}

/// A beam broken on step 7's measurement, blocked for `hold`, with `wait`.
fn beam_rig(seed: u64, clock: &Arc<VirtualClock>, hold: Duration, wait: Duration) -> Rig {
    let mut b = builder(seed, clock);
    // 12 locate measurements first: measurement 20 is step 7's.
    b.tracker.break_on_measurement = Some(20);
    b.tracker.beam_hold = hold;
    make_rig(b, false, Timing { beam_wait: wait, beam_retry: Duration::from_secs(10), ..Timing::default() }, None)
}

#[tokio::test]
async fn a_beam_lost_for_five_minutes_suspends_the_survey_and_it_goes_on_when_the_beam_is_back() {
    let clock = Arc::new(VirtualClock::new());
    let mut rig = beam_rig(3, &clock, Duration::from_secs(300), Duration::from_secs(600));
    let plan = plan12();
    let mut sink = MemorySink::default();
    let outcome = rig.engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    assert_eq!(sink.samples.len() as u64, plan.total_steps(), "every step once");
    assert!(sink.samples.iter().enumerate().all(|(i, r)| r.seq == i as u64));
    assert_eq!(outcome.faults_survived, 1, "one suspension, survived");
    let warns = events(&sink, "warn");
    assert_eq!(warns.len(), 1, "{warns:?}");
    assert!(warns[0].contains("survey suspended, the axis holds"), "{}", warns[0]);
    let back = events(&sink, "info");
    let resumed = back.iter().find(|m| m.contains("beam re-acquired after")).expect("the beam came back");
    // Searches of 5 s every 10 s from the break: the first to end past 300 s.
    let waited: f64 = resumed.split("after ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!((300.0..330.0).contains(&waited), "{resumed}");
    assert!(back.iter().any(|m| m.contains("still waiting for the beam")), "it says it waits: {back:?}");
    // Step 7 was measured after the beam came back, at least 300 s after step 6.
    let t = |i: usize| sink.samples[i].sample.timestamp_s.unwrap();
    assert!(t(7) - t(6) > 300.0, "steps 6 and 7 at {} and {}", t(6), t(7));
    // The point measured again is as good as any: within 0.03 deg of its target (fig8's error bound).
    assert!((sink.samples[7].sample.actual_deg - sink.samples[7].sample.target_deg).abs() < 0.03);
}

#[tokio::test]
async fn a_beam_lost_past_the_wait_ends_the_survey_interrupted_with_the_axis_held_and_a_resume_finishes_it() {
    let clock = Arc::new(VirtualClock::new());
    let wait = Duration::from_secs(120);
    let mut rig = beam_rig(4, &clock, Duration::from_secs(3600), wait);
    let plan = plan12();
    let mut sink = MemorySink::default();
    let err = rig.engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap_err();
    let EngineError::Suspended(why) = &err else { panic!("{err:?}") };
    assert!(why.contains("the beam stayed lost") && why.contains("survey resume"), "{why}");
    assert_eq!(sink.samples.len(), 7, "steps 0..=6 kept");
    let errors = events(&sink, "error");
    assert_eq!(errors.len(), 1, "{errors:?}");
    // The axis held at step 7's target all along (nothing was commanded).
    let target = plan.steps()[7].target_deg;
    assert!((rig.truth.actual_deg(clock.now()) - target).abs() < 0.03, "the axis is at step 7's target");
    assert_eq!(*rig.stops.lock().unwrap(), 0, "a held axis needs no stop");
    // It waited the whole wait, and no more than one search beyond it.
    let broke = sink.samples[6].sample.timestamp_s.unwrap();
    let waited = clock.now().as_secs_f64() - broke;
    assert!(waited >= wait.as_secs_f64() && waited < wait.as_secs_f64() + 30.0, "waited {waited} s");

    // Resumed on a clear beam, from the first missing step, around the same axis.
    let axis = sink.axis.clone().unwrap();
    let later = Arc::new(VirtualClock::starting_at(clock.now()));
    let mut resumed = rig_clear(5, &later, axis);
    let mut rest = MemorySink::default();
    resumed.engine.run(&plan, 7, &mut rest, &mut |_| {}).await.unwrap();
    let seqs: Vec<u64> = sink.samples.iter().chain(&rest.samples).map(|r| r.seq).collect();
    assert_eq!(seqs, (0..plan.total_steps()).collect::<Vec<_>>(), "every step exactly once");
}

fn rig_clear(seed: u64, clock: &Arc<VirtualClock>, axis: AxisFit) -> Rig {
    let mut r = make_rig(builder(seed, clock), false, Timing::default(), None);
    r.engine = r.engine.with_axis(axis);
    r
}

#[tokio::test]
async fn a_limit_switch_stops_the_axis_and_interrupts_the_survey_at_once() {
    let clock = Arc::new(VirtualClock::new());
    // Locating takes 13 moves; the 16th move ends at the limit switch.
    let mut rig = make_rig(builder(6, &clock), false, Timing::default(), Some(15));
    let mut sink = MemorySink::default();
    let err = rig.engine.run(&plan12(), 0, &mut sink, &mut |_| {}).await.unwrap_err();
    let EngineError::Suspended(why) = &err else { panic!("{err:?}") };
    assert!(why.contains("Upper limit switch") && why.contains("axis is stopped"), "{why}");
    assert_eq!(*rig.stops.lock().unwrap(), 1, "the axis was stopped");
    assert!(events(&sink, "warn").is_empty(), "a limit is not retried: {:?}", sink.events);
    assert_eq!(events(&sink, "error").len(), 1, "{:?}", sink.events);
}

#[tokio::test]
async fn a_drive_fault_that_clearing_does_not_cure_stops_the_axis() {
    let clock = Arc::new(VirtualClock::new());
    let faults = PositionerFaults { fault_probability_per_move: 1.0, ..Default::default() };
    let mut rig = make_rig(builder(9, &clock).faults(faults), false, Timing::default(), None);
    let mut sink = MemorySink::default();
    let err = rig.engine.run(&plan12(), 0, &mut sink, &mut |_| {}).await.unwrap_err();
    assert!(matches!(err, EngineError::Instrument(ref e) if e.kind == ErrorKind::Device), "{err:?}");
    assert_eq!(*rig.stops.lock().unwrap(), 1, "the axis was stopped after the last retry");
    assert_eq!(events(&sink, "warn").len(), Timing::default().max_retries as usize);
}

/// A positioner that refuses to clear its fault as bad usage (the SCPI
/// controller without a public fault-clear command) stops the survey at
/// the first trip, its words (what to do) the error, without retries that
/// would meet the same fault.
#[tokio::test]
async fn a_fault_the_positioner_cannot_clear_stops_the_axis_at_the_first_trip_saying_what_to_do() {
    let clock = Arc::new(VirtualClock::new());
    let faults = PositionerFaults { fault_probability_per_move: 1.0, ..Default::default() };
    let mut rig = make_rig_with(builder(9, &clock).faults(faults), false, Timing::default(), None, true);
    let mut sink = MemorySink::default();
    let err = rig.engine.run(&plan12(), 0, &mut sink, &mut |_| {}).await.unwrap_err();
    let EngineError::Instrument(e) = &err else { panic!("{err:?}") };
    assert_eq!(e.kind, ErrorKind::Usage, "{e}");
    assert!(e.message.contains("clear it at the controller"), "{e}");
    assert_eq!(*rig.stops.lock().unwrap(), 1, "the axis was stopped");
    let errors = events(&sink, "error");
    assert!(errors.len() == 1 && errors[0].contains("clear it at the controller"), "{:?}", sink.events);
}

#[tokio::test]
async fn an_autocollimator_out_of_range_is_measured_again_then_its_face_is_named() {
    let plan = plan12();
    // A range of 1 arcsec: the positioner's error (about 50 arcsec) leaves every face out of it.
    let clock = Arc::new(VirtualClock::new());
    let ac = AutocollimatorConfig { range_arcsec: 1.0, ..AutocollimatorConfig::seeded(12, 8) };
    let mut rig = make_rig(builder(8, &clock).autocollimator(ac), true, Timing::default(), None);
    let mut sink = MemorySink::default();
    let err = rig.engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap_err();
    let EngineError::Instrument(e) = &err else { panic!("{err:?}") };
    assert!(e.message.starts_with("face 0 (nominal 0 deg) out of range"), "{e}");
    let warns = events(&sink, "warn");
    assert_eq!(warns.len(), Timing::default().max_retries as usize, "measured again each retry");
    assert!(warns.iter().all(|w| w.contains("face 0")), "{warns:?}");

    // A view blocked now and then: each reading is measured again and the survey completes.
    let clock = Arc::new(VirtualClock::new());
    let ac = AutocollimatorConfig { blocked_probability: 0.05, ..AutocollimatorConfig::seeded(12, 8) };
    let mut again = make_rig(builder(8, &clock).autocollimator(ac), true, Timing::default(), None);
    let mut sink = MemorySink::default();
    let outcome = again.engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    assert_eq!(sink.samples.len() as u64, plan.total_steps());
    assert!(outcome.faults_survived > 0);
    assert!(events(&sink, "warn").iter().all(|w| w.contains("out of range") && w.contains("face ")));
}
