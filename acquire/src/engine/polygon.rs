//! A polygon on a stage (issue 48): the polygon the autocollimator looks at
//! stands on a second, indexing axis (any positioner the drivers speak to),
//! and the survey turns it relative to the table between runs, by a whole
//! number of faces per run as the plan of orientations says. Then every face
//! meets every table position the orientations link, and the processing
//! measures the polygon's face errors in place (closure,
//! `survey_tables::closure`) instead of trusting its certificate.
//!
//! Without a stage the operator turns it ([`PolygonStage::by_operator`]):
//! the polygon is taken as the operator set it up for the run the survey
//! starts (or resumes) in, and when a run needs another turn the survey
//! stops `interrupted` before it, asking for the turn by name; `survey
//! resume`, run once the polygon is turned, is the confirmation.
//!
//! With the polygon turned by `s` faces, face `k` meets the optical axis
//! when the table is at `(k + s)` faces: the face read at a target is the
//! target's place less `s`, and the certificate read is that face's. The
//! stage need not be exact (the closure measures how far it sat from each
//! turn); it must only stay put while a run is measured. The turn happens
//! before the first step of each run (and again on a resume, where the
//! stage may have been moved); a turn that fails is a reference fault,
//! retried with its recovery, and ends the survey `interrupted` when the
//! retries do not cure it.

use super::{Engine, EngineError, Failed, Reference};
use crate::record::SampleSink;
use std::time::Duration;
use survey_drivers::DriverError;
use survey_drivers::clock::with_timeout;
use survey_drivers::traits::Positioner;
use survey_plan::budget::Component;

/// The most a stage's turn may take, from its command to in position.
pub const TURN_TIMEOUT: Duration = Duration::from_secs(120);

/// The polygon's stage and the orientation of each run.
#[derive(Debug)]
pub struct PolygonStage {
    /// `None`: the operator turns it.
    stage: Option<Box<dyn Positioner>>,
    /// Faces turned in run `r` (from 1): `orientations[(r - 1) % len]`.
    orientations: Vec<u32>,
    /// Where the stage was last turned to, faces (`None`: not yet).
    turned: Option<u32>,
}

impl PolygonStage {
    /// The polygon turned by `orientations[(run - 1) % len]` faces in run `run`.
    pub fn new(stage: Box<dyn Positioner>, orientations: Vec<u32>) -> Self {
        Self { stage: Some(stage), orientations, turned: None }
    }

    /// The polygon turned by hand: see the module documentation.
    pub fn by_operator(orientations: Vec<u32>) -> Self {
        Self { stage: None, orientations, turned: None }
    }

    /// The faces turned in `run` (from 1).
    pub fn orientation_of_run(&self, run: u32) -> u32 {
        match self.orientations.len() {
            0 => 0,
            n => self.orientations[(run.max(1) - 1) as usize % n],
        }
    }
}

impl Engine {
    /// The polygon stands on `stage`, turned by the orientations (faces, one
    /// per run, repeated when the runs outnumber them).
    pub fn with_polygon_stage(mut self, stage: PolygonStage) -> Self {
        self.polygon = Some(stage);
        self
    }

    /// How many faces the polygon is turned by now (0 without a stage).
    pub(super) fn polygon_turn(&self) -> u32 {
        self.polygon.as_ref().and_then(|p| p.turned).unwrap_or(0)
    }

    /// The face of a polygon of `faces` the autocollimator sees with the
    /// table near `near_deg`.
    pub(super) fn face_at(&self, near_deg: f64, faces: u32) -> u32 {
        face_seen(near_deg, faces, self.polygon_turn())
    }

