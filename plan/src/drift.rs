//! Drift control: a reference target re-measured every K steps, the drift of
//! its readout error over time, and (optionally) the samples corrected for it.
//!
//! A positioner's error drifts as it warms up or its encoder's reference
//! moves; a survey of hours then mixes the positioner's error with its
//! drift. With `[drift_control] every_steps = K` the engine goes to the
//! reference target (`reference_deg`, approached forward, like the first pass)
//! before step 0, before every K-th step and after the last step of a pass
//! (so every sample lies between two), and measures the pair there as
//! at any target. The reference's readout error `e_ref(t) = readout - actual`
//! changes only by the drift (the target, the approach and so the systematic
//! error are the same every time), so `drift(t) = e_ref(t) - e_ref(t0)`,
//! `t0` the first reference measurement. Each measurement is stored
//! (`drift_points`, migration 2) and reported by `survey show` and `survey
//! stats`; [`DriftPoint`]s are the data of a drift-over-time plot.
//!
//! With `correct = true` the statistics and the processing (`survey stats`,
//! `survey process`, and those at the end of `run` and `resume`) use samples
//! corrected for it: `actual' = actual + drift(t)`, so `error' = error -
//! drift(t)`, `drift(t)` interpolated linearly in time between the reference
//! measurements (held at the ends). What one reference cannot remove: at a
//! fixed readout a drift `D` changes the readout error by `D / (1 + P')`, `P'`
//! the error's slope there, so a target whose slope differs from the
//! reference's keeps `D (P'_ref - P'(r))` to first order (at most
//! `2 max|P'|` of the drift; measured and bounded in the orchestrator's
//! engine tests).
//! The stored samples stay as measured;
//! `survey export` and `survey model-gap` see them as measured (model-gap
//! names a drift as an effect of the model).

use serde::{Deserialize, Serialize};
use survey_processing::Sample;
use survey_processing::units::Units;

/// `[drift_control]` of a configuration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriftControl {
    /// Re-measure the reference before every `every_steps`-th step (at least 1).
    pub every_steps: u64,
    /// The reference target, degrees (readout).
    #[serde(default)]
    pub reference_deg: f64,
    /// Correct the samples for the drift in the statistics and processing.
    #[serde(default)]
    pub correct: bool,
}

impl DriftControl {
    /// The setting's defects, named by key.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=1_000_000).contains(&self.every_steps) {
            return Err(format!("drift_control.every_steps = {} is outside 1..=1000000", self.every_steps));
        }
        if !(self.reference_deg.is_finite() && self.reference_deg.abs() <= 3600.0) {
            return Err(format!(
                "drift_control.reference_deg = {} is not an angle within +/-3600 deg",
                survey_processing::num::Num(self.reference_deg)
            ));
        }
        Ok(())
    }

    /// Whether the reference is measured before step `seq` of a pass that
    /// starts (or resumes) at `from_seq`: at the start, and every K-th step.
    pub fn due(&self, seq: u64, from_seq: u64) -> bool {
        seq == from_seq || seq.is_multiple_of(self.every_steps)
    }
}

/// One measurement of the reference target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DriftMeasurement {
    /// Measured before this step of the plan.
    pub before_seq: u64,
    /// Instrument time, s.
    pub at_s: f64,
    /// The reference target, deg.
    pub reference_deg: f64,
    /// What the positioner displayed there, deg.
    pub readout_deg: f64,
    /// What the reference instrument measured there, deg.
    pub actual_deg: f64,
}

impl DriftMeasurement {
    /// The readout error there, `readout - actual`, deg.
    pub fn error_deg(&self) -> f64 {
        self.readout_deg - self.actual_deg
    }
}

/// A point of the drift over time: what a plot draws.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DriftPoint {
    /// Instrument time, s.
    pub at_s: f64,
    /// The drift since the first reference measurement, deg.
    pub drift_deg: f64,
    /// Measured before this step.
    pub before_seq: u64,
}

/// The drift over time of a survey's reference measurements (in time order).
pub fn drift_points(measurements: &[DriftMeasurement]) -> Vec<DriftPoint> {
    let mut m = measurements.to_vec();
    m.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    let Some(first) = m.first().map(DriftMeasurement::error_deg) else { return Vec::new() };
    m.iter().map(|p| DriftPoint { at_s: p.at_s, drift_deg: p.error_deg() - first, before_seq: p.before_seq }).collect()
}

