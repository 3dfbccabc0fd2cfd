//! The acquisition's pure arithmetic: the plan (this file), the instrument
//! time it costs (`budget`), the pairing of continuous streams (`pairing`)
//! and drift control (`drift`). Data in, data out, like `survey-processing`
//! (a test there checks this crate too): the acquisition
//! (`survey-acquire`) and the bench plan with it, the processing never does.
//!
//! # The plan
//!
//! The survey plan: targets, runs, directions, and the order of the steps.
//!
//! Each run is a forward pass over the targets approaching each from below,
//! then (bidirectional) an overrun past the last target and a reverse pass
//! approaching each from above, as ISO 230-2 prescribes. The steps are numbered
//! densely from 0 (`seq`): a stored sample is identified by its step, which is
//! how an interrupted survey resumes without losing or duplicating a sample.

pub mod budget;
pub mod drift;
pub mod pairing;

mod passes;

pub use passes::{
    CALIBRATION_ARC_DEG, CALIBRATION_VELOCITY_SHARE, PassPlan, ScanTiming, calibration_passes, passes, scan_order,
    start_deg, within_travel_for_scan,
};

use serde::{Deserialize, Serialize};
use std::time::Duration;
use survey_processing::Direction;
use survey_processing::errormap::Coverage;
use survey_processing::num::Num;

/// What to measure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurveyPlan {
    /// Target readout angles in ascending order, degrees.
    pub targets_deg: Vec<f64>,
    /// Number of runs (ISO 230-2 asks for 5).
    pub runs: u32,
    /// Measure the reverse pass too.
    pub bidirectional: bool,
    /// How far past a target the axis goes before approaching it from the
    /// other side, degrees (takes up backlash before the first target of a pass).
    pub overrun_deg: f64,
    /// Stop at every target (`step`, the default) or turn steadily through
    /// them (`continuous`: one pass per run and direction, `points` samples each).
    #[serde(default)]
    pub scan: ScanMode,
}

/// How a plan is acquired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScanMode {
    /// Stop at every target and measure at rest.
    #[default]
    Step,
    /// Turn steadily while both instruments stream; pair the streams by time.
    Continuous,
}

impl ScanMode {
    /// `step` or `continuous`.
    pub fn as_str(self) -> &'static str {
        match self {
            ScanMode::Step => "step",
            ScanMode::Continuous => "continuous",
        }
    }
}

/// One step of the plan: measure `target_deg` approached in `direction` during `run`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Step {
    pub seq: u64,
    pub run: u32,
    pub direction: Direction,
    pub target_index: usize,
    pub target_deg: f64,
}

/// The most steps a plan may hold (counted both ways): 4 million, about 93
/// days of instrument time at 2 s a step. A survey beyond it is a typing
/// error, and the plan (a few dozen bytes a step) must fit in memory.
pub const MAX_STEPS: u64 = 4_000_000;

/// Why a plan is not valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error("--points must be at least 2, got {0}")]
    TooFewPoints(u32),
    #[error("--runs must be at least 2 (repeatability needs two runs; ISO 230-2 asks for 5), got {0}")]
    TooFewRuns(u32),
    #[error(
        "--points {points} x --runs {runs} makes {steps} steps, more than the {max} a survey may hold (at about 2 s a \
         step that is {days:.0} days of instrument time)",
        max = MAX_STEPS,
        days = *steps as f64 * 2.0 / 86400.0
    )]
    TooManySteps { points: u32, runs: u32, steps: u64 },
    #[error(
        "with an autocollimator the targets are the faces of the {faces}-face polygon: --points must be {faces}, got \
         {points}"
    )]
    NotTheFaces { points: u32, faces: u32 },
    #[error(
        "the travel {}..{} deg holds {found} of the {faces} polygon faces (every {} deg) with room to \
         approach them from both sides; at least 2 are needed",
        Num(*min),
        Num(*max),
        Num(*pitch)
    )]
    TooFewFaces { min: f64, max: f64, faces: u32, pitch: f64, found: usize },
    #[error("the range {}..{} deg is empty or not finite", Num(*start), Num(*end))]
    BadRange { start: f64, end: f64 },
    #[error("the overrun must be positive and finite, got {} deg", Num(*.0))]
    BadOverrun(f64),
    #[error(
        "targets {}..{} deg with {} deg of overrun leave the travel {}..{} deg",
        Num(*first),
        Num(*last),
        Num(*overrun),
        Num(*min),
        Num(*max)
    )]
    OutsideTravel { first: f64, last: f64, overrun: f64, min: f64, max: f64 },
    #[error(
        "--verify-points {points}: the verification target {} deg falls on a calibration target, where the \
         table needs no interpolation; choose a count whose targets all fall between them (a multiple of the \
         {calibration} calibration targets always does)",
        Num(*target)
    )]
    VerificationOnTarget { points: u32, target: f64, calibration: usize },
}