    /// Turn the polygon to `run`'s orientation, unless it is there.
    pub(super) async fn turn_polygon_for(&mut self, run: u32, sink: &mut dyn SampleSink) -> Result<(), EngineError> {
        let Reference::Autocollimator { faces, .. } = &self.reference else { return Ok(()) };
        let faces = *faces;
        let Some(p) = &self.polygon else { return Ok(()) };
        let want = p.orientation_of_run(run);
        if p.turned == Some(want) {
            return Ok(());
        }
        let target = f64::from(want) * 360.0 / f64::from(faces);
        if p.stage.is_none() {
            return self.ask_the_operator(run, want, target, sink).await;
        }
        let what = format!("turning the polygon by {want} faces ({target} deg) for run {run}");
        let mut attempt = 0;
        loop {
            self.ledger.switch(self.clock.now(), Component::Move);
            match self.try_turn(target).await {
                Ok(()) => break,
                Err(e) => {
                    attempt += 1;
                    self.survive(e, Failed::Reference, attempt, &what, sink).await?;
                }
            }
        }
        if let Some(p) = &mut self.polygon {
            p.turned = Some(want);
        }
        let message = format!("polygon turned by {want} faces ({target} deg) relative to the table for run {run}");
        tracing::info!("{message}");
        sink.event(self.clock.now().as_secs_f64(), "info", &message).await.map_err(EngineError::Sink)
    }

