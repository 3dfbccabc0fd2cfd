//! Where a controller table's points fall and what they hold: the range and
//! spacing the user chose (or each format's default), the table read at
//! those points, low-passed to what the spacing can hold, and which
//! directions it holds.
//!
//! A full-circle table is periodic: it is read at any joint position, several
//! turns included (a controller that holds its end values and never wraps,
//! like LinuxCNC, needs its table over the joint's whole range). Before it is
//! read, every line at or above half the points per revolution of the chosen
//! spacing is removed (a line the coarse table cannot hold is dropped rather
//! than aliased to a false low-frequency error). A partial-range table is read
//! as it is, inside the measured range only.

use serde::{Deserialize, Serialize};
use survey_processing::Direction;
use survey_processing::num::Num;
use survey_processing::resample::Resampler;
use survey_processing::table::CorrectionTable;

/// Relative tolerance on "a whole number of intervals".
const WHOLE: f64 = 1e-6;

/// Which directions a controller table holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Directions {
    /// Forward and reverse when the table is direction-aware, else one.
    #[default]
    Auto,
    /// One set of values for both directions (the mean of a direction-aware table).
    Combined,
    /// Forward and reverse (equal for a one-column table).
    Separate,
}

/// The user's choice of range and spacing; `None` takes the format's default.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RangeChoice {
    /// First position, degrees.
    pub start_deg: Option<f64>,
    /// Last position, degrees.
    pub end_deg: Option<f64>,
    /// Spacing, degrees (or `points`).
    pub interval_deg: Option<f64>,
    /// Number of points (or `interval_deg`).
    pub points: Option<usize>,
}

/// What the survey's table covers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Span {
    /// A full revolution: the table is periodic and can be read anywhere.
    FullCircle,
    /// Only the measured range, degrees.
    Measured {
        /// First measured target.
        start: f64,
        /// Last measured target.
        end: f64,
    },
}

/// A format's spacing when the user gives none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DefaultSpacing {
    /// The finest spacing that keeps the range within this many points; over a
    /// full circle, a whole number of points per revolution when one fits, so
    /// every turn holds the same values.
    FinestWithin(usize),
    /// About this spacing: exactly, when the range is a whole number of it or
    /// is a measured range the user left open (then the multiples of the
    /// spacing inside it); else the nearest spacing that divides the range.
    Interval(f64),
}

/// Uniform points from `start_deg`, `interval_deg` apart.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Grid {
    /// First position, degrees.
    pub start_deg: f64,
    /// Spacing, degrees.
    pub interval_deg: f64,
    /// Number of points (at least 2).
    pub points: usize,
}

impl Grid {
    /// Position of point `i`, degrees.
    pub fn position(&self, i: usize) -> f64 {
        self.start_deg + i as f64 * self.interval_deg
    }

    /// Last position, degrees.
    pub fn end_deg(&self) -> f64 {
        self.position(self.points - 1)
    }

    /// The span, degrees.
    pub fn span_deg(&self) -> f64 {
        self.end_deg() - self.start_deg
    }

    /// Whether the grid is exactly one revolution from 0 to 360.
    pub fn is_zero_to_360(&self) -> bool {
        self.start_deg.abs() < 1e-9 && (self.end_deg() - 360.0).abs() < 1e-9
    }

    /// The index of the point at `deg`, when there is one.
    pub fn index_of(&self, deg: f64) -> Option<usize> {
        let k = (deg - self.start_deg) / self.interval_deg;
        let r = k.round();
        ((k - r).abs() <= WHOLE * k.abs().max(1.0) && r >= 0.0 && (r as usize) < self.points).then_some(r as usize)
    }
}

/// A choice that does not make a grid, naming the `[export]` key at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct LayoutError {
    /// The recipe's `[export]` key (`start_deg`, `end_deg`, `interval_deg`, `points`).
    pub key: &'static str,
    /// What is wrong.
    pub message: String,
}

fn err(key: &'static str, message: String) -> LayoutError {
    LayoutError { key, message }
}

