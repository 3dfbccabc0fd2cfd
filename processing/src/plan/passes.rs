//! The passes of a continuous scan (`survey run --scan continuous`): each
//! run and direction of a plan is one pass, from a run-up point before its
//! first target (far enough to reach the pass's velocity) steadily past its
//! last target to a run-out point; the first run turns at the calibration
//! velocity, the others at the scan velocity.

use super::SurveyPlan;
use crate::Direction;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// The continuous scan's velocities and rates (part of the orchestrator's engine timing).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ScanTiming {
    /// Velocity of the survey's passes (the runs after the first), deg/s
    /// (default: half the configured velocity).
    pub velocity_deg_s: Option<f64>,
    /// Velocity of the first run, which calibrates the latency, deg/s
    /// (default: the configured velocity).
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
        (self.calibration_velocity_deg_s.unwrap_or(configured), self.velocity_deg_s.unwrap_or(configured / 2.0))
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

/// One pass of a plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PassPlan {
    pub index: u32,
    pub run: u32,
    pub direction: Direction,
    /// Unsigned velocity, deg/s.
    pub speed: f64,
    /// Where the axis starts and ends the pass, degrees.
    pub start: f64,
    pub end: f64,
    /// `(seq, target)` in the order the pass meets them.
    pub targets: Vec<(u64, f64)>,
}

/// Where a plan's acquisition starts: the first approach's start (step),
/// or the first pass's run-up point (continuous).
pub fn start_deg(plan: &SurveyPlan, velocity: f64, accel: f64, t: &ScanTiming) -> f64 {
    if plan.continuous() {
        passes(plan, velocity, accel, t).first().map_or(plan.targets_deg[0], |p| p.start)
    } else {
        plan.targets_deg[0] - plan.overrun_deg
    }
}

/// The passes of a plan on an axis of `velocity` and `accel`.
pub fn passes(plan: &SurveyPlan, velocity: f64, accel: f64, t: &ScanTiming) -> Vec<PassPlan> {
    let (cal, scan) = t.speeds(velocity);
    let steps = plan.steps();
    let n = plan.targets_deg.len();
    steps
        .chunks(n)
        .enumerate()
        .map(|(i, chunk)| {
            let (run, direction) = (chunk[0].run, chunk[0].direction);
            let speed = if run == 1 { cal } else { scan };
            let sign = direction.sign();
            let runup = t.runup_deg(speed, accel);
            let first = chunk[0].target_deg;
            let last = chunk[n - 1].target_deg;
            PassPlan {
                index: i as u32,
                run,
                direction,
                speed,
                start: first - sign * runup,
                end: last + sign * runup,
                targets: chunk.iter().map(|s| (s.seq, s.target_deg)).collect(),
            }
        })
        .collect()
}