    /// Without a stage: the polygon taken as set up when the survey starts
    /// or resumes, else the survey stopped for the operator to turn it.
    async fn ask_the_operator(
        &mut self,
        run: u32,
        want: u32,
        target: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<(), EngineError> {
        let at = self.clock.now().as_secs_f64();
        let p = self.polygon.as_mut().expect("a polygon");
        match p.turned {
            None => {
                p.turned = Some(want);
                let message = format!(
                    "the polygon taken as turned by {want} faces ({target} deg) relative to the table for run {run}, \
                     as the operator set it up"
                );
                tracing::info!("{message}");
                sink.event(at, "info", &message).await.map_err(EngineError::Sink)
            }
            Some(was) => {
                let message = format!(
                    "run {run} reads the polygon turned by {want} faces relative to the table, and it is turned by \
                     {was}: turn it on the table so that its face 0 is read with the table at {target} deg, then run \
                     `survey resume` (the survey is interrupted, nothing is lost)"
                );
                tracing::warn!("{message}");
                sink.event(at, "warn", &message).await.map_err(EngineError::Sink)?;
                Err(EngineError::Suspended(message))
            }
        }
    }

    /// Command the stage to `target_deg` and wait until it reports in
    /// position, every call bounded; a fault or a limit it reports is a
    /// device fault of the stage.
    async fn try_turn(&mut self, target_deg: f64) -> Result<(), DriverError> {
        let clock = self.clock.clone();
        let t = self.timing.clone();
        let stage = self.polygon.as_mut().and_then(|p| p.stage.as_mut()).expect("a stage");
        let name = stage.name().to_string();
        with_timeout(&*clock, t.call_timeout, &name, "move command", stage.move_to(target_deg)).await?;
        let deadline = clock.now() + TURN_TIMEOUT;
        loop {
            clock.sleep(t.poll_interval).await;
            let s = with_timeout(&*clock, t.call_timeout, &name, "status", stage.status()).await?;
            if let Some(f) = &s.fault {
                let _ = with_timeout(&*clock, t.call_timeout, &name, "clear fault", stage.clear_fault()).await;
                return Err(DriverError::device(&name, f.code, format!("the polygon's stage faulted: {}", f.text)));
            }
            if let Some(limit) = s.limit {
                return Err(DriverError::device(&name, 0, format!("the polygon's stage is at its {limit:?} limit")));
            }
            if s.in_position && !s.moving {
                return Ok(());
            }
            if clock.now() >= deadline {
                // Connected and answering, but not getting there: the device's.
                return Err(DriverError::device(
                    &name,
                    0,
                    format!("the polygon's stage is not in position at {target_deg} deg after {TURN_TIMEOUT:?}"),
                ));
            }
        }
    }
}

/// The face seen with the table near `near_deg` and the polygon turned by
/// `turned` faces.
pub(super) fn face_seen(near_deg: f64, faces: u32, turned: u32) -> u32 {
    let place = (near_deg / 360.0 * f64::from(faces)).round().rem_euclid(f64::from(faces)) as u32;
    (place + faces - turned % faces) % faces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Timing;
    use crate::record::{MemorySink, RawReading};
    use std::sync::Arc;
    use survey_drivers::{Clock, VirtualClock};
    use survey_plan::SurveyPlan;
    use survey_sims::autocollimator::AutocollimatorConfig;
    use survey_sims::bench::index_stage;
    use survey_sims::{Preset, SimBench};

    /// A 12-face polygon on a stage turned `turns`, the fig8 axis without
    /// noise; the stage's configuration changed by `stage`.
    fn engine(turns: Vec<u32>, stage: impl FnOnce(&mut survey_sims::PositionerConfig), tracker: bool) -> Engine {
        let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
        let mut cfg = index_stage(3);
        stage(&mut cfg);
        let bench = SimBench::builder(&Preset::by_name("fig8").unwrap(), 5, clock.clone())
            .autocollimator(AutocollimatorConfig::seeded(12, 9))
            .polygon_stage(cfg)
            .without_noise()
            .build();
        let timing = Timing {
            velocity_deg_s: bench.positioner.config().velocity_deg_s,
            accel_deg_s2: bench.positioner.config().accel_deg_s2,
            ..Timing::default()
        };
        let reference = if tracker {
            Reference::Tracker(Box::new(bench.tracker))
        } else {
            Reference::Autocollimator {
                faces: 12,
                certificate_arcsec: bench.autocollimator.certificate_arcsec().to_vec(),
                instrument: Box::new(bench.autocollimator),
            }
        };
        let stage = bench.polygon_stage.expect("a stage");
        Engine::new(clock, Box::new(bench.positioner), reference, timing)
            .with_polygon_stage(PolygonStage::new(Box::new(stage), turns))
    }

    #[tokio::test]
    async fn each_run_reads_the_faces_its_turn_brings_and_says_so() {
        let mut e = engine(vec![0, 1, 5], |_| {}, false);
        let plan = SurveyPlan::full_circle(12, 4, false).unwrap();
        let mut sink = MemorySink::default();
        e.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
        assert_eq!(sink.samples.len(), 48);
        for r in &sink.samples {
            let RawReading::Autocollimator { face, .. } = r.raw else { panic!("{:?}", r.raw) };
            let place = (r.sample.target_deg / 30.0).round() as u32;
            // Runs 1..4 at turns 0, 1, 5, then 0 again.
            let turn = [0, 1, 5, 0][r.sample.run as usize - 1];
            assert_eq!(face, (place + 12 - turn) % 12, "run {} at {} deg", r.sample.run, r.sample.target_deg);
            // Read through the face's certificate, at the table's place: the
            // actual angle near the target (the stage's error of an arcsec or
            // two and the axis's fig8 error of about 0.015 deg aside).
            assert!((r.sample.actual_deg - r.sample.target_deg).abs() < 0.02, "{:?}", r.sample);
        }
        let turned: Vec<&String> =
            sink.events.iter().filter(|e| e.2.contains("polygon turned")).map(|e| &e.2).collect();
        assert_eq!(turned.len(), 4, "{turned:?}");
        assert!(turned[2].contains("by 5 faces (150 deg)") && turned[2].contains("run 3"), "{}", turned[2]);
    }

    #[tokio::test]
    async fn a_stage_that_faults_on_every_move_ends_the_survey_naming_it() {
        let mut e = engine(vec![0, 1], |c| c.faults.fault_probability_per_move = 1.0, false);
        let plan = SurveyPlan::full_circle(12, 2, false).unwrap();
        let mut sink = MemorySink::default();
        let err = e.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("sim-polygon-stage") && text.contains("faulted"), "{text}");
        assert!(sink.samples.is_empty(), "nothing measured on an unturned polygon");
        let retried = sink.events.iter().filter(|e| e.2.contains("turning the polygon by 0 faces")).count();
        assert_eq!(retried as u32, Timing::default().max_retries + 1, "each attempt logged");
    }