/// Whether `x` is a whole number within the tolerance; the number if so.
/// The widest a table reaches: +/-3600 deg (ten turns either way, the
/// travel a configuration allows).
pub const MAX_TABLE_DEG: f64 = 3600.0;

pub(crate) fn whole(x: f64) -> Option<u64> {
    let r = x.round();
    ((x - r).abs() <= WHOLE * x.abs().max(1.0) && r >= 0.0).then_some(r as u64)
}

/// The grid of `choice` over `span`, `default` filling what the choice leaves open.
pub fn resolve(choice: &RangeChoice, span: Span, default: DefaultSpacing) -> Result<Grid, LayoutError> {
    let (lo, hi) = match span {
        Span::FullCircle => (0.0, 360.0),
        Span::Measured { start, end } => (start, end),
    };
    let start = choice.start_deg.unwrap_or(lo);
    let end = choice.end_deg.unwrap_or(hi);
    if !(start.is_finite() && start.abs() <= MAX_TABLE_DEG) {
        return Err(err("start_deg", format!("must be an angle within +/-{MAX_TABLE_DEG} deg, got {}", Num(start))));
    }
    if !(end.is_finite() && end.abs() <= MAX_TABLE_DEG) || end <= start {
        return Err(err(
            "end_deg",
            format!(
                "must be an angle above the start ({} deg) within +/-{MAX_TABLE_DEG} deg, got {}",
                Num(start),
                Num(end)
            ),
        ));
    }
    if let Span::Measured { start: s, end: e } = span {
        let tol = 1e-9 * (e - s).abs().max(1.0);
        if start < s - tol {
            return Err(err(
                "start_deg",
                format!(
                    "{} deg is outside the measured range {}..{} deg: a partial-range table holds nothing outside what was measured",
                    Num(start),
                    Num(s),
                    Num(e)
                ),
            ));
        }
        if end > e + tol {
            return Err(err(
                "end_deg",
                format!(
                    "{} deg is outside the measured range {}..{} deg: a partial-range table holds nothing outside what was measured",
                    Num(end),
                    Num(s),
                    Num(e)
                ),
            ));
        }
    }
    let span_deg = end - start;
    let grid = |interval_deg: f64, points: usize| Grid { start_deg: start, interval_deg, points };
    match (choice.interval_deg, choice.points) {
        (Some(_), Some(_)) => Err(err("points", "give interval_deg or points, not both".into())),
        (Some(d), None) => {
            if !(d.is_finite() && d > 0.0) {
                return Err(err("interval_deg", format!("must be a positive number of degrees, got {}", Num(d))));
            }
            match whole(span_deg / d) {
                Some(n) if (1..1 << 24).contains(&n) => Ok(grid(span_deg / n as f64, n as usize + 1)),
                _ => Err(err(
                    "interval_deg",
                    format!(
                        "the range {}..{} deg ({} deg) is not a whole number of {} deg intervals",
                        Num(start),
                        Num(end),
                        Num(span_deg),
                        Num(d)
                    ),
                )),
            }
        }
        (None, Some(p)) => {
            if !(2..1 << 24).contains(&p) {
                return Err(err("points", format!("must be at least 2, got {p}")));
            }
            Ok(grid(span_deg / (p - 1) as f64, p))
        }
        (None, None) => Ok(match default {
            DefaultSpacing::FinestWithin(max) => {
                let max = max.max(2);
                let per_turn = ((max - 1) as f64 * 360.0 / span_deg).floor();
                let turns = (span == Span::FullCircle && per_turn >= 1.0)
                    .then(|| whole(span_deg * per_turn / 360.0))
                    .flatten()
                    .filter(|&n| n >= 1 && (n as usize) < max);
                match turns {
                    Some(n) => grid(360.0 / per_turn, n as usize + 1),
                    None => grid(span_deg / (max - 1) as f64, max),
                }
            }
            DefaultSpacing::Interval(d) => {
                // A measured range the user did not bound is laid on the
                // multiples of the spacing inside it (-9.86..89.86 every 1
                // deg: -9..89), so the spacing stays exact: a controller that
                // counts in detection units (Fanuc) takes it, and the points
                // are the round positions an operator expects.
                let (first, last) = ((start / d - WHOLE).ceil(), (end / d + WHOLE).floor());
                let unbounded = choice.start_deg.is_none() && choice.end_deg.is_none();
                if matches!(span, Span::Measured { .. }) && unbounded && last > first {
                    let n = (last - first) as usize;
                    Grid { start_deg: first * d, interval_deg: d, points: n + 1 }
                } else {
                    let n = (span_deg / d).round().max(1.0) as usize;
                    grid(span_deg / n as f64, n + 1)
                }
            }
        }),
    }
}

