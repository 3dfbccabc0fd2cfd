//! The controller formats: table files as bytes, pure writers, no file system (the caller stages and
//! renames them into place). One module per format:
//!
//! - [`table_csv`] (here): the contract's correction table. Header
//!   `readout_deg,error_deg` (or `readout_deg,error_forward_deg,error_reverse_deg`),
//!   one row per table row at `360 i / n` degrees from 0 up to `360 - 360/n`,
//!   numbers in Rust's shortest round-trip form.
//! - [`linuxcnc`]: LinuxCNC `COMP_FILE`s (types 0 and 1) over a joint range,
//!   several turns included, at most 256 points.
//! - [`sinumerik`]: Siemens SINUMERIK 840D measuring-system error compensation
//!   (`%_N_AX_EEC_INI`).
//! - [`fanuc`]: Fanuc stored pitch-error compensation, the values and the
//!   parameters 3620-3627.
//! - [`generic`]: a CSV with the sign, absolute/incremental and direction
//!   choices of commercial calibration software, for any other controller.
//! - [`layout`]: where the points of a controller table fall (range, interval
//!   or point count) and the table read there, low-passed to what the spacing holds.
//! - [`export`]: the recipe's `[export]` choices (the section itself,
//!   [`export::ExportChoices`]) turned into the files of each controller asked
//!   for, with the accuracy each is predicted to give.
//! - [`corrector`]: the binary table ([`corrector::to_bytes`]) and the
//!   constant-time real-time corrector that reads it.
//!
//! Heidenhain's nonlinear axis-error compensation is not written: its sign,
//! header and field formats are not public.
//!
//! Every controller table is a function of the readout (the position the
//! control knows); the error is `readout - actual` (the contract), and each
//! writer turns it into its format's sign.

pub mod corrector;
pub mod export;
pub mod fanuc;
pub mod generic;
pub mod layout;
pub mod linuxcnc;
pub mod sinumerik;
#[cfg(test)]
mod tests;

use layout::Grid;
use std::fmt::Write as _;
use survey_processing::Direction;
use survey_processing::table::CorrectionTable;

/// The contract's table CSV.
pub fn table_csv(table: &CorrectionTable) -> String {
    let mut s = String::with_capacity(table.len() * 48);
    match &table.reverse {
        None => {
            s.push_str("readout_deg,error_deg\n");
            for (i, e) in table.forward.iter().enumerate() {
                let _ = writeln!(s, "{},{e}", table.readout_at(i));
            }
        }
        Some(r) => {
            s.push_str("readout_deg,error_forward_deg,error_reverse_deg\n");
            for (i, (f, r)) in table.forward.iter().zip(r).enumerate() {
                let _ = writeln!(s, "{},{f},{r}", table.readout_at(i));
            }
        }
    }
    s
}

/// How a controller applies its table, for predicting what it leaves: the
/// error it removes at a position (the corrected error is `e - removed`).
pub trait Applied {
    /// The error the table removes for motion in `direction`, as the
    /// controller interpolates it.
    fn applied(&self, direction: Direction) -> AppliedLine;
    /// The positions the table covers (infinite for a modulo table).
    fn range_deg(&self) -> (f64, f64);
    /// The error removed at `position_deg` for motion in `direction`,
    /// degrees (a line made for the one position: [`Applied::applied`]
    /// once, then [`AppliedLine::at`], for many).
    fn removed_deg(&self, position_deg: f64, direction: Direction) -> f64 {
        self.applied(direction).at(position_deg)
    }
}

/// A controller table for one direction of motion as the controller applies
/// it: the error removed at each point of a uniform grid, linear between
/// points; a modulo (rotary) table first brings a position into the
/// revolution from its grid's start, and beyond the points the end values
/// hold (LinuxCNC's `control.c`, a non-modulo 840D table, a linear Fanuc
/// table, and the last section of a rotary Fanuc one).
#[derive(Debug, Clone, PartialEq)]
pub struct AppliedLine {
    start_deg: f64,
    /// Points per degree: a position's place on the grid is a product.
    per_deg: f64,
    removed_deg: Vec<f64>,
    /// The last point's place on the grid (`removed_deg.len() - 1`).
    last: f64,
    modulo: bool,
}

