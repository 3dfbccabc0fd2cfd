//! The passes of a continuous scan (`survey run --scan continuous`): each
//! run and direction of a plan is one pass, from a run-up point before its
//! first target (far enough to reach the pass's velocity) steadily past its
//! last target to a run-out point, every one at the scan velocity (by
//! default the configured velocity: the positioner's pace).
//!
//! The latency between the instruments ([`crate::pairing::latency`]) is
//! measured by four calibration passes before the first run
//! ([`calibration_passes`]): over the first [`CALIBRATION_ARC_DEG`] of the
//! plan's range, forward and back at the scan velocity, then forward and
//! back at a second velocity (by default a quarter of it). What they see at
//! the same angles differs by the latency times the difference of the
//! velocities. They come first, rather than reusing the first run over the
//! arc (which would save one forward and one reverse pass over it, about
//! 13 s at 10 deg/s), so that the latency is known before any run: every
//! pass of the plan is paired and stored as it ends (none held in memory),
//! a survey stopped anywhere resumes from its first pass not stored, and a
//! resume with no pass stored measures the latency again on the same
//! arc. [`scan_order`] is the order the engine scans them in.

use super::{PlanError, SurveyPlan};
use serde::{Deserialize, Serialize};
use std::time::Duration;
use survey_processing::Direction;

/// The continuous scan's velocities and rates (part of the orchestrator's engine timing).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ScanTiming {
    /// Velocity of the survey's passes, deg/s (default: the configured
    /// velocity, the positioner's maximum).
    pub velocity_deg_s: Option<f64>,
    /// The second velocity of the calibration passes that measure the
    /// latency, deg/s (default: a quarter of the scan velocity).
    pub calibration_velocity_deg_s: Option<f64>,
    /// The readout's capture (or polling) period.
    pub capture_period: Duration,
    /// The tracker's point period (emScon's time separation).
    pub stream_period: Duration,
    /// How often both streams are read.
    pub fetch_interval: Duration,
    /// The longest gap, in periods of a stream, bridged around a target.
    pub max_gap_periods: f64,
    /// Half-width of the tracker fit around a target, in periods.
    pub fit_half_width_periods: f64,
}

impl Default for ScanTiming {
    fn default() -> Self {
        Self {
            velocity_deg_s: None,
            calibration_velocity_deg_s: None,
            capture_period: Duration::from_millis(5),
            stream_period: Duration::from_millis(5),
            fetch_interval: Duration::from_millis(50),
            max_gap_periods: 6.0,
            fit_half_width_periods: 2.5,
        }
    }
}

impl ScanTiming {
    /// `(calibration velocity, scan velocity)` for a configured velocity.
    pub fn speeds(&self, configured: f64) -> (f64, f64) {
        let scan = self.velocity_deg_s.unwrap_or(configured);
        (self.calibration_velocity_deg_s.unwrap_or(scan * CALIBRATION_VELOCITY_SHARE), scan)
    }

    /// Distance before the first target (and after the last) of a pass at
    /// `speed`: the acceleration ramp, plus room for the fits, the gaps and
    /// a latency of up to 50 ms.
    pub fn runup_deg(&self, speed: f64, accel: f64) -> f64 {
        let margin = self.fit_half_width_periods * self.stream_period.as_secs_f64()
            + self.max_gap_periods * self.stream_period.as_secs_f64().max(self.capture_period.as_secs_f64())
            + 0.05;
        speed * speed / (2.0 * accel) + speed * margin + 0.01
    }
}

/// The arc the calibration passes turn over, degrees (the plan's range when
/// it is shorter), and the second velocity's share of the scan velocity.
///
/// A latency error `e` moves every forward sample by `v e` and every
/// reverse one by `-v e`: the reversal of a directional table is off by
/// `2 v e`, so at 10 deg/s each microsecond costs 1e-5 deg, half the
/// simulated fig8 table's true residual. What limits the estimate is noise
/// over the arc: the tracker's (about 8e-4 deg a point, a point every
/// `v x 5 ms`) and the positioner's own (0.0004 deg, a new value every 0.05
/// deg along a move), on all four passes. For a given time on the arc, the
/// variance is least with the second velocity near a quarter of the first
/// (fewer tracker points at a higher one, a smaller difference of the
/// velocities at a higher one, little gain below). Measured on the
/// simulated bench (tests/engine/scan_latency.rs): 60 deg at 10 and 2.5
/// deg/s (63 s) give a standard error of 3.4-4.5 us; 30 deg at 10 and 5
/// (22 s) 7.6-9.5 us; 90 deg at 10 and 2.5 (94 s) 2.9-3.5 us, past the
/// time a survey 50 times shorter than step mode has for it.
pub const CALIBRATION_VELOCITY_SHARE: f64 = 0.25;