/// The table as a controller file holds it: read at any position, per
/// direction, low-passed to a spacing (full circle) and either direction-aware
/// or the mean of both directions.
#[derive(Debug, Clone)]
pub struct Reader {
    table: CorrectionTable,
    periodic: bool,
    separate: bool,
}

impl Reader {
    /// `table` read at points `interval_deg` apart: over a full circle
    /// (`periodic`), its lines at or above half the points per revolution are
    /// removed first. `separate`: keep the forward and reverse columns of a
    /// directional table; else both directions read their mean.
    pub fn new(table: &CorrectionTable, periodic: bool, interval_deg: f64, separate: bool) -> Self {
        let mut table = table.clone();
        if periodic {
            let per_turn = (360.0 / interval_deg + 1e-9).floor().max(1.0) as usize;
            // Lines strictly below per_turn / 2 are held.
            let keep = (per_turn - 1) / 2;
            if keep < table.len() / 2 {
                let mut rs = Resampler::new();
                let mut low = |col: &[f64]| {
                    let mut s = rs.analyze(col);
                    s.truncate(keep);
                    rs.synthesize(&s, col.len())
                };
                let f = low(&table.forward);
                let r = table.reverse.as_deref().map(&mut low);
                table = CorrectionTable { forward: f, reverse: r };
            }
        }
        Self { table, periodic, separate }
    }

    /// Whether the two directions read different columns.
    pub fn is_separate(&self) -> bool {
        self.separate && self.table.is_directional()
    }

    /// Whether the table repeats every revolution.
    pub fn is_periodic(&self) -> bool {
        self.periodic
    }

    /// The error `readout - actual` at `position_deg` for `direction`, degrees.
    pub fn error_at(&self, position_deg: f64, direction: Direction) -> f64 {
        if self.separate || !self.table.is_directional() {
            self.table.error_at(position_deg, direction)
        } else {
            0.5 * (self.table.error_at(position_deg, Direction::Forward)
                + self.table.error_at(position_deg, Direction::Reverse))
        }
    }