impl AppliedLine {
    /// `removed_deg` at the points of `grid` (one value a point), modulo
    /// 360 degrees from the grid's start or not.
    pub fn new(grid: &Grid, removed_deg: Vec<f64>, modulo: bool) -> Self {
        assert_eq!(removed_deg.len(), grid.points, "a value for each point of the grid");
        assert!(grid.points >= 1 && grid.interval_deg > 0.0, "a grid of points ascending");
        let last = (removed_deg.len() - 1) as f64;
        AppliedLine { start_deg: grid.start_deg, per_deg: 1.0 / grid.interval_deg, removed_deg, last, modulo }
    }

    /// The error removed at `position_deg`, degrees: a product, a
    /// comparison and a linear interpolation (no search: it is taken at
    /// every sample of a survey, for every controller).
    pub fn at(&self, position_deg: f64) -> f64 {
        let p = if self.modulo {
            self.start_deg + survey_processing::types::rem_euclid_360(position_deg - self.start_deg)
        } else {
            position_deg
        };
        let v = &self.removed_deg;
        let last = v.len() - 1;
        // The place on the grid, in points from its start.
        let t = (p - self.start_deg) * self.per_deg;
        if t.is_nan() || t <= 0.0 {
            return v[0];
        }
        if t >= self.last {
            return v[last];
        }
        // `t` is positive: `as` is its floor, below `last`. Through `i64`:
        // a float's conversion to an unsigned integer, and back, take
        // several instructions each on x86-64 (this runs at every sample for
        // every controller).
        let k = t as i64;
        let i = k as usize;
        v[i] + (v[i + 1] - v[i]) * (t - k as f64)
    }
}

/// The corrected peak error (`max |e - removed - mean|`) a controller's table
/// is predicted to leave on `samples`, on every turn it covers: a periodic
/// (full-circle) survey is moved by whole turns onto each turn of the table's
/// range, and the worst turn is returned. `None` when no sample falls inside.
///
/// Each turn some sample falls on folds its errors into their count, sum,
/// least and largest, a chunk of samples at a time ([`predicted_peaks_deg`],
/// the fold in registers over a chunk): the peak about
/// the mean is the larger of `largest - mean` and `mean - least` (rounding
/// is monotonic: the same bits as `survey_tables::correction::ErrorFigures`'
/// `peak_deg` of the errors collected, with no vector of them). A turn onto
/// which the least and the largest readout both move outside the range, on
/// one side, takes no sample (a sum is monotonic) and is not passed over.
pub fn predicted_peak_deg(samples: &[survey_processing::Sample], table: &dyn Applied, periodic: bool) -> Option<f64> {
    predicted_peaks_deg(samples, &[AppliedTable::of(table)], periodic)[0]
}

/// A controller table as [`predicted_peaks_deg`] takes it: the lines it
/// applies in each direction and the range it covers.
#[derive(Debug, Clone)]
pub struct AppliedTable {
    lines: [AppliedLine; 2],
    range_deg: (f64, f64),
}

impl AppliedTable {
    /// `table`'s lines and range.
    pub fn of(table: &dyn Applied) -> Self {
        AppliedTable {
            lines: [table.applied(Direction::Forward), table.applied(Direction::Reverse)],
            range_deg: table.range_deg(),
        }
    }
}