    #[tokio::test]
    async fn a_stage_under_a_tracker_or_a_continuous_scan_is_refused() {
        let mut e = engine(vec![0, 1], |_| {}, true);
        let plan = SurveyPlan::full_circle(12, 2, false).unwrap();
        let err = e.run(&plan, 0, &mut MemorySink::default(), &mut |_| {}).await.unwrap_err();
        assert!(format!("{err}").contains("autocollimator reads"), "{err}");
        let mut e = engine(vec![0, 1], |_| {}, false);
        let mut plan = SurveyPlan::full_circle(12, 2, false).unwrap();
        plan.scan = survey_plan::ScanMode::Continuous;
        let err = e.run(&plan, 0, &mut MemorySink::default(), &mut |_| {}).await.unwrap_err();
        assert!(format!("{err}").contains("use --scan step"), "{err}");
    }

    /// The operator turns the polygon: the survey stops before run 2 asking
    /// for the turn, the operator turns it (the simulated stage placed by
    /// hand), and the survey resumed reads run 2 on the turned faces.
    #[tokio::test]
    async fn without_a_stage_the_operator_is_asked_to_turn_it_and_the_resume_confirms() {
        let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
        let build = || {
            SimBench::builder(&Preset::by_name("fig8").unwrap(), 5, clock.clone())
                .autocollimator(AutocollimatorConfig::seeded(12, 9))
                .polygon_stage(index_stage(3))
                .without_noise()
                .build()
        };
        let plan = SurveyPlan::full_circle(12, 2, false).unwrap();
        let engine_on = |bench: SimBench| {
            let timing = Timing {
                velocity_deg_s: bench.positioner.config().velocity_deg_s,
                accel_deg_s2: bench.positioner.config().accel_deg_s2,
                ..Timing::default()
            };
            let by_hand = bench.polygon_stage.as_ref().expect("a stage").truth();
            let reference = Reference::Autocollimator {
                faces: 12,
                certificate_arcsec: bench.autocollimator.certificate_arcsec().to_vec(),
                instrument: Box::new(bench.autocollimator),
            };
            let e = Engine::new(clock.clone(), Box::new(bench.positioner), reference, timing)
                .with_polygon_stage(PolygonStage::by_operator(vec![0, 1]));
            (e, by_hand)
        };
        let (mut e, by_hand) = engine_on(build());
        let mut sink = MemorySink::default();
        let err = e.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap_err();
        let text = format!("{err}");
        assert!(matches!(err, EngineError::Suspended(_)), "{err:?}");
        assert!(text.contains("turned by 1 faces") && text.contains("at 30 deg") && text.contains("survey resume"));
        assert_eq!(sink.samples.len(), 12, "run 1 measured, run 2 not begun");
        // The operator turns it by one face, and the survey resumes.
        by_hand.place(30.0);
        let bench = build();
        bench.polygon_stage.as_ref().unwrap().truth().place(30.0);
        let (mut e, _) = engine_on(bench);
        e.run(&plan, 12, &mut sink, &mut |_| {}).await.unwrap();
        assert_eq!(sink.samples.len(), 24);
        for r in &sink.samples[12..] {
            let RawReading::Autocollimator { face, .. } = r.raw else { panic!("{:?}", r.raw) };
            let place = (r.sample.target_deg / 30.0).round() as u32;
            assert_eq!(face, (place + 11) % 12, "run 2 at {} deg", r.sample.target_deg);
            // Read on the face the operator turned there: the actual angle
            // near the target (the axis's fig8 error of 0.015 deg aside).
            assert!((r.sample.actual_deg - r.sample.target_deg).abs() < 0.02, "{:?}", r.sample);
        }
    }

    #[test]
    fn the_face_seen_is_the_place_less_the_turn() {
        assert_eq!(face_seen(0.0, 24, 0), 0);
        assert_eq!(face_seen(15.0, 24, 1), 0);
        assert_eq!(face_seen(0.0, 24, 1), 23);
        assert_eq!(face_seen(359.99, 24, 0), 0);
        assert_eq!(face_seen(-15.0, 24, 2), 21);
    }
}
