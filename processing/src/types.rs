//! Data types shared by every stage: a paired survey sample and its direction.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Direction of approach. `Forward` is increasing angle (ISO 230-2 "up"),
/// `Reverse` is decreasing angle ("down").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    Forward,
    Reverse,
}

impl Direction {
    /// The name used in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::Forward => "forward",
            Direction::Reverse => "reverse",
        }
    }

    /// +1 for forward, -1 for reverse.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Forward => 1.0,
            Direction::Reverse => -1.0,
        }
    }
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Direction {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "forward" => Ok(Direction::Forward),
            "reverse" => Ok(Direction::Reverse),
            other => Err(format!("unknown direction '{other}' (expected 'forward' or 'reverse')")),
        }
    }
}

/// One paired sample of a survey: what the positioner displayed (`readout_deg`)
/// and what the reference instrument measured (`actual_deg`) when the axis was
/// commanded to `target_deg` during run `run` (counted from 1).
///
/// The readout error is `readout_deg - actual_deg`; the ISO 230-2 positioning
/// deviation is `actual_deg - target_deg`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    pub run: u32,
    pub direction: Direction,
    pub target_deg: f64,
    pub readout_deg: f64,
    pub actual_deg: f64,
    /// Instrument time of the reading, seconds since the survey started.
    pub timestamp_s: Option<f64>,
}

impl Sample {
    /// Readout error `readout - actual`, degrees (the contract's sign).
    pub fn error_deg(&self) -> f64 {
        self.readout_deg - self.actual_deg
    }

    /// ISO 230-2 positioning deviation `actual - target`, degrees.
    pub fn deviation_deg(&self) -> f64 {
        self.actual_deg - self.target_deg
    }
}

/// `deg.rem_euclid(360.0)`, without its division for an angle in `[0,
/// 360)` already (which it returns unchanged): the per-sample paths call it.
#[inline]
pub fn rem_euclid_360(deg: f64) -> f64 {
    if (0.0..360.0).contains(&deg) { deg } else { deg.rem_euclid(360.0) }
}

/// Wrap an angle into `[0, 360)`.
pub fn wrap_360(deg: f64) -> f64 {
    let w = rem_euclid_360(deg);
    if w >= 360.0 { 0.0 } else { w }
}

/// Wrap an angle difference into `[-180, 180)`.
pub fn wrap_180(deg: f64) -> f64 {
    wrap_360(deg + 180.0) - 180.0
}
