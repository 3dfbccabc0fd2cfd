//! A generic table for controllers whose format is not written here (or a
//! PLC, a drive, a spreadsheet), with the choices commercial calibration
//! software offers: the sign (error `readout - actual`, or the correction
//! `actual - readout` that is added to the readout), absolute values or
//! increments, one column or forward and reverse columns, over any range and
//! spacing.
//!
//! CSV, header `position_deg,<column>...` where a column is named by what it
//! holds: `error_deg` or `correction_deg`, prefixed `forward_`/`reverse_` for a
//! direction-aware table, suffixed `_increment` for increments
//! (`position_deg,forward_correction_increment_deg,reverse_correction_increment_deg`).
//! Increments: the first row holds the absolute value at the first position,
//! every other row the change from the row before, so a running sum gives the
//! absolute values back. Numbers with 10 decimals.

use super::layout::{Grid, Reader};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use survey_processing::Direction;

/// The sign of the values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sign {
    /// The error, `readout - actual`.
    #[default]
    Error,
    /// The correction, `actual - readout` (added to the readout).
    Correction,
}

/// Absolute values or increments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Values {
    /// The value at each position.
    #[default]
    Absolute,
    /// The change from the position before (the first row absolute).
    Incremental,
}

impl Sign {
    /// The name used in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Sign::Error => "error",
            Sign::Correction => "correction",
        }
    }
}

impl Values {
    /// The name used in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Values::Absolute => "absolute",
            Values::Incremental => "incremental",
        }
    }
}

/// The generic table.
#[derive(Debug, Clone, PartialEq)]
pub struct GenericTable {
    /// The points.
    pub grid: Grid,
    /// The sign.
    pub sign: Sign,
    /// Absolute or incremental.
    pub values: Values,
    /// One column per direction (forward, then reverse when direction-aware), signed, absolute.
    pub columns: Vec<Vec<f64>>,
}

impl GenericTable {
    /// The table on `grid` read from `reader`, `offset_deg` subtracted from the error first.
    pub fn new(reader: &Reader, grid: &Grid, offset_deg: f64, sign: Sign, values: Values) -> Self {
        let s = match sign {
            Sign::Error => 1.0,
            Sign::Correction => -1.0,
        };
        let col = |d| reader.column(grid, d).into_iter().map(|e| s * (e - offset_deg)).collect();
        let mut columns = vec![col(Direction::Forward)];
        if reader.is_separate() {
            columns.push(col(Direction::Reverse));
        }
        Self { grid: *grid, sign, values, columns }
    }

    /// The CSV text.
    pub fn text(&self) -> String {
        let mut s = String::from("position_deg");
        let suffix = if self.values == Values::Incremental { "_increment" } else { "" };
        let dirs: &[&str] = if self.columns.len() == 2 { &["forward_", "reverse_"] } else { &[""] };
        for d in dirs {
            let _ = write!(s, ",{d}{}{suffix}_deg", self.sign.as_str());
        }
        s.push('\n');
        for i in 0..self.grid.points {
            let _ = write!(s, "{:.10}", self.grid.position(i));
            for c in &self.columns {
                let v = match (self.values, i) {
                    (Values::Incremental, i) if i > 0 => c[i] - c[i - 1],
                    _ => c[i],
                };
                let _ = write!(s, ",{v:.10}");
            }
            s.push('\n');
        }
        s
    }
}