impl SurveyPlan {
    /// `points` targets evenly over a full revolution: `k * 360 / points`.
    pub fn full_circle(points: u32, runs: u32, bidirectional: bool) -> Result<Self, PlanError> {
        Self::check_counts(points, runs)?;
        let targets_deg = (0..points).map(|k| k as f64 * 360.0 / points as f64).collect();
        Ok(Self { targets_deg, runs, bidirectional, overrun_deg: default_overrun(points, 360.0), scan: ScanMode::Step })
    }

    /// `points` targets evenly from `start` to `end` inclusive (a partial-range axis).
    pub fn range(start: f64, end: f64, points: u32, runs: u32, bidirectional: bool) -> Result<Self, PlanError> {
        Self::check_counts(points, runs)?;
        if !(start.is_finite() && end.is_finite() && end > start) {
            return Err(PlanError::BadRange { start, end });
        }
        let step = (end - start) / (points - 1) as f64;
        let targets_deg = (0..points).map(|k| start + k as f64 * step).collect();
        Ok(Self {
            targets_deg,
            runs,
            bidirectional,
            overrun_deg: default_overrun(points, end - start),
            scan: ScanMode::Step,
        })
    }

    /// A plan for a travel-limited axis: targets spread over the travel,
    /// kept one overrun inside each end so every target can be approached
    /// from both sides.
    pub fn within_travel(min: f64, max: f64, points: u32, runs: u32, bidirectional: bool) -> Result<Self, PlanError> {
        let overrun = default_overrun(points, max - min);
        let mut plan = Self::range(min + overrun, max - overrun, points, runs, bidirectional)?;
        plan.overrun_deg = overrun;
        Ok(plan)
    }

    /// The plan of a survey against an N-face polygon: the targets are the
    /// faces (`k * 360 / faces`). `points` must be the face count. On a
    /// travel-limited axis, the faces that lie one overrun inside each end of
    /// the travel (an elevation axis of -10..90 deg and a 36-face polygon:
    /// 0, 10, ..., 80 deg).
    pub fn polygon(
        faces: u32,
        points: u32,
        travel: Option<(f64, f64)>,
        runs: u32,
        bidirectional: bool,
    ) -> Result<Self, PlanError> {
        if points != faces {
            return Err(PlanError::NotTheFaces { points, faces });
        }
        let Some((min, max)) = travel else {
            return Self::full_circle(faces, runs, bidirectional);
        };
        Self::check_counts(faces, runs)?;
        if !(min.is_finite() && max.is_finite() && max > min) {
            return Err(PlanError::BadRange { start: min, end: max });
        }
        let pitch = 360.0 / f64::from(faces);
        let overrun = default_overrun(faces, 360.0);
        let first = ((min + overrun) / pitch).ceil() as i64;
        let last = ((max - overrun) / pitch).floor() as i64;
        let targets_deg: Vec<f64> = (first..=last).map(|k| k as f64 * pitch).collect();
        if targets_deg.len() < 2 {
            return Err(PlanError::TooFewFaces { min, max, faces, pitch, found: targets_deg.len() });
        }
        Ok(Self { targets_deg, runs, bidirectional, overrun_deg: overrun, scan: ScanMode::Step })
    }