/// [`predicted_peak_deg`] of each of `tables`, from one pass over the
/// samples' memory for them all (each table's turns folded over a chunk of
/// them in turn, each in the samples' order: the same bits as a pass a
/// table; a pass over a large survey's samples costs more in memory traffic
/// than the lookups in it).
pub fn predicted_peaks_deg(
    samples: &[survey_processing::Sample],
    tables: &[AppliedTable],
    periodic: bool,
) -> Vec<Option<f64>> {
    let tol = 1e-9;
    // The least and the largest readout, when a table's turns need them.
    let mut extent = None;
    // Each table's turns, in the order they are reduced: (table, turn).
    let mut folds: Vec<TurnFold> = Vec::new();
    for (t, table) in tables.iter().enumerate() {
        let (lo, hi) = table.range_deg;
        let (lo_tol, hi_tol) = (lo - tol, hi + tol);
        if periodic && lo.is_finite() && hi.is_finite() {
            let (least, largest) = *extent.get_or_insert_with(|| {
                samples
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| (a.min(s.readout_deg), b.max(s.readout_deg)))
            });
            folds.extend(
                ((lo / 360.0).floor() as i64 - 1..=(hi / 360.0).ceil() as i64 + 1)
                    .filter(|&k| largest + 360.0 * k as f64 >= lo_tol && least + 360.0 * k as f64 <= hi_tol)
                    .map(|k| TurnFold::new(t, 360.0 * k as f64, lo_tol, hi_tol)),
            );
        } else {
            folds.push(TurnFold::new(t, 0.0, lo_tol, hi_tol));
        }
    }
    // A chunk of the samples at a time (cached), each turn's fold held in
    // registers over it: the memory is read once, the loop is a table's.
    for chunk in samples.chunks(PEAK_CHUNK) {
        for f in &mut folds {
            let lines = &tables[f.table].lines;
            let (turn, lo_tol, hi_tol) = (f.turn, f.lo_tol, f.hi_tol);
            let (mut n, mut sum, mut least, mut largest) = (f.n, f.sum, f.least, f.largest);
            for s in chunk {
                let p = s.readout_deg + turn;
                if p >= lo_tol && p <= hi_tol {
                    let line = &lines[usize::from(s.direction == Direction::Reverse)];
                    let e = s.error_deg() - line.at(p);
                    (n, sum, least, largest) = (n + 1, sum + e, least.min(e), largest.max(e));
                }
            }
            (f.n, f.sum, f.least, f.largest) = (n, sum, least, largest);
        }
    }
    let mut peaks = vec![None; tables.len()];
    for f in &folds {
        if let Some(peak) = f.peak() {
            let best: &mut Option<f64> = &mut peaks[f.table];
            *best = Some(best.map_or(peak, |b: f64| b.max(peak)));
        }
    }
    peaks
}

/// Samples a chunk of [`predicted_peaks_deg`] (96 KiB: within a core's
/// second-level cache).
const PEAK_CHUNK: usize = 2048;

/// One turn of a table: where the samples fall on it, and the fold of
/// their corrected errors there (count, sum, least, largest).
struct TurnFold {
    table: usize,
    turn: f64,
    lo_tol: f64,
    hi_tol: f64,
    n: usize,
    sum: f64,
    least: f64,
    largest: f64,
}

impl TurnFold {
    fn new(table: usize, turn: f64, lo_tol: f64, hi_tol: f64) -> Self {
        // The sum in the errors' order from -0.0, as `Iterator::sum` takes it.
        TurnFold { table, turn, lo_tol, hi_tol, n: 0, sum: -0.0, least: f64::INFINITY, largest: f64::NEG_INFINITY }
    }

    /// The peak about the mean (`None`: no sample on this turn).
    fn peak(&self) -> Option<f64> {
        (self.n > 0).then(|| {
            let mean = self.sum / self.n as f64;
            0.0f64.max(self.largest - mean).max(mean - self.least)
        })
    }
}

#[cfg(test)]
mod csv_tests {
    use super::*;

    /// A table removing a smooth error over `range`, more in reverse.
    struct Smooth {
        range: (f64, f64),
    }

    impl Applied for Smooth {
        /// The smooth error at a point every 0.1 deg of the range (one
        /// revolution, modulo, for an infinite one).
        fn applied(&self, direction: Direction) -> AppliedLine {
            let (lo, hi) = self.range;
            let modulo = !(lo.is_finite() && hi.is_finite());
            let (start_deg, end_deg) = if modulo { (0.0, 360.0) } else { (lo, hi) };
            let points = ((end_deg - start_deg) * 10.0).round() as usize + 1;
            let grid = Grid { start_deg, interval_deg: (end_deg - start_deg) / (points - 1) as f64, points };
            let removed = (0..points)
                .map(|i| {
                    let p = grid.position(i);
                    0.004 * (3.0 * p).to_radians().sin() + if direction == Direction::Reverse { 0.001 } else { 0.0 }
                })
                .collect();
            AppliedLine::new(&grid, removed, modulo)
        }
        fn range_deg(&self) -> (f64, f64) {
            self.range
        }
    }

