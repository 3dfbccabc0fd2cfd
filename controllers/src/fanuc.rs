//! Fanuc stored pitch-error compensation (0i/16i/18i/15i parameter manuals),
//! as a text file for the person who enters it: the parameters 3620-3625
//! (and 3605#0, 3626, 3627 for a bidirectional table) beside the values.
//!
//! The control adds the compensation to the motion ("error +, value -" in the
//! manuals' sense of error, `actual - command`, which is minus ours). A value
//! is an increment: point `n` holds the change of the compensation over the
//! section that ends at point `n`, in detection units x magnification (3623),
//! a whole number. With `C(theta) = e(theta) - e(reference)` (our error,
//! `readout - actual`, zero at the reference point) the values are
//! `v_n = R(theta_n) - R(theta_{n-1})`, `R = round(C / (unit x magnification))`:
//! rounding the cumulative compensation, not each increment, so the rounding
//! never accumulates and a revolution sums to exactly zero.
//!
//! - Rotary type (a full-circle table over one revolution): 3621, the most
//!   negative number, is the reference point's number 3620; 3622 = 3620 +
//!   (travel per revolution 3625) / (interval 3624); the values from 3620 + 1
//!   to 3622 sum to zero, and the reference point's value equals the last
//!   point's (the manuals' example: "for compensation position 60, set the same
//!   compensation value as for 68").
//! - Linear type (a partial range, or several turns of a non-modulo rotary
//!   axis; 3625 = 0): 3621 = 3620 - (reference - start) / interval + 1,
//!   3622 = 3620 + (end - reference) / interval.
//! - Bidirectional (3605#0 = 1): a second table for travel in the negative
//!   direction, from number 3626 with the same layout, holding the reverse
//!   error relative to the forward error at the reference; 3627 is the absolute
//!   compensation at the reference point for an approach from the negative
//!   direction (its value in the same units).
//!
//! Not confirmed publicly, so only checked and warned about: the per-point
//! limit (commonly -128..127 in units of the magnification), the total number
//! of points (commonly 1024, numbers 0-1023, shared by every axis), whether
//! 3624/3625 are entered in detection units or in degrees (both are printed),
//! the punch-data record format (not written: the values are printed as a
//! table), and the negative-direction table's layout on a rotary axis (written
//! like the positive one). Where within a section the control outputs a value
//! is not modelled: [`Applied`] interpolates linearly, exact at the points.

use super::layout::{Grid, Reader, whole};
use super::{Applied, AppliedLine};
use std::fmt::Write as _;
use survey_processing::Direction;
use survey_processing::num::Num;

/// The finest detection unit taken, degrees (IS-E is 1e-6 deg); a finer
/// one makes compensation values beyond any register.
pub const MIN_UNIT_DEG: f64 = 1e-7;

/// The common per-point limit (not confirmed publicly).
pub const VALUE_RANGE: std::ops::RangeInclusive<i64> = -128..=127;
/// The common number of compensation points (numbers 0-1023; not confirmed publicly).
pub const COMMON_POINTS: u32 = 1024;

/// The control's units and numbering.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FanucOptions {
    /// Detection unit, degrees (0.001 for IS-B).
    pub unit_deg: f64,
    /// Magnification, parameter 3623 (1 to 100).
    pub magnification: u32,
    /// The reference point's compensation number, 3620 (default: 0 for a
    /// rotary table; the smallest that keeps every number from 0 otherwise).
    pub reference_number: Option<u32>,
    /// The reference point, degrees (a point of the grid).
    pub reference_deg: f64,
}

impl Default for FanucOptions {
    fn default() -> Self {
        Self { unit_deg: 0.001, magnification: 1, reference_number: None, reference_deg: 0.0 }
    }
}

/// Why the table cannot be made; each names the `[export]` key at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct FanucError {
    /// The recipe's `[export]` key.
    pub key: &'static str,
    /// What is wrong.
    pub message: String,
}

fn fail<T>(key: &'static str, message: String) -> Result<T, FanucError> {
    Err(FanucError { key, message })
}

/// One direction's table: numbers, values, and the cumulative compensation at
/// each grid point.
#[derive(Debug, Clone, PartialEq)]
pub struct FanucColumn {
    /// The compensation numbers, in order, and their values (detection units x magnification).
    pub values: Vec<(u32, i64)>,
    /// `R_k`: the cumulative compensation at grid point `k`, same units.
    pub absolute: Vec<i64>,
}

/// A stored pitch-error compensation table and its parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct FanucTable {
    /// Units and numbering.
    pub options: FanucOptions,
    /// The points (a rotary table starts at the reference point).
    pub grid: Grid,
    /// Rotary type (one revolution, 3625 set) or linear type.
    pub rotary: bool,
    /// Index of the reference point in the grid.
    pub reference_index: usize,
    /// 3620.
    pub reference_number: u32,
    /// The table for travel in the positive direction (the only one when not bidirectional).
    pub forward: FanucColumn,
    /// The table for travel in the negative direction, when bidirectional.
    pub reverse: Option<FanucColumn>,
    /// What exceeds the common (unconfirmed) limits.
    pub warnings: Vec<String>,
}

