//! Table files as bytes: pure writers, no file system (the caller stages and
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
//! - [`controllers`]: the recipe's `[export]` choices turned into the files of
//!   each controller asked for, with the accuracy each is predicted to give.
//! - The binary table is [`crate::corrector::to_bytes`].
//!
//! Heidenhain's nonlinear axis-error compensation is not written: its sign,
//! header and field formats are not public.
//!
//! Every controller table is a function of the readout (the position the
//! control knows); the error is `readout - actual` (the contract), and each
//! writer turns it into its format's sign.

pub mod controllers;
pub mod fanuc;
pub mod generic;
pub mod layout;
pub mod linuxcnc;
pub mod sinumerik;
#[cfg(test)]
mod tests;

use crate::Direction;
use crate::table::CorrectionTable;
use std::fmt::Write as _;

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
    /// The error removed at `position_deg` for motion in `direction`, degrees.
    fn removed_deg(&self, position_deg: f64, direction: Direction) -> f64;
    /// The positions the table covers (infinite for a modulo table).
    fn range_deg(&self) -> (f64, f64);
}

/// Linear interpolation in `ys` over ascending `xs`, the end values held
/// outside (LinuxCNC's `control.c` and a non-modulo 840D table).
pub(crate) fn interpolate_held(xs: &[f64], ys: &[f64], p: f64) -> f64 {
    interpolate_held_by(xs.len(), |i| xs[i], |i| ys[i], p)
}

/// [`interpolate_held`] over `n` points given by index (`x(i)` ascending):
/// a table whose positions or values are computed reads only the two points
/// around `p`, so predicting it on every sample builds nothing.
pub(crate) fn interpolate_held_by(n: usize, x: impl Fn(usize) -> f64, y: impl Fn(usize) -> f64, p: f64) -> f64 {
    if p <= x(0) {
        return y(0);
    }
    if p >= x(n - 1) {
        return y(n - 1);
    }
    // The first index whose position is above p (`partition_point`), minus one.
    // The index where p would fall on evenly spaced points is tried first:
    // on a controller's grid it is right but for rounding, and two
    // comparisons then end the search.
    let (mut lo, mut hi) = (0, n);
    let (x0, xn) = (x(0), x(n - 1));
    let guess = (((p - x0) / (xn - x0) * (n - 1) as f64) as usize).min(n - 1);
    if x(guess) <= p {
        lo = guess + 1;
        if lo < n && x(lo) > p {
            hi = lo;
        }
    } else {
        hi = guess;
    }
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if x(mid) <= p { lo = mid + 1 } else { hi = mid }
    }
    let i = lo - 1;
    let (x0, x1, y0, y1) = (x(i), x(i + 1), y(i), y(i + 1));
    y0 + (y1 - y0) * (p - x0) / (x1 - x0)
}

/// The corrected peak error (`max |e - removed - mean|`) a controller's table
/// is predicted to leave on `samples`, on every turn it covers: a periodic
/// (full-circle) survey is moved by whole turns onto each turn of the table's
/// range, and the worst turn is returned. `None` when no sample falls inside.
///
/// One pass over the samples for every turn at once, each turn's errors
/// folded into their count, sum, least and largest: the peak about the mean
/// is the larger of `largest - mean` and `mean - least` (rounding is
/// monotonic: the same bits as [`crate::correction::ErrorFigures`]' `peak_deg` of the errors
/// collected, with no vector of them).
pub fn predicted_peak_deg(samples: &[crate::Sample], table: &dyn Applied, periodic: bool) -> Option<f64> {
    let (lo, hi) = table.range_deg();
    let turns: Vec<i64> = if periodic && lo.is_finite() && hi.is_finite() {
        ((lo / 360.0).floor() as i64 - 1..=(hi / 360.0).ceil() as i64 + 1).collect()
    } else {
        vec![0]
    };
    let tol = 1e-9;
    // (count, sum, least, largest) of each turn's errors; the sum in their
    // order from -0.0, as `Iterator::sum` takes it.
    let mut folds = vec![(0usize, -0.0f64, f64::INFINITY, f64::NEG_INFINITY); turns.len()];
    for s in samples {
        for (&k, fold) in turns.iter().zip(folds.iter_mut()) {
            let p = s.readout_deg + 360.0 * k as f64;
            if p >= lo - tol && p <= hi + tol {
                let e = s.error_deg() - table.removed_deg(p, s.direction);
                *fold = (fold.0 + 1, fold.1 + e, fold.2.min(e), fold.3.max(e));
            }
        }
    }
    folds
        .into_iter()
        .filter(|f| f.0 > 0)
        .map(|(n, sum, least, largest)| {
            let mean = sum / n as f64;
            0.0f64.max(largest - mean).max(mean - least)
        })
        .reduce(f64::max)
}

#[cfg(test)]
mod csv_tests {
    use super::*;

    /// A table removing a smooth error over `range`, more in reverse.
    struct Smooth {
        range: (f64, f64),
    }

    impl Applied for Smooth {
        fn removed_deg(&self, p: f64, direction: Direction) -> f64 {
            0.004 * (3.0 * p).to_radians().sin() + if direction == Direction::Reverse { 0.001 } else { 0.0 }
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
            errors in proptest::collection::vec((0.0f64..360.0, -0.01f64..0.01, proptest::bool::ANY), 1..200),
            range in proptest::sample::select(vec![(0.0, 360.0), (-180.0, 540.0), (10.0, 90.0), (f64::NEG_INFINITY, f64::INFINITY)]),
            periodic in proptest::bool::ANY,
        ) {
            let samples: Vec<crate::Sample> = errors
                .iter()
                .map(|&(readout_deg, e, reverse)| crate::Sample {
                    run: 1,
                    direction: if reverse { Direction::Reverse } else { Direction::Forward },
                    target_deg: readout_deg.round(),
                    readout_deg,
                    actual_deg: readout_deg - e,
                    timestamp_s: None,
                })
                .collect();
            let table = Smooth { range };
            let (lo, hi) = range;
            let turns: Vec<i64> = if periodic && lo.is_finite() && hi.is_finite() {
                ((lo / 360.0).floor() as i64 - 1..=(hi / 360.0).ceil() as i64 + 1).collect()
            } else {
                vec![0]
            };
            let collected = turns
                .into_iter()
                .filter_map(|k| {
                    let e: Vec<f64> = samples
                        .iter()
                        .filter_map(|s| {
                            let p = s.readout_deg + 360.0 * k as f64;
                            (p >= lo - 1e-9 && p <= hi + 1e-9).then(|| s.error_deg() - table.removed_deg(p, s.direction))
                        })
                        .collect();
                    (!e.is_empty()).then(|| crate::correction::ErrorFigures::of(&e, None).peak_deg)
                })
                .reduce(f64::max);
            let folded = predicted_peak_deg(&samples, &table, periodic);
            proptest::prop_assert_eq!(folded.map(f64::to_bits), collected.map(f64::to_bits));
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
        let xs = [0.0, 10.0, 20.0];
        let ys = [1.0, 3.0, -1.0];
        assert_eq!(interpolate_held(&xs, &ys, -5.0), 1.0);
        assert_eq!(interpolate_held(&xs, &ys, 5.0), 2.0);
        assert_eq!(interpolate_held(&xs, &ys, 10.0), 3.0);
        assert_eq!(interpolate_held(&xs, &ys, 15.0), 1.0);
        assert_eq!(interpolate_held(&xs, &ys, 25.0), -1.0);
    }
}