    /// The plan that verifies a table made from a survey of this plan: the
    /// same runs, directions and overrun, at targets *between* this plan's
    /// targets, so that what the table interpolates is measured. By default
    /// (`points = None`) half a step from each target: over a full circle the
    /// `n` points `first + (k + 1/2) 360/n`, over a partial range the `n - 1`
    /// midpoints of consecutive targets. With `points = Some(N)`, `N` targets
    /// evenly over the same span, offset by half their own step; a count that
    /// puts one of them on a calibration target is refused. Every target lies
    /// within the span of this plan's targets, so the travel this plan kept
    /// is kept.
    pub fn between_targets(&self, points: Option<u32>) -> Result<Self, PlanError> {
        let n = self.targets_deg.len();
        let first = self.targets_deg[0];
        let last = *self.targets_deg.last().expect("a plan has targets");
        let full_circle = matches!(Coverage::of_targets(&self.targets_deg).0, Coverage::FullCircle { .. });
        let (span, count) = match (full_circle, points) {
            (true, None) => (360.0, n),
            (false, None) => (last - first, n - 1),
            (true, Some(p)) => (360.0, p as usize),
            (false, Some(p)) => (last - first, p as usize),
        };
        let count_u32 = u32::try_from(count).unwrap_or(u32::MAX);
        // Half a step needs no count check (a partial range of 2 targets has
        // one midpoint); a count asked for does.
        if points.is_some() {
            Self::check_counts(count_u32, self.runs)?;
        }
        let step = span / count as f64;
        let mut targets_deg: Vec<f64> = (0..count)
            .map(|k| {
                let t = first + (k as f64 + 0.5) * step;
                if full_circle && t >= 360.0 { t - 360.0 } else { t }
            })
            .collect();
        targets_deg.sort_by(f64::total_cmp);
        // Closer than this to a calibration target is on it (the targets are
        // computed in floating point from the same numbers).
        const ON_TARGET_DEG: f64 = 1e-6;
        for &t in &targets_deg {
            let on = self.targets_deg.iter().any(|c| {
                let d = (t - c).abs();
                d < ON_TARGET_DEG || (full_circle && (360.0 - d).abs() < ON_TARGET_DEG)
            });
            if on {
                return Err(PlanError::VerificationOnTarget { points: count_u32, target: t, calibration: n });
            }
        }
        Ok(Self {
            targets_deg,
            runs: self.runs,
            bidirectional: self.bidirectional,
            overrun_deg: self.overrun_deg,
            scan: ScanMode::Step,
        })
    }

    fn check_counts(points: u32, runs: u32) -> Result<(), PlanError> {
        if points < 2 {
            return Err(PlanError::TooFewPoints(points));
        }
        if runs < 2 {
            return Err(PlanError::TooFewRuns(runs));
        }
        // Counted as if bidirectional: the bound does not depend on the flag.
        let steps = u64::from(points) * u64::from(runs) * 2;
        if steps > MAX_STEPS {
            return Err(PlanError::TooManySteps { points, runs, steps });
        }
        Ok(())
    }

    /// Check that every position the plan visits (targets and overruns) lies
    /// within the travel.
    pub fn check_travel(&self, min: f64, max: f64) -> Result<(), PlanError> {
        if !(self.overrun_deg.is_finite() && self.overrun_deg > 0.0) {
            return Err(PlanError::BadOverrun(self.overrun_deg));
        }
        let first = self.targets_deg[0];
        let last = *self.targets_deg.last().expect("a plan has targets");
        if first - self.overrun_deg < min - 1e-9 || last + self.overrun_deg > max + 1e-9 {
            return Err(PlanError::OutsideTravel { first, last, overrun: self.overrun_deg, min, max });
        }
        Ok(())
    }

    /// Whether the plan is acquired by a continuous scan.
    pub fn continuous(&self) -> bool {
        self.scan == ScanMode::Continuous
    }

