//! The acquisition's settings: plain values the configuration file, the
//! bench and the engine share (the reference's kind, deadlines and retries,
//! settling, the continuous scan's rates). Nothing here acts: the engine
//! imports these, never the other way.

use serde::{Deserialize, Serialize};
use std::time::Duration;
use survey_plan::ScanTiming;
use survey_plan::budget::Settling;

/// The reference instrument that measures the actual angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReferenceKind {
    /// A tracking laser measuring an SMR on an arm (the axis is located first).
    Tracker,
    /// An autocollimator on a polygon: the targets are the faces.
    Autocollimator,
}

impl ReferenceKind {
    /// `tracker` or `autocollimator`.
    pub fn as_str(self) -> &'static str {
        match self {
            ReferenceKind::Tracker => "tracker",
            ReferenceKind::Autocollimator => "autocollimator",
        }
    }
}

/// Deadlines, waits and retry limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Deadline of a short request (status, readout, command).
    pub call_timeout: Duration,
    /// Deadline of a reference measurement (a tracker's stationary measurement
    /// takes about a second).
    pub measure_timeout: Duration,
    /// A move may take this much longer than its motion profile predicts
    /// (settling included) before it counts as stuck.
    pub move_margin: Duration,
    /// How often the status is polled while waiting for in-position.
    pub poll_interval: Duration,
    /// Wait after the axis is at rest before reading (default 0; see [`SettleSpec`]).
    pub dwell: Duration,
    /// Retries of one operation before the engine gives up.
    pub max_retries: u32,
    /// Wait before a retry.
    pub retry_backoff: Duration,
    /// SMR positions measured to locate the axis.
    pub locate_points: u32,
    /// Axis velocity and acceleration used to predict move times, deg/s and deg/s².
    pub velocity_deg_s: f64,
    pub accel_deg_s2: f64,
    /// How the engine decides the axis is at rest (see the engine's settling).
    #[serde(default)]
    pub settle: SettleSpec,
    /// The continuous scan's rates.
    #[serde(default)]
    pub scan: ScanTiming,
    /// How long a survey suspended on a lost beam waits for it before it
    /// ends interrupted.
    #[serde(default = "default_beam_wait")]
    pub beam_wait: Duration,
    /// Wait between two attempts to re-acquire a lost beam.
    #[serde(default = "default_beam_retry")]
    pub beam_retry: Duration,
}

impl Default for Timing {
    fn default() -> Self {
        Self {
            call_timeout: Duration::from_secs(2),
            measure_timeout: Duration::from_secs(10),
            move_margin: Duration::from_secs(10),
            poll_interval: Duration::from_millis(100),
            dwell: Duration::ZERO,
            max_retries: 3,
            retry_backoff: Duration::from_secs(1),
            locate_points: 12,
            velocity_deg_s: 10.0,
            accel_deg_s2: 20.0,
            settle: SettleSpec::default(),
            scan: ScanTiming::default(),
            beam_wait: default_beam_wait(),
            beam_retry: default_beam_retry(),
        }
    }
}

/// The default of `Timing::beam_wait`: 10 minutes.
fn default_beam_wait() -> Duration {
    Duration::from_secs(600)
}

/// The default of `Timing::beam_retry`: 10 s.
fn default_beam_retry() -> Duration {
    Duration::from_secs(10)
}

/// How the engine decides the axis is at rest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SettleMode {
    /// Readout within the window for a while (see the module documentation).
    Adaptive,
    /// The controller's in-position flag, then the fixed dwell.
    InPosition,
}

impl SettleMode {
    /// `adaptive` or `in-position`.
    pub fn as_str(self) -> &'static str {
        match self {
            SettleMode::Adaptive => "adaptive",
            SettleMode::InPosition => "in-position",
        }
    }
}

/// The settling settings (part of [`Timing`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SettleSpec {
    pub mode: SettleMode,
    /// The readout must stay this close to the target, degrees.
    pub window_deg: f64,
    /// ... for this long.
    pub stable_for: Duration,
    /// Readout polls while settling.
    pub poll: Duration,
    /// A tracker measurement whose standard deviation exceeds this many
    /// times the survey's typical one is taken again.
    pub reference_std_ratio: f64,
    /// Measurements of one sample before the engine takes the last one as it
    /// is (and logs a warning).
    pub max_remeasure: u32,
}

impl Default for SettleSpec {
    fn default() -> Self {
        Self {
            mode: SettleMode::Adaptive,
            window_deg: 1e-4,
            stable_for: Duration::from_millis(30),
            poll: Duration::from_millis(10),
            reference_std_ratio: 1.5,
            max_remeasure: 3,
        }
    }
}

/// The default settle window for a reference: a tenth of its noise per
/// reading, degrees (see the module documentation).
pub fn default_window_deg(reference: ReferenceKind) -> f64 {
    match reference {
        ReferenceKind::Tracker => 1e-4,
        ReferenceKind::Autocollimator => 3e-6,
    }
}

/// The settling an axis needs after a move, for the lower bound of a plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettleModel {
    /// A simulated servo: the time its ringing takes to come within the window.
    Servo { servo: survey_sims::servo::Servo, window_deg: f64 },
    /// The same settling after every move (`settle_time_s` of a configuration).
    Fixed(Duration),
    /// Not known: the bound counts none.
    Unknown,
}

impl Settling for SettleModel {
    /// Seconds of settling a move of `distance` degrees needs.
    fn needed_s(&self, distance: f64, velocity: f64, accel: f64) -> f64 {
        match self {
            SettleModel::Servo { servo, window_deg } => {
                if distance == 0.0 {
                    0.0
                } else {
                    servo.move_settle_s(distance, velocity, accel, *window_deg)
                }
            }
            SettleModel::Fixed(d) => d.as_secs_f64(),
            SettleModel::Unknown => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_settle_model_gives_the_servo_time_to_the_window() {
        let servo = survey_sims::servo::Servo::default();
        let m = SettleModel::Servo { servo, window_deg: 1e-4 };
        assert_eq!(m.needed_s(0.0, 10.0, 20.0), 0.0);
        let s = m.needed_s(0.2, 10.0, 20.0);
        assert!((s - servo.settle_time_s(0.004, 1e-4)).abs() < 1e-12 && s > 0.2 && s < 0.4, "{s}");
        assert_eq!(SettleModel::Fixed(Duration::from_millis(300)).needed_s(5.0, 1.0, 1.0), 0.3);
    }
}
