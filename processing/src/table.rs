//! Correction tables: the readout error as a function of the readout angle.
//!
//! Rows sit at uniform spacing `360/n` from 0 to `360 - 360/n`, the table wraps
//! at 360 and is read with linear interpolation (the contract's table format).
//! The corrected angle is `readout - error(readout)`.

use crate::types::Direction;
use serde::{Deserialize, Serialize};

/// A correction table. `reverse` is present for a direction-aware table, in
/// which case `forward` holds the error for forward approaches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CorrectionTable {
    pub forward: Vec<f64>,
    pub reverse: Option<Vec<f64>>,
}

/// Why a table cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TableError {
    #[error("a correction table needs at least 2 rows, got {0}")]
    TooShort(usize),
    #[error("forward and reverse columns differ in length ({forward} vs {reverse})")]
    LengthMismatch { forward: usize, reverse: usize },
    #[error("row {row} is not a finite number")]
    NotFinite { row: usize },
}

impl CorrectionTable {
    /// A table with one error column for both directions.
    pub fn new(errors_deg: Vec<f64>) -> Result<Self, TableError> {
        Self::build(errors_deg, None)
    }

    /// A direction-aware table.
    pub fn directional(forward: Vec<f64>, reverse: Vec<f64>) -> Result<Self, TableError> {
        Self::build(forward, Some(reverse))
    }

    fn build(forward: Vec<f64>, reverse: Option<Vec<f64>>) -> Result<Self, TableError> {
        if forward.len() < 2 {
            return Err(TableError::TooShort(forward.len()));
        }
        if let Some(r) = &reverse
            && r.len() != forward.len()
        {
            return Err(TableError::LengthMismatch { forward: forward.len(), reverse: r.len() });
        }
        let all = forward.iter().chain(reverse.iter().flatten());
        if let Some(row) = all.clone().position(|v| !v.is_finite()) {
            return Err(TableError::NotFinite { row: row % forward.len() });
        }
        Ok(Self { forward, reverse })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.forward.len()
    }

    /// Never true: a table has at least two rows.
    pub fn is_empty(&self) -> bool {
        self.forward.is_empty()
    }

    /// Whether the table holds separate forward and reverse columns.
    pub fn is_directional(&self) -> bool {
        self.reverse.is_some()
    }

    /// Row spacing in degrees.
    pub fn spacing_deg(&self) -> f64 {
        360.0 / self.forward.len() as f64
    }

    /// The readout angle of row `i`.
    pub fn readout_at(&self, i: usize) -> f64 {
        i as f64 * self.spacing_deg()
    }

    /// The error at `readout_deg` for an approach in `direction`, read with
    /// linear interpolation between rows and wrapping at 360. Constant time.
    /// This is the one reading of a table: the real-time
    /// [`crate::corrector::Corrector`] precomputes the same slopes and gives
    /// the same bits.
    pub fn error_at(&self, readout_deg: f64, direction: Direction) -> f64 {
        let col = match (direction, &self.reverse) {
            (Direction::Reverse, Some(r)) => r.as_slice(),
            _ => self.forward.as_slice(),
        };
        let n = col.len();
        let (i, frac) = row_position(readout_deg, n, n as f64, n as f64 / 360.0, 1.0 / n as f64);
        let a = col[i];
        a + (col[(i + 1) % n] - a) * frac
    }

    /// The corrected angle `readout - error(readout)`.
    pub fn correct(&self, readout_deg: f64, direction: Direction) -> f64 {
        readout_deg - self.error_at(readout_deg, direction)
    }
}

/// Where `readout_deg` falls in a table of `rows` rows: the row below it and
/// the fraction of the way to the next (wrapping at 360, any turn), with
/// `rows_f = rows`, `scale = rows / 360` and `inv_rows = 1 / rows` passed in
/// so that the real-time corrector computes them once. No division and no
/// branch on the table size; `as usize` saturates (a negative or NaN position
/// gives row 0), so no input can index out of range.
#[inline(always)]
pub fn row_position(readout_deg: f64, rows: usize, rows_f: f64, scale: f64, inv_rows: f64) -> (usize, f64) {
    let p = readout_deg * scale;
    let p = p - rows_f * (p * inv_rows).floor();
    // Rounding can give p == rows: clamped to the last row, fraction 1.
    // Through `i64` (a NaN gives 0 as well): a float's conversion to an
    // unsigned integer, and back, take several instructions each on x86-64.
    let i = (p as i64).clamp(0, rows as i64 - 1);
    (i as usize, p - i as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_between_rows_and_wraps() {
        let t = CorrectionTable::new(vec![0.0, 0.01, 0.02, 0.03]).unwrap();
        assert_eq!(t.spacing_deg(), 90.0);
        assert!((t.error_at(45.0, Direction::Forward) - 0.005).abs() < 1e-15);
        // Between the last row (270) and the wrap to row 0 at 360.
        assert!((t.error_at(315.0, Direction::Forward) - 0.015).abs() < 1e-15);
        assert!((t.error_at(-45.0, Direction::Reverse) - 0.015).abs() < 1e-15);
        assert!((t.correct(90.0, Direction::Forward) - (90.0 - 0.01)).abs() < 1e-12);
    }

    #[test]
    fn directional_table_reads_its_own_column() {
        let t = CorrectionTable::directional(vec![0.001; 8], vec![-0.001; 8]).unwrap();
        assert_eq!(t.error_at(10.0, Direction::Forward), 0.001);
        assert_eq!(t.error_at(10.0, Direction::Reverse), -0.001);
    }

    #[test]
    fn rejects_bad_tables() {
        assert_eq!(CorrectionTable::new(vec![0.0]), Err(TableError::TooShort(1)));
        assert!(matches!(
            CorrectionTable::directional(vec![0.0; 4], vec![0.0; 3]),
            Err(TableError::LengthMismatch { .. })
        ));
        assert_eq!(CorrectionTable::new(vec![0.0, f64::NAN]), Err(TableError::NotFinite { row: 1 }));
    }
}