    /// The directions measured in each run, in order.
    pub fn directions(&self) -> &'static [Direction] {
        if self.bidirectional { &[Direction::Forward, Direction::Reverse] } else { &[Direction::Forward] }
    }

    /// Number of samples the plan acquires.
    pub fn total_steps(&self) -> u64 {
        self.targets_deg.len() as u64 * self.runs as u64 * self.directions().len() as u64
    }

    /// Every step in acquisition order.
    pub fn steps(&self) -> Vec<Step> {
        let mut steps = Vec::with_capacity(self.total_steps() as usize);
        let n = self.targets_deg.len();
        for run in 1..=self.runs {
            for &direction in self.directions() {
                for k in 0..n {
                    let target_index = if direction == Direction::Forward { k } else { n - 1 - k };
                    steps.push(Step {
                        seq: steps.len() as u64,
                        run,
                        direction,
                        target_index,
                        target_deg: self.targets_deg[target_index],
                    });
                }
            }
        }
        steps
    }

    /// Instrument time the plan takes, from the axis dynamics and the time
    /// spent at each target (settle, dwell and measurement).
    pub fn estimate_duration(&self, velocity_deg_s: f64, accel_deg_s2: f64, per_target: Duration) -> Duration {
        let mut total = 0.0;
        let mut pos = self.targets_deg[0] - self.overrun_deg;
        for step in self.steps() {
            let approach_from = step.target_deg - step.direction.sign() * self.overrun_deg;
            let wrong_side = (step.target_deg - pos) * step.direction.sign() <= 0.0;
            if wrong_side {
                total += move_time(approach_from - pos, velocity_deg_s, accel_deg_s2);
                pos = approach_from;
            }
            total += move_time(step.target_deg - pos, velocity_deg_s, accel_deg_s2) + per_target.as_secs_f64();
            pos = step.target_deg;
        }
        Duration::from_secs_f64(total)
    }

    /// Instrument time of one run.
    pub fn estimate_run_duration(&self, velocity_deg_s: f64, accel_deg_s2: f64, per_target: Duration) -> Duration {
        self.estimate_duration(velocity_deg_s, accel_deg_s2, per_target) / self.runs
    }
}

/// Half a target spacing, at most 1 degree: enough to take up backlash, small
/// enough to stay clear of the neighbouring target.
fn default_overrun(points: u32, span_deg: f64) -> f64 {
    (0.5 * span_deg / points as f64).min(1.0)
}

/// Time of a trapezoidal (or triangular) move over `distance` degrees.
pub fn move_time(distance: f64, velocity: f64, accel: f64) -> f64 {
    let d = distance.abs();
    if d == 0.0 {
        return 0.0;
    }
    let d_ramp = velocity * velocity / accel;
    if d >= d_ramp { d / velocity + velocity / accel } else { 2.0 * (d / accel).sqrt() }
}

