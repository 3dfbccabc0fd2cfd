//! Siemens SINUMERIK 840D measuring-system error compensation (EEC): the
//! `%_N_AX_EEC_INI` file (Function Manual Extended Functions, K3).
//!
//! ```text
//! %_N_AX_EEC_INI
//! CHANDATA(1)
//! $AA_ENC_COMP[0,0,C1]=<value at MIN>
//! ...
//! $AA_ENC_COMP[0,k,C1]=<value at MIN + k STEP>
//! $AA_ENC_COMP_STEP[0,C1]=<STEP>
//! $AA_ENC_COMP_MIN[0,C1]=<MIN>
//! $AA_ENC_COMP_MAX[0,C1]=<MAX>
//! $AA_ENC_COMP_IS_MODULO[0,C1]=<1 or 0>
//! ; zero at the reference point 0 deg (K3); --sinumerik-absolute keeps absolute values
//! M17
//! ```
//!
//! The index is `[measuring system (0 or 1), point, machine axis]`. The control
//! interpolates linearly between points; outside MIN..MAX the end values hold
//! unless modulo is set. Sign: "a positive compensation value causes the
//! machine axis to move in the negative direction": the value is added to the
//! measuring system's position, so a value is `actual - readout`, minus our
//! error (`actual = readout + value`). A rotary axis over exactly 0..360 is
//! written modulo, with equal end values. The values are zero at the
//! reference point by default, as the K3 manual asks for the compensation
//! value there; `[export] sinumerik_absolute = true` (`survey process
//! --sinumerik-absolute`) keeps them absolute. A comment line (`;`, the NC
//! language's comment) before `M17` says which. The compensation is one
//! table for both directions: a direction-aware table is written as the mean of
//! its directions (the direction-dependent CEC tables' sign was not found
//! stated publicly). MD38000 `$MA_MM_ENC_COMP_MAX_POINTS` must reserve at least
//! the points written ((MAX - MIN) / STEP + 1), and the tables load only while
//! MD32700 `$MA_ENC_COMP_ENABLE` is 0.
//!
//! The axis name is the machine axis name of the control's configuration
//! (`C1` by default, the first C axis; `A1`, `B1`, `AX4` are others). Values
//! are written with 7 decimals (1e-7 deg), positions with up to 9.

use super::layout::{Grid, Reader};
use super::{Applied, AppliedLine};
use std::fmt::Write as _;
use survey_processing::Direction;

/// The axis name written when none is given.
pub const DEFAULT_AXIS: &str = "C1";

/// What the file names: the machine axis and its measuring system.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SinumerikOptions {
    /// Machine axis name (`C1`).
    pub axis: String,
    /// Measuring system, 0 or 1.
    pub measuring_system: u8,
}

/// Why the file cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SinumerikError {
    /// The axis name is not a machine axis name.
    #[error(
        "'{0}' is not a machine axis name (a letter, then letters, digits or '_', at most 16 characters: C1, A1, AX4)"
    )]
    BadAxis(String),
    /// The measuring system is not 0 or 1.
    #[error("the measuring system is 0 or 1, got {0}")]
    BadMeasuringSystem(u8),
}

/// Check an axis name.
pub fn check_axis(axis: &str) -> Result<(), SinumerikError> {
    let mut chars = axis.chars();
    let ok = chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        && axis.len() <= 16;
    if ok { Ok(()) } else { Err(SinumerikError::BadAxis(axis.to_string())) }
}

/// The compensation table of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Sinumerik840d {
    /// The axis and measuring system.
    pub options: SinumerikOptions,
    /// The points.
    pub grid: Grid,
    /// `$AA_ENC_COMP` values, `actual - readout`, degrees.
    pub values_deg: Vec<f64>,
    /// `$AA_ENC_COMP_IS_MODULO`.
    pub modulo: bool,
    /// The reference point the values are zero at, degrees (`None`: absolute values).
    pub zero_at_deg: Option<f64>,
}

impl Sinumerik840d {
    /// The table on `grid` read from `reader` (one column: the mean of the
    /// directions of a direction-aware table), zero at the reference point
    /// `zero_at_deg` when one is given (its error subtracted from every value).
    pub fn new(
        reader: &Reader,
        grid: &Grid,
        zero_at_deg: Option<f64>,
        options: SinumerikOptions,
    ) -> Result<Self, SinumerikError> {
        check_axis(&options.axis)?;
        if options.measuring_system > 1 {
            return Err(SinumerikError::BadMeasuringSystem(options.measuring_system));
        }
        let modulo = reader.is_periodic() && grid.is_zero_to_360();
        let error = |p: f64| {
            if reader.is_separate() {
                0.5 * (reader.error_at(p, Direction::Forward) + reader.error_at(p, Direction::Reverse))
            } else {
                reader.error_at(p, Direction::Forward)
            }
        };
        let offset_deg = zero_at_deg.map_or(0.0, error);
        let mut values_deg: Vec<f64> = (0..grid.points).map(|i| -(error(grid.position(i)) - offset_deg)).collect();
        if modulo {
            let first = values_deg[0];
            *values_deg.last_mut().expect("a grid has two points or more") = first;
        }
        Ok(Self { options, grid: *grid, values_deg, modulo, zero_at_deg })
    }

    /// The `%_N_AX_EEC_INI` file.
    pub fn text(&self) -> String {
        let (e, ax) = (self.options.measuring_system, &self.options.axis);
        let mut s = String::with_capacity(self.values_deg.len() * 40 + 200);
        s.push_str("%_N_AX_EEC_INI\nCHANDATA(1)\n");
        for (n, v) in self.values_deg.iter().enumerate() {
            let _ = writeln!(s, "$AA_ENC_COMP[{e},{n},{ax}]={}", number(*v, 7));
        }
        let _ = writeln!(s, "$AA_ENC_COMP_STEP[{e},{ax}]={}", number(self.grid.interval_deg, 9));
        let _ = writeln!(s, "$AA_ENC_COMP_MIN[{e},{ax}]={}", number(self.grid.start_deg, 9));
        let _ = writeln!(s, "$AA_ENC_COMP_MAX[{e},{ax}]={}", number(self.grid.end_deg(), 9));
        let _ = writeln!(s, "$AA_ENC_COMP_IS_MODULO[{e},{ax}]={}", u8::from(self.modulo));
        match self.zero_at_deg {
            Some(r) => {
                let _ = writeln!(
                    s,
                    "; zero at the reference point {} deg (K3); --sinumerik-absolute keeps absolute values",
                    number(r, 9)
                );
            }
            None => s.push_str("; absolute values, not zero at the reference point (--sinumerik-absolute)\n"),
        }
        s.push_str("M17\n");
        s
    }
}

/// `x` with at most `decimals` decimals, trailing zeros dropped (`0.5`, `-0.0012345`, `360`).
pub(crate) fn number(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    if s == "-0" { "0".into() } else { s }
}

impl Applied for Sinumerik840d {
    /// The control adds the interpolated value to the measured position: the
    /// error it removes is minus the value; modulo wraps, else the ends hold.
    fn applied(&self, _direction: Direction) -> AppliedLine {
        AppliedLine::new(&self.grid, self.values_deg.iter().map(|v| -v).collect(), self.modulo)
    }

    fn range_deg(&self) -> (f64, f64) {
        if self.modulo { (f64::NEG_INFINITY, f64::INFINITY) } else { (self.grid.start_deg, self.grid.end_deg()) }
    }
}