/// The drift at time `t`: linear between the points, held beyond them.
pub fn drift_at(points: &[DriftPoint], t: f64) -> f64 {
    match points {
        [] => 0.0,
        [only] => only.drift_deg,
        _ => {
            let i = points.partition_point(|p| p.at_s <= t);
            if i == 0 {
                return points[0].drift_deg;
            }
            if i == points.len() {
                return points[i - 1].drift_deg;
            }
            let (a, b) = (points[i - 1], points[i]);
            let span = b.at_s - a.at_s;
            if span <= 0.0 {
                return b.drift_deg;
            }
            a.drift_deg + (b.drift_deg - a.drift_deg) * (t - a.at_s) / span
        }
    }
}

/// The samples corrected for the drift: `actual + drift(t)` (a sample
/// without a time is left as it is).
pub fn correct(samples: &[Sample], points: &[DriftPoint]) -> Vec<Sample> {
    samples
        .iter()
        .map(|s| match s.timestamp_s {
            Some(t) if !points.is_empty() => Sample { actual_deg: s.actual_deg + drift_at(points, t), ..*s },
            _ => *s,
        })
        .collect()
}

/// The samples the statistics and the processing use: as measured, or
/// corrected for the drift when the survey asked for it (`correct`) and
/// the reference was measured.
pub fn for_analysis<'a>(
    correct_asked: bool,
    samples: &'a [Sample],
    points: &[DriftPoint],
) -> std::borrow::Cow<'a, [Sample]> {
    if correct_asked && !points.is_empty() { correct(samples, points).into() } else { samples.into() }
}

/// The drift table of `survey show` and `survey stats`, the drift in `units`.
pub fn text(points: &[DriftPoint], units: Units) -> String {
    if points.is_empty() {
        return String::new();
    }
    let column = format!("drift_{}", units.symbol());
    let mut out = format!("drift of the reference target (drift control):\n      time_s   before_step {column:>13}\n");
    for p in points {
        out += &format!("{:>12.1} {:>13} {:>13}\n", p.at_s, p.before_seq, units.small(p.drift_deg, 3, false));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_processing::Direction;

    fn m(seq: u64, at_s: f64, error: f64) -> DriftMeasurement {
        DriftMeasurement { before_seq: seq, at_s, reference_deg: 0.0, readout_deg: 0.0, actual_deg: -error }
    }

    #[test]
    fn drift_is_the_reference_error_since_the_first_measurement_interpolated_in_time() {
        let pts = drift_points(&[m(10, 100.0, 0.003), m(0, 0.0, 0.001), m(20, 200.0, 0.002)]);
        assert_eq!(pts.iter().map(|p| p.before_seq).collect::<Vec<_>>(), [0, 10, 20]);
        let d: Vec<f64> = pts.iter().map(|p| p.drift_deg).collect();
        assert!((d[0]).abs() < 1e-15 && (d[1] - 0.002).abs() < 1e-15 && (d[2] - 0.001).abs() < 1e-15);
        assert!((drift_at(&pts, 50.0) - 0.001).abs() < 1e-15);
        assert!((drift_at(&pts, 150.0) - 0.0015).abs() < 1e-15);
        assert_eq!(drift_at(&pts, -5.0), pts[0].drift_deg);
        assert_eq!(drift_at(&pts, 500.0), pts[2].drift_deg);
        assert_eq!(drift_at(&[], 5.0), 0.0);
        let s = Sample {
            run: 1,
            direction: Direction::Forward,
            target_deg: 5.0,
            readout_deg: 5.0,
            actual_deg: 4.99,
            timestamp_s: Some(150.0),
        };
        let c = correct(&[s, Sample { timestamp_s: None, ..s }], &pts);
        // The error drops by the drift: readout - (actual + drift).
        assert!(((c[0].readout_deg - c[0].actual_deg) - (0.01 - 0.0015)).abs() < 1e-12);
        assert_eq!(c[1], Sample { timestamp_s: None, ..s });
    }

    #[test]
    fn the_reference_is_due_at_the_start_and_every_k_steps() {
        let d = DriftControl { every_steps: 4, reference_deg: 0.0, correct: false };
        let due: Vec<u64> = (0..10).filter(|s| d.due(*s, 0)).collect();
        assert_eq!(due, [0, 4, 8]);
        let due: Vec<u64> = (5..10).filter(|s| d.due(*s, 5)).collect();
        assert_eq!(due, [5, 8]);
        assert!(DriftControl { every_steps: 0, ..d.clone() }.check().unwrap_err().contains("every_steps"));
        assert!(DriftControl { reference_deg: f64::NAN, ..d }.check().unwrap_err().contains("reference_deg"));
    }
}