/// The readouts at which the SMR is measured to locate the axis: `points`
/// (at least 3) evenly over the full circle, or over the plan's targets on
/// a partial range.
pub fn locate_readouts(plan: &SurveyPlan, points: u32) -> Vec<f64> {
    let points = points.max(3);
    let first = plan.targets_deg[0];
    let last = *plan.targets_deg.last().expect("a plan has targets");
    let spacing = if plan.targets_deg.len() > 1 { plan.targets_deg[1] - first } else { 0.0 };
    let full_circle = (last - first + spacing - 360.0).abs() < 1e-6;
    if full_circle {
        (0..points).map(|k| first + k as f64 * 360.0 / points as f64).collect()
    } else {
        (0..points).map(|k| first + k as f64 * (last - first) / (points - 1) as f64).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polygon_plan_on_an_elevation_axis_measures_the_faces_inside_the_travel() {
        let plan = SurveyPlan::polygon(36, 36, Some((-10.0, 90.0)), 5, true).unwrap();
        assert_eq!(plan.targets_deg, (0..=8).map(|k| f64::from(k) * 10.0).collect::<Vec<_>>());
        assert_eq!(plan.overrun_deg, 1.0);
        plan.check_travel(-10.0, 90.0).unwrap();
        let full = SurveyPlan::polygon(24, 24, None, 2, false).unwrap();
        assert_eq!(full, SurveyPlan::full_circle(24, 2, false).unwrap());
    }

    #[test]
    fn full_circle_steps_go_forward_then_reverse_each_run() {
        let plan = SurveyPlan::full_circle(4, 2, true).unwrap();
        assert_eq!(plan.targets_deg, vec![0.0, 90.0, 180.0, 270.0]);
        let steps = plan.steps();
        assert_eq!(steps.len() as u64, plan.total_steps());
        assert_eq!(steps.len(), 16);
        let order: Vec<(u32, Direction, f64)> = steps.iter().map(|s| (s.run, s.direction, s.target_deg)).collect();
        assert_eq!(
            order[0..8],
            [
                (1, Direction::Forward, 0.0),
                (1, Direction::Forward, 90.0),
                (1, Direction::Forward, 180.0),
                (1, Direction::Forward, 270.0),
                (1, Direction::Reverse, 270.0),
                (1, Direction::Reverse, 180.0),
                (1, Direction::Reverse, 90.0),
                (1, Direction::Reverse, 0.0),
            ]
        );
        assert!(steps.iter().enumerate().all(|(i, s)| s.seq == i as u64));
        assert_eq!(steps[8].run, 2);
    }

    #[test]
    fn unidirectional_and_partial_range() {
        let plan = SurveyPlan::within_travel(-10.0, 90.0, 11, 3, false).unwrap();
        assert_eq!(plan.steps().len(), 33);
        assert!(plan.targets_deg[0] > -10.0 && *plan.targets_deg.last().unwrap() < 90.0);
        plan.check_travel(-10.0, 90.0).unwrap();
        let full = SurveyPlan::full_circle(10, 2, true).unwrap();
        assert!(matches!(full.check_travel(0.0, 300.0), Err(PlanError::OutsideTravel { .. })));
    }

    #[test]
    fn rejects_too_few_points_or_runs() {
        assert_eq!(SurveyPlan::full_circle(1, 5, true), Err(PlanError::TooFewPoints(1)));
        assert_eq!(SurveyPlan::polygon(36, 24, None, 5, true), Err(PlanError::NotTheFaces { points: 24, faces: 36 }));
        assert!(matches!(
            SurveyPlan::polygon(4, 4, Some((-10.0, 90.0)), 2, true),
            Err(PlanError::TooFewFaces { found: 1, .. })
        ));
        assert_eq!(SurveyPlan::full_circle(10, 1, true), Err(PlanError::TooFewRuns(1)));
        assert!(SurveyPlan::range(5.0, 5.0, 3, 2, false).is_err());
    }

    #[test]
    fn the_verification_plan_measures_between_the_calibration_targets() {
        let plan = SurveyPlan::full_circle(8, 3, true).unwrap();
        let v = plan.between_targets(None).unwrap();
        assert_eq!(v.targets_deg, (0..8).map(|k| 22.5 + 45.0 * k as f64).collect::<Vec<_>>());
        assert_eq!((v.runs, v.bidirectional, v.overrun_deg), (3, true, plan.overrun_deg));
        // Denser: 16 points, offset by half their own step (11.25 deg), none on a target.
        let dense = plan.between_targets(Some(16)).unwrap();
        assert_eq!(dense.targets_deg.len(), 16);
        assert!((dense.targets_deg[0] - 11.25).abs() < 1e-12 && (dense.targets_deg[15] - 348.75).abs() < 1e-12);
        // 4 points at 45, 135, ... are calibration targets: refused.
        assert!(matches!(
            plan.between_targets(Some(4)),
            Err(PlanError::VerificationOnTarget { points: 4, calibration: 8, .. })
        ));
        assert_eq!(plan.between_targets(Some(1)), Err(PlanError::TooFewPoints(1)));
        // A partial range: the midpoints, inside the span (so inside the travel).
        let partial = SurveyPlan::within_travel(-10.0, 90.0, 11, 2, true).unwrap();
        let v = partial.between_targets(None).unwrap();
        assert_eq!(v.targets_deg.len(), 10);
        let step = partial.targets_deg[1] - partial.targets_deg[0];
        assert!((v.targets_deg[0] - (partial.targets_deg[0] + step / 2.0)).abs() < 1e-9);
        v.check_travel(-10.0, 90.0).unwrap();
        let dense = partial.between_targets(Some(40)).unwrap();
        dense.check_travel(-10.0, 90.0).unwrap();
        assert!(dense.targets_deg.iter().all(|t| *t > partial.targets_deg[0] && *t < partial.targets_deg[10]));
    }

    #[test]
    fn move_time_matches_the_profile() {
        // 90 deg at 10 deg/s and 20 deg/s^2: 0.5 s ramps, 9.5 s in all.
        assert!((move_time(90.0, 10.0, 20.0) - 9.5).abs() < 1e-12);
        // Short move: triangular, 2*sqrt(d/a).
        assert!((move_time(1.0, 10.0, 20.0) - 2.0 * (1.0f64 / 20.0).sqrt()).abs() < 1e-12);
        let plan = SurveyPlan::full_circle(4, 2, false).unwrap();
        assert!(plan.estimate_duration(10.0, 20.0, Duration::from_secs(1)) > Duration::from_secs(8));
    }
}