/// See [`CALIBRATION_VELOCITY_SHARE`].
pub const CALIBRATION_ARC_DEG: f64 = 60.0;

/// A continuous plan on an axis that travels only `lo..hi`: its targets
/// kept far enough inside the travel for every pass's run-up and run-out
/// (a step plan keeps them one overrun inside, which a pass at the
/// positioner's pace overshoots), the same count, runs, directions, overrun
/// and scan. The plan itself when it fits; an error naming the travel and
/// the run-up when the travel is too short for a scan.
pub fn within_travel_for_scan(
    plan: &SurveyPlan,
    (lo, hi): (f64, f64),
    velocity: f64,
    accel: f64,
    t: &ScanTiming,
) -> Result<SurveyPlan, PlanError> {
    let fits = |p: &SurveyPlan| {
        scan_order(p, velocity, accel, t)
            .iter()
            .all(|pass| pass.start.min(pass.end) >= lo && pass.start.max(pass.end) <= hi)
    };
    if fits(plan) {
        return Ok(plan.clone());
    }
    let (cal, scan) = t.speeds(velocity);
    let inset = t.runup_deg(cal.max(scan), accel).max(plan.overrun_deg);
    let points = plan.targets_deg.len() as u32;
    SurveyPlan::range(lo + inset, hi - inset, points, plan.runs, plan.bidirectional)
        .ok()
        .map(|inside| SurveyPlan { overrun_deg: plan.overrun_deg, scan: plan.scan, ..inside })
        .filter(fits)
        .ok_or(PlanError::OutsideTravel { first: lo + inset, last: hi - inset, overrun: inset, min: lo, max: hi })
}

/// One pass of a plan, or a calibration pass.
#[derive(Debug, Clone, PartialEq)]
pub struct PassPlan {
    /// The plan's pass number (calibration passes: numbered after them).
    pub index: u32,
    /// A calibration pass: paired only to measure the latency, never stored.
    pub calibration: bool,
    /// The run (0 for a calibration pass).
    pub run: u32,
    pub direction: Direction,
    /// Unsigned velocity, deg/s.
    pub speed: f64,
    /// Where the axis starts and ends the pass, degrees.
    pub start: f64,
    pub end: f64,
    /// `(seq, target)` in the order the pass meets them (a calibration
    /// pass: its pairing points, numbered from 0 in ascending angle).
    pub targets: Vec<(u64, f64)>,
}

/// Where a plan's acquisition starts: the first approach's start (step),
/// or the first pass's run-up point (continuous).
pub fn start_deg(plan: &SurveyPlan, velocity: f64, accel: f64, t: &ScanTiming) -> f64 {
    if plan.continuous() {
        scan_order(plan, velocity, accel, t).first().map_or(plan.targets_deg[0], |p| p.start)
    } else {
        plan.targets_deg[0] - plan.overrun_deg
    }
}

/// A pass over `targets` (in the order met) at `speed`, with its run-up
/// and run-out (numbered 0, run 0, not a calibration pass).
fn pass_over(targets: Vec<(u64, f64)>, direction: Direction, speed: f64, accel: f64, t: &ScanTiming) -> PassPlan {
    let sign = direction.sign();
    let runup = t.runup_deg(speed, accel);
    let (first, last) = (targets[0].1, targets[targets.len() - 1].1);
    PassPlan {
        index: 0,
        calibration: false,
        run: 0,
        direction,
        speed,
        start: first - sign * runup,
        end: last + sign * runup,
        targets,
    }
}

/// The passes of a plan on an axis of `velocity` and `accel`, all at the
/// scan velocity.
pub fn passes(plan: &SurveyPlan, velocity: f64, accel: f64, t: &ScanTiming) -> Vec<PassPlan> {
    let (_, scan) = t.speeds(velocity);
    let n = plan.targets_deg.len();
    plan.steps()
        .chunks(n)
        .enumerate()
        .map(|(i, chunk)| {
            let targets = chunk.iter().map(|s| (s.seq, s.target_deg)).collect();
            PassPlan { index: i as u32, run: chunk[0].run, ..pass_over(targets, chunk[0].direction, scan, accel, t) }
        })
        .collect()
}

