//! The engine's side of drift control ([`survey_plan::drift`]): before step 0 of
//! a pass (or the step a resume starts at) and every K-th step, the axis goes
//! to the reference target (approached forward) and the pair is read there;
//! the run loop writes the measurement to the sink outside the race with a
//! stop request (a stop never cancels a write). Moves and reads race a stop
//! like a step's, and their faults are survived the same way.

use super::{Engine, EngineError};
use crate::record::SampleSink;
use survey_plan::drift::DriftMeasurement;
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
    use crate::record::{MemorySink, RawReading};
    use survey_drivers::VirtualClock;
    use survey_plan::drift::{DriftControl, correct, drift_points};
    use survey_processing::model::Model;
    use survey_processing::types::wrap_180;
    use survey_processing::{Direction, Sample};
    use survey_sims::tracker::ArmGeometry;
    use survey_sims::{Preset, SimBench};

    /// The Figure 8 positioner with a ramp drift of 0.01 deg per run, one run
    /// every 600 s of instrument time, no noise anywhere; returns what was
    /// measured, the model without its drift, and the tracker's arm.
    fn drifting_survey(every_steps: Option<u64>) -> (MemorySink, Model, ArmGeometry) {
        let preset = Preset::default();
        let mut text = preset.model.to_toml();
        text += "\n[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.01\nshape = \"ramp\"\n";
        let model = Model::parse(&text, "drift.toml").unwrap();
        let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
        let builder = SimBench::builder(&preset, 21, clock.clone())
            .model(model.clone())
            .drift_run_period(Duration::from_secs(600))
            .without_noise()
            .without_motions();
        let arm = builder.tracker.arm.clone();
        let bench = builder.build();
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
        (sink, model, arm)
    }

    /// The true axis angle of an SMR position (noise off: exact), near `near`.
    fn true_angle(arm: &ArmGeometry, p: [f64; 3], near: f64) -> f64 {
        let (u, v, _) = arm.basis();
        let c = arm.circle_center_mm();
        let d: [f64; 3] = std::array::from_fn(|i| p[i] - c[i]);
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let raw = dot(d, v).atan2(dot(d, u)).to_degrees() - arm.arm_phase_deg;
        near + wrap_180(raw - near)
    }

    /// The slope of the model's error at `theta` (deg/deg).
    fn slope(m: &Model, theta: f64, dir: Direction) -> f64 {
        let h = 1e-4;
        (m.systematic_error_deg(theta + h, dir, 0.0) - m.systematic_error_deg(theta - h, dir, 0.0)) / (2.0 * h)
    }

    /// The drift-free readout error at readout `r` after a drift `d`: the
    /// servo holds the readout, so the true angle `a` solves `a + e(a) + d = r`.
    fn error_at_readout(m: &Model, r: f64, dir: Direction, d: f64) -> f64 {
        let mut a = r;
        for _ in 0..100 {
            a = r - d - m.systematic_error_deg(a, dir, 0.0);
        }
        r - a
    }

    fn spread(x: &[f64]) -> f64 {
        x.iter().cloned().fold(f64::MIN, f64::max) - x.iter().cloned().fold(f64::MAX, f64::min)
    }

    /// What is left after the correction, accounted for exactly. At a fixed
    /// readout `r` (how a survey indexes its errors and a table is read) a
    /// drift `D` moves the true angle by `-D / (1 + P'(r))`, `P'` the error's
    /// slope there, so the readout error changes by `D / (1 + P'(r))`. The
    /// reference measures that at its own readout, `D / (1 + P'_ref)`, and the
    /// correction removes it from every sample; what is left at target `r`
    /// is `(D(t) - D(t0)) (1 / (1 + P'(r)) - 1 / (1 + P'_ref))`, about
    /// `D (P'_ref - P'(r))`: the drift's effect differs from target to target
    /// by the error's slope, which no single reference can see. Nothing of the
    /// interpolation in time is left (the ramp is linear between reference
    /// measurements) and the time stamps of samples and references lag their
    /// rest by the same settle, dwell and measurement, within one poll.
    ///
    /// (An earlier version of this test compared with the model's error at
    /// the *measured* angle, which carries the axis zero `c`, 4.5e-3 deg here:
    /// that added `c P'(theta)` to every residual, constant in time and
    /// varying with the target, the "unexplained" 0.5 % it reported.)
    #[test]
    fn the_reference_is_measured_every_k_steps_and_the_correction_removes_the_simulated_drift() {
        let (sink, truth, arm) = drifting_survey(Some(6));
        let samples: Vec<Sample> = sink.samples.iter().map(|r| r.sample).collect();
        assert_eq!(samples.len(), 48, "every step once; the reference measurements are not samples");
        let seqs: Vec<u64> = sink.drift.iter().map(|m| m.before_seq).collect();
        assert_eq!(seqs, [0, 6, 12, 18, 24, 30, 36, 42, 48], "every 6 steps, and after the last");
        let points = drift_points(&sink.drift);

        // The true angle of every sample, from its SMR position; the measured
        // one differs by the axis zero `c` (a constant: the zero is set so the
        // located points' mean error is zero).
        let truths: Vec<f64> = sink
            .samples
            .iter()
            .map(|r| match r.raw {
                RawReading::Smr(m) => true_angle(&arm, m.xyz(), r.sample.target_deg),
                _ => unreachable!("a tracker survey"),
            })
            .collect();
        let c = samples[0].actual_deg - truths[0];
        for (s, a) in samples.iter().zip(&truths) {
            assert!((s.actual_deg - a - c).abs() < 1e-9, "the axis zero is one constant");
        }
        // The simulated drift of each sample, and at the first reference.
        let drift_of = |r: f64, a: f64, dir| r - a - truth.systematic_error_deg(a, dir, 0.0);
        let d: Vec<f64> = samples.iter().zip(&truths).map(|(s, a)| drift_of(s.readout_deg, *a, s.direction)).collect();
        let first = &sink.drift[0];
        let a_ref = first.actual_deg - c;
        let d0 = drift_of(first.readout_deg, a_ref, Direction::Forward);
        let p_ref = slope(&truth, a_ref, Direction::Forward);

        // The measured drift is the simulated one seen at the reference's
        // readout, D / (1 + P'_ref).
        for (p, m) in points.iter().zip(&sink.drift) {
            let dk = drift_of(m.readout_deg, m.actual_deg - c, Direction::Forward);
            let want = error_at_readout(&truth, m.readout_deg, Direction::Forward, dk)
                - error_at_readout(&truth, m.readout_deg, Direction::Forward, d0);
            assert!((p.drift_deg - want).abs() < 1e-10, "at {} s: {} against {want}", p.at_s, p.drift_deg);
            // To first order D / (1 + P'_ref); the second order (the slope
            // changes over the D the true angle moves) is below 1e-7 deg here.
            assert!((p.drift_deg - (dk - d0) / (1.0 + p_ref)).abs() < 1e-7, "at {} s", p.at_s);
        }

        // The residual of every corrected sample against the drift-free
        // error at its readout (the survey's error as of the first reference,
        // drift D(t0)), and what the account above predicts for it.
        let corrected = correct(&samples, &points);
        let mut residual = Vec::new();
        let mut predictions = Vec::new();
        let mut worst_left = 0.0f64;
        let mut worst_miss = 0.0f64;
        for (k, s) in corrected.iter().enumerate() {
            let want = error_at_readout(&truth, s.readout_deg, s.direction, d0);
            let r = (s.readout_deg - s.actual_deg + c) - want;
            let p = slope(&truth, truths[k], s.direction);
            // The drift since t0 at this readout, less the same seen at the
            // reference's (exact; to first order the formula above, within 1e-7).
            let at = |r: f64, dir| error_at_readout(&truth, r, dir, d[k]) - error_at_readout(&truth, r, dir, d0);
            let predicted = at(s.readout_deg, s.direction) - at(first.readout_deg, Direction::Forward);
            let first_order = (d[k] - d0) * (1.0 / (1.0 + p) - 1.0 / (1.0 + p_ref));
            assert!((predicted - first_order).abs() < 1e-7, "sample {k}: {predicted} against {first_order}");
            // The drift froze when the axis came to rest and each time stamp
            // follows the rest by settle + dwell + measurement and up to one
            // 0.1 s poll, for samples and references alike: the interpolated
            // drift is off by at most 0.01 deg / 600 s x 0.1 s = 1.7e-6 deg.
            assert!(
                (r - predicted).abs() < 1.7e-6,
                "sample {k} (target {}, {}): residual {r:.3e}, predicted {predicted:.3e}",
                s.target_deg,
                s.direction
            );
            residual.push(r);
            predictions.push(predicted);
            worst_left = worst_left.max(predicted.abs());
            worst_miss = worst_miss.max((r - predicted).abs());
            // And without the correction, the whole drift since t0 is there.
            let raw = samples[k].readout_deg - samples[k].actual_deg + c - want;
            assert!((raw - at(s.readout_deg, s.direction)).abs() < 1e-10, "sample {k}: {raw}");
        }
        let before: Vec<f64> = samples
            .iter()
            .map(|s| (s.readout_deg - s.actual_deg + c) - error_at_readout(&truth, s.readout_deg, s.direction, d0))
            .collect();
        // Measured: the spread falls from 8.7e-3 to 5.9e-5 deg (0.67 % of the
        // drift), all of it the slope term (what is not is below 1.2e-7 deg);
        // the slope term is at most 2 max|P'| / (1 - max|P'|) of the drift
        // (max|P'| over the whole circle: 0.42 % on this positioner).
        let drift_span = spread(&d);
        let max_slope = (0..36_000)
            .map(|k| k as f64 / 100.0)
            .flat_map(|t| [slope(&truth, t, Direction::Forward), slope(&truth, t, Direction::Reverse)])
            .fold(0.0f64, |m, p| m.max(p.abs()));
        assert!(spread(&before) > 0.005 && (spread(&before) - drift_span).abs() < 1e-4, "{}", spread(&before));
        let bound = drift_span * 2.0 * max_slope / (1.0 - max_slope);
        assert!(worst_left <= bound, "the slope term {worst_left:.3e} is within {bound:.3e} (max|P'| {max_slope:.3e})");
        assert!(
            spread(&residual) <= spread(&predictions) + 2.0 * 1.7e-6,
            "corrected spread {} against the slope term's {}",
            spread(&residual),
            spread(&predictions)
        );
        eprintln!(
            "drift {drift_span:.3e} deg; spread before {:.3e}, after {:.3e}; slope term: spread {:.3e}, at most \
             {worst_left:.3e} (bound {bound:.3e}, max|P'| {max_slope:.3e}, P'_ref {p_ref:.3e}); residual less the \
             slope term at most {worst_miss:.2e}",
            spread(&before),
            spread(&residual),
            spread(&predictions)
        );
    }

    #[test]
    fn without_drift_control_no_reference_is_measured() {
        let (sink, _, _) = drifting_survey(None);
        assert!(sink.drift.is_empty());
        assert_eq!(sink.samples.len(), 48);
    }
}
