//! The engine's side of drift control ([`crate::drift`]): before step 0 of
//! a pass (or the step a resume starts at) and every K-th step, the axis goes
//! to the reference target (approached forward) and the pair is read there;
//! the run loop writes the measurement to the sink outside the race with a
//! stop request (a stop never cancels a write). Moves and reads race a stop
//! like a step's, and their faults are survived the same way.

use super::{Engine, EngineError};
use crate::drift::DriftMeasurement;
use crate::record::SampleSink;
use survey_processing::Direction;

impl Engine {
    /// Measure the reference target before step `seq` when it is due.
    pub(super) async fn drift_reference(
        &mut self,
        seq: u64,
        from_seq: u64,
        overrun: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<Option<DriftMeasurement>, EngineError> {
        let Some(control) = self.drift.clone() else { return Ok(None) };
        if !control.due(seq, from_seq) {
            return Ok(None);
        }
        let target = control.reference_deg;
        let (readout, raw) = self.measure(target, Direction::Forward, overrun, sink).await?;
        let actual = self.actual_deg(target, &raw)?;
        let m = DriftMeasurement {
            before_seq: seq,
            at_s: self.clock.now().as_secs_f64(),
            reference_deg: target,
            readout_deg: readout,
            actual_deg: actual,
        };
        tracing::debug!(seq, error_deg = m.error_deg(), "drift control: reference measured");
        Ok(Some(m))
    }

    /// After the last step of a pass that measured any, the reference once
    /// more, so every sample lies between two reference measurements (the
    /// drift is interpolated, never extrapolated). Raced against a stop like
    /// a step; written after.
    pub(super) async fn drift_closing(
        &mut self,
        total: u64,
        from_seq: u64,
        overrun: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<(), EngineError> {
        if self.drift.is_none() || from_seq >= total {
            return Ok(());
        }
        let mut stop = self.stop.clone();
        let measured = tokio::select! {
            biased;
            why = stop.wait() => Err(why),
            r = self.drift_reference(total, total, overrun, sink) => Ok(r),
        };
        match measured {
            Ok(r) => {
                if let Some(m) = r? {
                    sink.drift_measured(&m).await.map_err(EngineError::Sink)?;
                }
                sink.flush().await.map_err(EngineError::Sink)
            }
            Err(why) => Err(self.halt(why).await),
        }
    }

    /// The reference target, approached forward from below by the overrun,
    /// within the travel `lo..=hi`, or why not.
    pub(super) fn check_drift_travel(&self, lo: f64, hi: f64, overrun: f64) -> Result<(), EngineError> {
        let Some(control) = &self.drift else { return Ok(()) };
        let (from, to) = (control.reference_deg - overrun, control.reference_deg);
        if from < lo || to > hi {
            return Err(EngineError::Plan(format!(
                "the drift reference at {to} deg is approached from {from} deg, outside the travel {lo}..{hi} deg"
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use crate::drift::{DriftControl, correct, drift_points};
    use crate::record::MemorySink;
    use survey_drivers::VirtualClock;
    use survey_processing::Direction;
    use survey_processing::model::Model;
    use survey_sims::{Preset, SimBench};

    /// The Figure 8 positioner with a ramp drift of 0.01 deg per run, one run
    /// every 600 s of instrument time, no noise anywhere.
    fn drifting_survey(every_steps: Option<u64>) -> (MemorySink, Model) {
        let preset = Preset::default();
        let mut text = preset.model.to_toml();
        text += "\n[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.01\nshape = \"ramp\"\n";
        let model = Model::parse(&text, "drift.toml").unwrap();
        let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
        let bench = SimBench::builder(&preset, 21, clock.clone())
            .model(model.clone())
            .drift_run_period(Duration::from_secs(600))
            .without_noise()
            .build();
        let cfg = bench.positioner.config();
        let timing = Timing { velocity_deg_s: cfg.velocity_deg_s, accel_deg_s2: cfg.accel_deg_s2, ..Timing::default() };
        let mut engine =
            Engine::new(clock, Box::new(bench.positioner), Reference::Tracker(Box::new(bench.tracker)), timing);
        engine.set_drift_control(every_steps.map(|k| DriftControl {
            every_steps: k,
            reference_deg: 0.0,
            correct: true,
        }));
        let plan = SurveyPlan::full_circle(12, 2, true).unwrap();
        let mut sink = MemorySink::default();
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
            .block_on(engine.run(&plan, 0, &mut sink, &mut |_| {}))
            .unwrap();
        let model = Model::parse(&preset.model.to_toml(), "no-drift.toml").unwrap();
        (sink, model)
    }

    /// Each sample's readout error less the simulator's true error without
    /// drift: the drift plus a constant (the axis zero).
    fn residuals(samples: &[survey_processing::Sample], truth: &Model) -> Vec<f64> {
        samples
            .iter()
            .map(|s| (s.readout_deg - s.actual_deg) - truth.systematic_error_deg(s.actual_deg, s.direction, 0.0))
            .collect()
    }

    fn spread(x: &[f64]) -> f64 {
        x.iter().cloned().fold(f64::MIN, f64::max) - x.iter().cloned().fold(f64::MAX, f64::min)
    }

    #[test]
    fn the_reference_is_measured_every_k_steps_and_the_correction_removes_the_simulated_drift() {
        let (sink, truth) = drifting_survey(Some(6));
        let samples: Vec<_> = sink.samples.iter().map(|r| r.sample).collect();
        assert_eq!(samples.len(), 48, "every step once; the reference measurements are not samples");
        let seqs: Vec<u64> = sink.drift.iter().map(|m| m.before_seq).collect();
        assert_eq!(seqs, [0, 6, 12, 18, 24, 30, 36, 42, 48], "every 6 steps, and after the last");
        let points = drift_points(&sink.drift);
        // At the reference the readout is fixed, so a drift D moves the true
        // angle by -D and the periodic error P with it: the reference's error
        // changes by D / (1 + P'), P' the slope of the error there (deg/deg).
        let h = 1e-4;
        let slope = (truth.systematic_error_deg(h, Direction::Forward, 0.0)
            - truth.systematic_error_deg(-h, Direction::Forward, 0.0))
            / (2.0 * h);
        let t0 = points[0].at_s;
        for p in &points {
            let want = 0.01 * (p.at_s - t0) / 600.0 / (1.0 + slope);
            // The drift freezes when the axis comes to rest; the reading follows
            // after the settle, a poll of up to 0.1 s and the dwell, a lag that
            // varies by up to 0.4 s from one target to another: 0.01/600 deg/s x
            // 0.4 s = 7e-6 deg.
            assert!((p.drift_deg - want).abs() < 7e-6, "at {} s: {} against {want}", p.at_s, p.drift_deg);
        }
        let before = residuals(&samples, &truth);
        let after = residuals(&correct(&samples, &points), &truth);
        // Uncorrected, the residual follows the ramp over the survey's duration.
        let duration = samples.last().unwrap().timestamp_s.unwrap() - samples[0].timestamp_s.unwrap();
        assert!((spread(&before) - 0.01 * duration / 600.0).abs() < 2e-4, "spread {}", spread(&before));
        assert!(spread(&before) > 0.005);
        // Corrected, the residual's spread falls from 8.8e-3 to 8.9e-5 deg
        // (measured). Part of what is left is the reference's bias D P'/(1 + P')
        // (the Figure 8 error's slope is at most 0.6 %); the rest, about 0.5 %
        // of the drift, varies with the target like the 20:1 gear sampled
        // every 30 deg, and is not accounted for yet. Bound: 1.5 % of the drift.
        assert!(slope.abs() < 0.006, "slope {slope}");
        assert!(spread(&after) < 0.015 * spread(&before), "corrected spread {} of {}", spread(&after), spread(&before));
    }

    #[test]
    fn without_drift_control_no_reference_is_measured() {
        let (sink, _) = drifting_survey(None);
        assert!(sink.drift.is_empty());
        assert_eq!(sink.samples.len(), 48);
    }
}