impl FanucTable {
    /// The table on `grid` read from `reader`. A periodic reader over exactly
    /// one revolution gives the rotary type (re-based to start at the
    /// reference point); anything else the linear type, whose reference point
    /// must be a point of the grid.
    pub fn new(reader: &Reader, grid: &Grid, options: FanucOptions) -> Result<Self, FanucError> {
        let u = options.unit_deg;
        if !(MIN_UNIT_DEG..=1.0).contains(&u) {
            return fail(
                "fanuc_unit_deg",
                format!("must be a detection unit from {} to 1 deg, got {}", Num(MIN_UNIT_DEG), Num(u)),
            );
        }
        if !(1..=100).contains(&options.magnification) {
            return fail("fanuc_magnification", format!("must be from 1 to 100, got {}", options.magnification));
        }
        if whole(grid.interval_deg / u).is_none() {
            return fail(
                "interval_deg",
                format!(
                    "the interval {} deg is not a whole number of detection units ({} deg): parameter 3624 holds whole units",
                    Num(grid.interval_deg),
                    Num(u)
                ),
            );
        }
        let reference = options.reference_deg;
        let rotary = reader.is_periodic() && (grid.span_deg() - 360.0).abs() < 1e-9;
        let (grid, reference_index) = if rotary {
            if whole(360.0 / u).is_none() {
                return fail("fanuc_unit_deg", format!("360 deg is not a whole number of {} deg units (3625)", Num(u)));
            }
            let off = (reference - grid.start_deg).rem_euclid(360.0) / grid.interval_deg;
            if whole(off).is_none() && whole(off - (grid.points - 1) as f64).is_none() {
                return fail(
                    "reference_deg",
                    format!(
                        "the reference point {} deg is not a point of the table (every {} deg)",
                        Num(reference),
                        Num(grid.interval_deg)
                    ),
                );
            }
            (Grid { start_deg: reference, ..*grid }, 0)
        } else {
            match grid.index_of(reference) {
                Some(j) => (*grid, j),
                None => {
                    return fail(
                        "reference_deg",
                        format!(
                            "the reference point {} deg is not a point of the table ({}..{} deg every {} deg)",
                            Num(reference),
                            Num(grid.start_deg),
                            Num(grid.end_deg()),
                            Num(grid.interval_deg)
                        ),
                    );
                }
            }
        };
        let k_last = grid.points - 1;
        let r = match options.reference_number {
            Some(r) => {
                if !rotary && (r as usize) + 1 < reference_index {
                    return fail(
                        "fanuc_reference_number",
                        format!(
                            "{r} would number the most negative point {}: it must be at least {}",
                            r as i64 - reference_index as i64 + 1,
                            reference_index - 1
                        ),
                    );
                }
                r
            }
            None if rotary => 0,
            None => reference_index.saturating_sub(1) as u32,
        };
        let scale = u * options.magnification as f64;
        let zero = reader.error_at(reference, Direction::Forward);
        let absolute = |d: Direction| -> Vec<i64> {
            let mut a: Vec<i64> = (0..grid.points)
                .map(|k| ((reader.error_at(grid.position(k), d) - zero) / scale).round() as i64)
                .collect();
            if rotary {
                a[k_last] = a[0];
            }
            a
        };
        let column = |absolute: Vec<i64>, first: u32| -> FanucColumn {
            let mut values: Vec<(u32, i64)> = Vec::with_capacity(grid.points);
            if rotary {
                values.push((first, absolute[k_last] - absolute[k_last - 1]));
            }
            for k in 1..=k_last {
                values.push((first + if rotary { k } else { k - 1 } as u32, absolute[k] - absolute[k - 1]));
            }
            FanucColumn { values, absolute }
        };
        let first_forward = if rotary { r } else { (r as usize + 1 - reference_index) as u32 };
        let forward = column(absolute(Direction::Forward), first_forward);
        let reverse = reader.is_separate().then(|| {
            let last = forward.values.last().map_or(first_forward, |v| v.0);
            column(absolute(Direction::Reverse), last + 1)
        });
        let mut table = Self {
            options,
            grid,
            rotary,
            reference_index,
            reference_number: r,
            forward,
            reverse,
            warnings: Vec::new(),
        };
        table.warnings = table.check_limits();
        Ok(table)
    }

    fn check_limits(&self) -> Vec<String> {
        let mut w = Vec::new();
        let mag = self.options.magnification;
        for (name, col) in [("positive", Some(&self.forward)), ("negative", self.reverse.as_ref())] {
            let Some(col) = col else { continue };
            let out: Vec<&(u32, i64)> = col.values.iter().filter(|(_, v)| !VALUE_RANGE.contains(v)).collect();
            if let Some(worst) = out.iter().max_by_key(|(_, v)| v.abs()) {
                w.push(format!(
                    "{} value(s) of the {name}-direction table exceed the common -128..127 limit (not confirmed publicly; the largest is {} at number {}): raise the magnification 3623 (now {mag}) or shorten the interval",
                    out.len(),
                    worst.1,
                    worst.0
                ));
            }
        }
        let highest = self.reverse.as_ref().unwrap_or(&self.forward).values.last().map_or(0, |v| v.0);
        if highest >= COMMON_POINTS {
            w.push(format!(
                "the numbers run to {highest}: many controls hold {COMMON_POINTS} points (0-{}) for every axis together (not confirmed publicly)",
                COMMON_POINTS - 1
            ));
        }
        w
    }