    /// The error at every point of `grid` for `direction`.
    pub fn column(&self, grid: &Grid, direction: Direction) -> Vec<f64> {
        (0..grid.points).map(|i| self.error_at(grid.position(i), direction)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn full(choice: RangeChoice, d: DefaultSpacing) -> Result<Grid, LayoutError> {
        resolve(&choice, Span::FullCircle, d)
    }

    #[test]
    fn defaults_fit_whole_turns_within_the_limit() {
        let g = full(RangeChoice::default(), DefaultSpacing::FinestWithin(256)).unwrap();
        assert_eq!((g.points, g.start_deg, g.end_deg()), (256, 0.0, 360.0));
        // -720..720: 63 points per turn, 252 intervals, 253 points.
        let c = RangeChoice { start_deg: Some(-720.0), end_deg: Some(720.0), ..RangeChoice::default() };
        let g = full(c, DefaultSpacing::FinestWithin(256)).unwrap();
        assert_eq!(g.points, 253);
        assert!((g.interval_deg - 360.0 / 63.0).abs() < 1e-12);
        assert!((g.end_deg() - 720.0).abs() < 1e-9);
        let g = full(RangeChoice::default(), DefaultSpacing::Interval(1.0)).unwrap();
        assert_eq!((g.points, g.interval_deg), (361, 1.0));
        let m = resolve(
            &RangeChoice::default(),
            Span::Measured { start: -10.0, end: 90.0 },
            DefaultSpacing::FinestWithin(256),
        )
        .unwrap();
        assert_eq!((m.points, m.start_deg, m.end_deg()), (256, -10.0, 90.0));
        // A measured range left open: the whole degrees inside it, the
        // spacing exact (Fanuc counts it in detection units).
        let span = Span::Measured { start: -9.861_111, end: 89.861_111 };
        let m = resolve(&RangeChoice::default(), span, DefaultSpacing::Interval(1.0)).unwrap();
        assert_eq!((m.points, m.start_deg, m.interval_deg, m.end_deg()), (99, -9.0, 1.0, 89.0));
        // Ends the user gave are kept: the spacing is stretched to divide them.
        let c = RangeChoice { start_deg: Some(-9.5), end_deg: Some(89.5), ..RangeChoice::default() };
        let m = resolve(&c, span, DefaultSpacing::Interval(1.0)).unwrap();
        assert_eq!((m.points, m.start_deg, m.end_deg()), (100, -9.5, 89.5));
    }

    #[test]
    fn choices_are_checked_and_named() {
        let c = RangeChoice { interval_deg: Some(7.0), ..RangeChoice::default() };
        assert_eq!(full(c, DefaultSpacing::Interval(1.0)).unwrap_err().key, "interval_deg");
        let c = RangeChoice { interval_deg: Some(10.0), ..RangeChoice::default() };
        assert_eq!(full(c, DefaultSpacing::Interval(1.0)).unwrap().points, 37);
        let c = RangeChoice { start_deg: Some(10.0), end_deg: Some(10.0), ..RangeChoice::default() };
        assert_eq!(full(c, DefaultSpacing::Interval(1.0)).unwrap_err().key, "end_deg");
        let c = RangeChoice { points: Some(1), ..RangeChoice::default() };
        assert_eq!(full(c, DefaultSpacing::Interval(1.0)).unwrap_err().key, "points");
        let c = RangeChoice { start_deg: Some(-20.0), ..RangeChoice::default() };
        let e = resolve(&c, Span::Measured { start: -10.0, end: 90.0 }, DefaultSpacing::Interval(1.0)).unwrap_err();
        assert_eq!(e.key, "start_deg");
        assert!(e.message.contains("outside the measured range"), "{e}");
        let g = full(RangeChoice { points: Some(5), ..RangeChoice::default() }, DefaultSpacing::Interval(1.0)).unwrap();
        assert_eq!((g.interval_deg, g.index_of(270.0), g.index_of(100.0)), (90.0, Some(3), None));
    }

    #[test]
    fn the_reader_drops_what_the_spacing_cannot_hold_and_wraps() {
        let n = 4096;
        let t = CorrectionTable::directional(
            (0..n).map(|i| 0.002 + 0.001 * (216.0 * i as f64 * 360.0 / n as f64).to_radians().sin()).collect(),
            vec![-0.002; n],
        )
        .unwrap();
        // 1 deg holds lines below 180 cycles: the 216-cycle line goes.
        let r = Reader::new(&t, true, 1.0, true);
        for p in [-725.3, 0.0, 17.5, 359.9, 1000.0] {
            assert!((r.error_at(p, Direction::Forward) - 0.002).abs() < 1e-12, "{p}");
            assert!((r.error_at(p, Direction::Reverse) + 0.002).abs() < 1e-12, "{p}");
        }
        // 0.1 deg holds it, and the combined reading is the mean of the directions.
        let r = Reader::new(&t, true, 0.1, false);
        let want = 0.0005 * (216.0 * 17.5f64).to_radians().sin();
        assert!((r.error_at(17.5, Direction::Reverse) - want).abs() < 1e-6);
        assert!(!r.is_separate());
    }
}
