//! LinuxCNC joint compensation files, for `[JOINT_n] COMP_FILE = ...` with
//! `COMP_FILE_TYPE = 0` and `1`.
//!
//! Looked up in LinuxCNC's source (LinuxCNC/linuxcnc): `src/emc/ini/inijoint.cc`
//! reads `COMP_FILE_TYPE` (default 0); `usrmotLoadComp` in
//! `src/emc/motion/usrmotintf.cc` reads one `nominal forward reverse` triplet
//! per line with `sscanf("%lf %lf %lf")` and stops at the first line that is
//! not one, so there is no header line; type 0 holds positions and is turned
//! into trims as `nominal - forward`, type 1 holds the trims directly;
//! `EMCMOT_SET_JOINT_COMP` in `command.c` refuses more than
//! `EMCMOT_COMP_SIZE` = 256 entries and nominals that do not increase; and
//! `control.c` indexes the table by the commanded joint position, adds the
//! forward trim to the motor command while moving up and the reverse trim while
//! moving down, interpolating linearly between entries and holding the end
//! values outside the table (there is no modulo: a rotary joint's machine
//! position runs past 360 and below 0). So a table over 0..360 corrects one
//! turn only; [`LinuxCncTable`] covers the joint range it is given, several
//! turns included.
//!
//! The motor position is our readout and the trim that puts the axis on the
//! commanded angle is our error `readout - actual`, so a line is
//! `nominal  nominal-error_fwd  nominal-error_rev` (type 0: the actual angles
//! the axis reaches) or `nominal  error_fwd  error_rev` (type 1), ascending
//! nominals, 10 decimals.

use super::layout::{Grid, Reader};
use super::{Applied, AppliedLine};
use std::fmt::Write as _;
use survey_processing::Direction;

/// The most entries LinuxCNC holds (`EMCMOT_COMP_SIZE`).
pub const MAX_POINTS: usize = 256;

/// A joint compensation table: nominal joint positions and the trims.
#[derive(Debug, Clone, PartialEq)]
pub struct LinuxCncTable {
    /// The nominal joint positions, degrees: a uniform grid.
    pub grid: Grid,
    /// Trim while moving up (our forward error), degrees.
    pub forward_deg: Vec<f64>,
    /// Trim while moving down (our reverse error), degrees.
    pub reverse_deg: Vec<f64>,
}

/// Why a LinuxCNC table cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinuxCncError {
    /// More than 256 points.
    #[error("LinuxCNC holds at most {MAX_POINTS} points, the range and interval give {0}")]
    TooManyPoints(usize),
}

impl LinuxCncTable {
    /// The table on `grid` read from `reader`, `offset_deg` subtracted from
    /// every trim (the error at the reference point, to zero it there; 0 keeps
    /// the table's own zero).
    pub fn new(reader: &Reader, grid: &Grid, offset_deg: f64) -> Result<Self, LinuxCncError> {
        if grid.points > MAX_POINTS {
            return Err(LinuxCncError::TooManyPoints(grid.points));
        }
        let col = |d| reader.column(grid, d).into_iter().map(|e| e - offset_deg).collect();
        Ok(Self { grid: *grid, forward_deg: col(Direction::Forward), reverse_deg: col(Direction::Reverse) })
    }

    /// The file of `COMP_FILE_TYPE` 0 (positions) or 1 (trims).
    pub fn text(&self, file_type: u8) -> String {
        let mut s = String::with_capacity(self.grid.points * 48);
        let nominal = (0..self.grid.points).map(|i| self.grid.position(i));
        for ((n, f), r) in nominal.zip(&self.forward_deg).zip(&self.reverse_deg) {
            let (a, b) = if file_type == 0 { (n - f, n - r) } else { (*f, *r) };
            let _ = writeln!(s, "{n:.10} {a:.10} {b:.10}");
        }
        s
    }
}

impl Applied for LinuxCncTable {
    /// `control.c`: the trim at the commanded position, linear between entries,
    /// the end values outside.
    fn applied(&self, direction: Direction) -> AppliedLine {
        let trims = match direction {
            Direction::Forward => &self.forward_deg,
            Direction::Reverse => &self.reverse_deg,
        };
        AppliedLine::new(&self.grid, trims.clone(), false)
    }

    fn range_deg(&self) -> (f64, f64) {
        (self.grid.start_deg, self.grid.end_deg())
    }
}