    /// The parameters, `(number, value, meaning)`.
    pub fn parameters(&self) -> Vec<(&'static str, String, String)> {
        let u = self.options.unit_deg;
        let units = |deg: f64| whole(deg / u).map_or_else(|| format!("{}", deg / u), |n| n.to_string());
        let first = self.forward.values.first().map_or(0, |v| v.0);
        let last = self.forward.values.last().map_or(0, |v| v.0);
        let mut p = vec![
            (
                "3620",
                self.reference_number.to_string(),
                format!(
                    "number of the reference point ({} deg)",
                    super::sinumerik::number(self.options.reference_deg, 9)
                ),
            ),
            ("3621", first.to_string(), "most negative number (travel in the positive direction)".into()),
            ("3622", last.to_string(), "most positive number (travel in the positive direction)".into()),
            ("3623", self.options.magnification.to_string(), "magnification".into()),
            (
                "3624",
                units(self.grid.interval_deg),
                format!(
                    "interval, detection units of {u} deg ({} deg)",
                    super::sinumerik::number(self.grid.interval_deg, 9)
                ),
            ),
            (
                "3625",
                if self.rotary { units(360.0) } else { "0".into() },
                if self.rotary {
                    "travel per revolution, detection units (360 deg): rotary type".into()
                } else {
                    "0: linear type".into()
                },
            ),
        ];
        if let Some(rev) = &self.reverse {
            p.push(("3605#0", "1".into(), "bidirectional pitch-error compensation".into()));
            p.push((
                "3626",
                rev.values.first().map_or(0, |v| v.0).to_string(),
                "most negative number (travel in the negative direction)".into(),
            ));
            p.push((
                "3627",
                rev.absolute[self.reference_index].to_string(),
                "compensation at the reference point approached in the negative direction (absolute)".into(),
            ));
        }
        p
    }

    /// The text file: what it is, the parameters, the values (see the module documentation).
    pub fn text(&self) -> String {
        let mut s = String::new();
        let unit = self.options.unit_deg * self.options.magnification as f64;
        let _ = writeln!(
            s,
            "FANUC stored pitch-error compensation, {} type{}.",
            if self.rotary { "rotary" } else { "linear" },
            if self.reverse.is_some() { ", bidirectional" } else { "" }
        );
        let _ = writeln!(
            s,
            "Values: increments over the section ending at each point, in detection units x magnification ({} deg); the reference point is at {} deg.",
            super::sinumerik::number(unit, 12),
            super::sinumerik::number(self.options.reference_deg, 9)
        );
        s.push_str(
            "The punch-data record format is not public: enter the parameters and values by hand or convert them.\n",
        );
        s.push_str("\nPARAMETERS\n");
        for (n, v, what) in self.parameters() {
            let _ = writeln!(s, "{n:<7} {v:>10}   {what}");
        }
        for w in &self.warnings {
            let _ = writeln!(s, "WARNING {w}");
        }
        let mut table = |title: &str, col: &FanucColumn| {
            let _ = writeln!(s, "\n{title}\n{:>6} {:>14} {:>6}", "number", "position_deg", "value");
            // A rotary table's first number is the reference point's (the section
            // ending there, the last of the previous revolution); a linear
            // table's first is the section ending at the second point.
            let offset = usize::from(!self.rotary);
            for (i, (n, v)) in col.values.iter().enumerate() {
                let pos = self.grid.position(i + offset);
                let _ = writeln!(s, "{n:>6} {:>14} {v:>6}", format!("{pos:.6}"));
            }
        };
        match &self.reverse {
            None => table("VALUES", &self.forward),
            Some(rev) => {
                table("VALUES, TRAVEL IN THE POSITIVE DIRECTION", &self.forward);
                table("VALUES, TRAVEL IN THE NEGATIVE DIRECTION", rev);
            }
        }
        s
    }
}

impl Applied for FanucTable {
    /// The cumulative compensation, relative to the reference point, linear
    /// between points; a rotary table repeats every revolution, a linear one
    /// holds its ends.
    fn applied(&self, direction: Direction) -> AppliedLine {
        let col = match (direction, &self.reverse) {
            (Direction::Reverse, Some(r)) => r,
            _ => &self.forward,
        };
        let scale = self.options.unit_deg * self.options.magnification as f64;
        AppliedLine::new(&self.grid, col.absolute.iter().map(|&r| r as f64 * scale).collect(), self.rotary)
    }

    fn range_deg(&self) -> (f64, f64) {
        if self.rotary { (f64::NEG_INFINITY, f64::INFINITY) } else { (self.grid.start_deg, self.grid.end_deg()) }
    }
}