    proptest::proptest! {
        /// The one-pass fold gives the bits of the peak of the errors
        /// collected turn by turn, as `ErrorFigures` takes it.
        #[test]
        fn predicted_peak_is_the_collected_errors_peak(
            errors in proptest::collection::vec((-400.0f64..800.0, -0.01f64..0.01, proptest::bool::ANY), 1..200),
            ranges in proptest::collection::vec(
                proptest::sample::select(vec![(0.0, 360.0), (-180.0, 540.0), (10.0, 90.0), (f64::NEG_INFINITY, f64::INFINITY)]),
                1..4,
            ),
            periodic in proptest::bool::ANY,
        ) {
            let samples: Vec<survey_processing::Sample> = errors
                .iter()
                .map(|&(readout_deg, e, reverse)| survey_processing::Sample {
                    run: 1,
                    direction: if reverse { Direction::Reverse } else { Direction::Forward },
                    target_deg: readout_deg.round(),
                    readout_deg,
                    actual_deg: readout_deg - e,
                    timestamp_s: None,
                })
                .collect();
            let collected = |table: &Smooth| {
                let (lo, hi) = table.range;
                let turns: Vec<i64> = if periodic && lo.is_finite() && hi.is_finite() {
                    ((lo / 360.0).floor() as i64 - 1..=(hi / 360.0).ceil() as i64 + 1).collect()
                } else {
                    vec![0]
                };
                turns
                    .into_iter()
                    .filter_map(|k| {
                        let e: Vec<f64> = samples
                            .iter()
                            .filter_map(|s| {
                                let p = s.readout_deg + 360.0 * k as f64;
                                (p >= lo - 1e-9 && p <= hi + 1e-9).then(|| s.error_deg() - table.removed_deg(p, s.direction))
                            })
                            .collect();
                        (!e.is_empty()).then(|| {
                            let mean = e.iter().sum::<f64>() / e.len() as f64;
                            e.iter().map(|x| (x - mean).abs()).fold(0.0, f64::max)
                        })
                    })
                    .reduce(f64::max)
            };
            let tables: Vec<Smooth> = ranges.into_iter().map(|range| Smooth { range }).collect();
            // Each alone, and all of them from one pass.
            let together =
                predicted_peaks_deg(&samples, &tables.iter().map(|t| AppliedTable::of(t)).collect::<Vec<_>>(), periodic);
            for (table, together) in tables.iter().zip(together) {
                let want = collected(table).map(f64::to_bits);
                proptest::prop_assert_eq!(predicted_peak_deg(&samples, table, periodic).map(f64::to_bits), want);
                proptest::prop_assert_eq!(together.map(f64::to_bits), want);
            }
        }
    }

    #[test]
    fn csv_format() {
        let t =
            CorrectionTable::directional(vec![0.001, 0.002, 0.003, 0.004], vec![-0.001, 0.0, 0.001, 0.002]).unwrap();
        assert_eq!(
            table_csv(&t),
            "readout_deg,error_forward_deg,error_reverse_deg\n0,0.001,-0.001\n90,0.002,0\n180,0.003,0.001\n270,0.004,0.002\n"
        );
        let one = CorrectionTable::new(vec![0.5, -0.25]).unwrap();
        assert_eq!(table_csv(&one), "readout_deg,error_deg\n0,0.5\n180,-0.25\n");
    }

    #[test]
    fn held_interpolation_is_control_c() {
        let grid = Grid { start_deg: 0.0, interval_deg: 10.0, points: 3 };
        let line = AppliedLine::new(&grid, vec![1.0, 3.0, -1.0], false);
        assert_eq!(line.at(-5.0), 1.0);
        assert_eq!(line.at(5.0), 2.0);
        assert_eq!(line.at(10.0), 3.0);
        assert_eq!(line.at(15.0), 1.0);
        assert_eq!(line.at(20.0), -1.0);
        assert_eq!(line.at(25.0), -1.0);
    }

    #[test]
    fn a_modulo_line_repeats_every_revolution_from_its_start() {
        // A rotary table from its reference point at 30 deg, a point every
        // 120 deg; past the last point the last section holds its end.
        let grid = Grid { start_deg: 30.0, interval_deg: 120.0, points: 3 };
        let line = AppliedLine::new(&grid, vec![0.0, 1.2, 2.4], true);
        for turns in [-2.0, -1.0, 0.0, 1.0, 5.0] {
            let at = |p: f64| line.at(p + 360.0 * turns);
            assert!((at(30.0) - 0.0).abs() < 1e-12);
            assert!((at(90.0) - 0.6).abs() < 1e-12);
            assert!((at(210.0) - 1.8).abs() < 1e-12);
            assert!((at(300.0) - 2.4).abs() < 1e-12);
            // 10 deg is 340 past the start: beyond the last point, held.
            assert!((at(10.0) - 2.4).abs() < 1e-12);
        }
    }
}