/// The calibration passes that measure the latency (see the module
/// documentation): over the first [`CALIBRATION_ARC_DEG`] of the plan's
/// range (all of a shorter one), forward and back at the scan velocity,
/// then at the calibration velocity, whatever the plan's directions (both
/// ways cancel what differs between the velocities' passes but not with
/// the direction). Paired at the same angles in all four, evenly over the
/// arc and at most a tracker point of the slower pass apart.
pub fn calibration_passes(plan: &SurveyPlan, velocity: f64, accel: f64, t: &ScanTiming) -> Vec<PassPlan> {
    let (cal, scan) = t.speeds(velocity);
    let from = plan.targets_deg[0];
    let arc = (plan.targets_deg[plan.targets_deg.len() - 1] - from).min(CALIBRATION_ARC_DEG);
    let spacing = cal.min(scan) * t.stream_period.as_secs_f64();
    let intervals = if spacing > 0.0 { (arc / spacing - 1e-9).ceil().max(1.0) as u64 } else { 1 };
    let forward: Vec<(u64, f64)> = (0..=intervals).map(|k| (k, from + arc * k as f64 / intervals as f64)).collect();
    let reverse: Vec<(u64, f64)> = forward.iter().rev().copied().collect();
    let first = plan.runs as usize * plan.directions().len();
    [scan, cal]
        .into_iter()
        .flat_map(|speed| [(speed, Direction::Forward, &forward), (speed, Direction::Reverse, &reverse)])
        .enumerate()
        .map(|(i, (speed, direction, targets))| PassPlan {
            index: (first + i) as u32,
            calibration: true,
            ..pass_over(targets.clone(), direction, speed, accel, t)
        })
        .collect()
}

/// The order a continuous scan turns in: the calibration passes, then the
/// plan's.
pub fn scan_order(plan: &SurveyPlan, velocity: f64, accel: f64, t: &ScanTiming) -> Vec<PassPlan> {
    let mut all = calibration_passes(plan, velocity, accel, t);
    all.extend(passes(plan, velocity, accel, t));
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ScanMode;

    fn continuous(mut plan: SurveyPlan) -> SurveyPlan {
        plan.scan = ScanMode::Continuous;
        plan
    }

    #[test]
    fn a_scan_on_a_travel_limited_axis_keeps_its_run_ups_inside_the_travel() {
        // An axis of the paper's Figure 1's travel, -10..90 deg, at 10 deg/s
        // and 20 deg/s^2: its step plan keeps the targets one overrun inside
        // the travel; a pass at 10 deg/s needs 2.5 deg to reach its velocity
        // and more to pair its first target.
        let t = ScanTiming::default();
        let plan = continuous(SurveyPlan::within_travel(-10.0, 90.0, 60, 2, true).unwrap());
        let outside = |p: &SurveyPlan| {
            scan_order(p, 10.0, 20.0, &t).iter().any(|s| s.start.min(s.end) < -10.0 || s.start.max(s.end) > 90.0)
        };
        assert!(outside(&plan), "the step plan's targets leave no room for the run-up");
        let inside = within_travel_for_scan(&plan, (-10.0, 90.0), 10.0, 20.0, &t).unwrap();
        assert!(!outside(&inside));
        assert_eq!(inside.targets_deg.len(), 60);
        assert_eq!((inside.runs, inside.bidirectional, inside.scan), (2, true, ScanMode::Continuous));
        assert_eq!(inside.overrun_deg, plan.overrun_deg);
        let runup = t.runup_deg(10.0, 20.0);
        assert!((inside.targets_deg[0] - (-10.0 + runup)).abs() < 1e-9, "{}", inside.targets_deg[0]);
        assert!((inside.targets_deg[59] - (90.0 - runup)).abs() < 1e-9);
        // A plan that fits is kept; a travel too short for two run-ups is refused.
        let slow = within_travel_for_scan(&plan, (-10.0, 90.0), 1.0, 20.0, &t).unwrap();
        assert_eq!(slow, plan);
        let short = continuous(SurveyPlan::within_travel(0.0, 4.0, 10, 2, true).unwrap());
        let e = within_travel_for_scan(&short, (0.0, 4.0), 10.0, 20.0, &t).unwrap_err();
        assert!(e.to_string().contains("leave the travel 0..4 deg"), "{e}");
    }

    #[test]
    fn every_pass_turns_at_the_configured_velocity_unless_told_otherwise() {
        let t = ScanTiming::default();
        assert_eq!(t.speeds(10.0), (2.5, 10.0));
        assert_eq!(ScanTiming { velocity_deg_s: Some(8.0), ..t }.speeds(10.0), (2.0, 8.0));
        assert_eq!(ScanTiming { calibration_velocity_deg_s: Some(3.0), ..t }.speeds(10.0), (3.0, 10.0));
        let plan = continuous(SurveyPlan::full_circle(36, 3, true).unwrap());
        let all = passes(&plan, 10.0, 20.0, &t);
        assert_eq!(all.len(), 6);
        for (i, p) in all.iter().enumerate() {
            assert_eq!((p.index, p.run, p.speed, p.calibration), (i as u32, i as u32 / 2 + 1, 10.0, false));
            assert_eq!(p.targets.len(), 36);
        }
    }

    #[test]
    fn the_calibration_passes_turn_over_the_same_short_arc_both_ways_at_two_velocities() {
        let t = ScanTiming::default();
        let plan = continuous(SurveyPlan::full_circle(1800, 5, true).unwrap());
        let cal = calibration_passes(&plan, 10.0, 20.0, &t);
        let got: Vec<(u32, Direction, f64, bool, u32)> =
            cal.iter().map(|p| (p.index, p.direction, p.speed, p.calibration, p.run)).collect();
        use Direction::{Forward, Reverse};
        assert_eq!(
            got,
            [
                (10, Forward, 10.0, true, 0),
                (11, Reverse, 10.0, true, 0),
                (12, Forward, 2.5, true, 0),
                (13, Reverse, 2.5, true, 0)
            ]
        );
        // Paired every 0.0125 deg (a 5 ms point at 2.5 deg/s) over 60 deg
        // from the first target, the same angles each way, in the order met.
        let forward: Vec<f64> = cal[0].targets.iter().map(|x| x.1).collect();
        assert_eq!(forward.len(), 4801);
        assert!((forward[1] - forward[0] - 0.0125).abs() < 1e-12 && forward[4800] == 60.0, "{forward:?}");
        for p in &cal {
            let mut angles: Vec<f64> = p.targets.iter().map(|x| x.1).collect();
            if p.direction == Reverse {
                angles.reverse();
                assert!(p.start > p.end);
            }
            assert_eq!(angles, forward);
            // Each starts before its first point by its run-up, and ends past its last.
            let runup = t.runup_deg(p.speed, 20.0);
            let sign = p.direction.sign();
            assert!((p.start - (p.targets[0].1 - sign * runup)).abs() < 1e-12);
            assert!((p.end - (p.targets.last().unwrap().1 + sign * runup)).abs() < 1e-12);
        }
        // They come first, and the plan's passes keep their numbers.
        let order = scan_order(&plan, 10.0, 20.0, &t);
        assert_eq!(order[..4], cal[..]);
        assert!(order[4..].iter().enumerate().all(|(i, p)| p.index == i as u32 && !p.calibration));
        assert_eq!(start_deg(&plan, 10.0, 20.0, &t), order[0].start);
        assert_eq!(order[0].start, order[4].start, "the first calibration pass starts where run 1 does");
    }

    #[test]
    fn a_short_plan_calibrates_over_its_own_range_and_a_unidirectional_one_both_ways() {
        let t = ScanTiming { calibration_velocity_deg_s: Some(2.0), ..ScanTiming::default() };
        let plan = continuous(SurveyPlan::range(10.0, 20.0, 11, 2, false).unwrap());
        let cal = calibration_passes(&plan, 10.0, 20.0, &t);
        assert_eq!(cal.len(), 4);
        for p in &cal {
            let (lo, hi) = p.targets.iter().fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(x.1), h.max(x.1)));
            assert_eq!((lo, hi), (10.0, 20.0));
            // 0.01 deg apart: a point at 2 deg/s.
            assert_eq!(p.targets.len(), 1001);
        }
        assert_eq!(
            cal.iter().map(|p| p.direction).collect::<Vec<_>>(),
            [Direction::Forward, Direction::Reverse, Direction::Forward, Direction::Reverse]
        );
        assert_eq!((cal[0].index, cal[2].speed), (2, 2.0));
    }
}
