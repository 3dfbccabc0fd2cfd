//! Table columns from lines of the true angle.
//!
//! A positioner's periodic errors are sinusoids of the TRUE axis angle
//! (the contract: `readout = actual + e(actual)`, the gears turn with the
//! real axis), while a table is indexed by the readout. A survey measures
//! `E(r) = e(theta(r))` at its targets, `theta(r)` solving `theta + e(theta)
//! = r`: the values there are right, but `E` as a function of the readout
//! holds, besides the lines of `e`, their products (`e e'`: a 20-cycle gear
//! pass of 0.0078 deg and its 0.0025 deg second harmonic make a 60-cycle line
//! of 1.0e-5 deg; the Figure 1 elevation axis, 0.028 deg at 6 cycles and
//! 0.006 deg at 72, lines of 1.1e-4 deg at 66 and 78 cycles). A table that
//! keeps only the significant lines of `E` drops those products, which are
//! below any test's threshold, yet a large part of what is left after
//! correction.
//!
//! So the kept lines are taken as lines of the true angle: find `g`, a sum of
//! the kept lines (a function of the true angle, in a frame whose zero is the
//! column's mean), such that the table it makes, `T_g(r) = g(theta(r))` with
//! `theta = r - (g(theta) - mean g)`, has the kept lines of the measured
//! column; the table is `T_g`, which then also holds their products. The
//! products are second order, so one correction of `g` leaves a third-order
//! error (two passes are made). A constant in `g` only shifts the frame of the
//! true angle, which the fitted phases absorb, so the column's mean (zero
//! reference and, per direction, half the backlash) is put back as it is.

use survey_processing::resample::{
    Complex64, PartialError, PartialFit, PartialMethod, Resampler, Series, Span, fit_partial,
};
use survey_processing::types::rem_euclid_360;

/// Passes of the correction of `g` (each removes one order of the products).
const PASSES: usize = 2;
/// Fixed-point iterations for `theta(r)`: `|g'|` is below about 0.01 for any
/// positioner worth a table, so 6 iterations leave 1e-12 of the error.
const THETA_ITERATIONS: usize = 6;
/// `g` is evaluated by cubic interpolation on a grid this many times finer
/// than the table (for a 432-cycle line of 4e-4 deg at 16384 rows, an
/// interpolation error of about 1e-10 deg).
const GRID_FACTOR: usize = 4;

/// Cubic (4-point Lagrange) interpolation of a periodic grid of
/// `grid.len()` points over 360 deg.
fn interp(grid: &[f64], theta_deg: f64) -> f64 {
    let m = grid.len();
    // `x` is not negative: `as` is its floor (through `i64`, a NaN gives 0:
    // a float's conversion to an unsigned integer, and back, take several
    // instructions each on x86-64).
    let x = rem_euclid_360(theta_deg) / 360.0 * m as f64;
    let k = (x as i64).min(m as i64 - 1);
    let (i, f) = (k as usize, x - k as f64);
    // The four nodes, wrapped around the grid only at its ends.
    let (a, b, c, d) = match grid.get(i.wrapping_sub(1)..i + 3) {
        Some(&[a, b, c, d]) => (a, b, c, d),
        _ => {
            let at = |k: usize| grid[(i + m - 1 + k) % m];
            (at(0), at(1), at(2), at(3))
        }
    };
    // Lagrange weights at nodes -1, 0, 1, 2.
    let wa = -f * (f - 1.0) * (f - 2.0) / 6.0;
    let wb = (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0;
    let wc = -(f + 1.0) * f * (f - 2.0) / 2.0;
    let wd = (f + 1.0) * f * (f - 1.0) / 6.0;
    wa * a + wb * b + wc * c + wd * d
}

/// The table `T_g` at `readouts` for `g` given on a grid (its mean removed
/// for the change of variable), in a frame `offset` degrees from `g`'s
/// (a directional column's half backlash: its true angle is `r - g - offset`).
fn through_true_angle(grid: &[f64], readouts: &[f64], offset: f64) -> Vec<f64> {
    let mean = grid.iter().sum::<f64>() / grid.len() as f64;
    // A readout's iterations start from the previous readout's `theta - (r -
    // offset)`: the readouts come in order, a target or a row apart, and
    // `g` changes little between them, so fewer iterations reach the fixed
    // point (the first starts from the readout itself).
    let mut previous = 0.0;
    readouts
        .iter()
        .map(|&r| {
            let mut theta = r - offset + previous;
            for _ in 0..THETA_ITERATIONS {
                let next = r - offset - (interp(grid, theta) - mean);
                // At a fixed point the iterations left would not move it.
                if next.to_bits() == theta.to_bits() {
                    break;
                }
                theta = next;
            }
            previous = theta - (r - offset);
            interp(grid, theta)
        })
        .collect()
}

/// The lines of the true angle behind a measured column: `g` (no mean) and
/// the column's mean.
pub(crate) struct TrueLines {
    g: Series,
    mean: f64,
}

impl TrueLines {
    /// `g` for `map`, the measured column at the survey's `targets`
    /// (readouts), `edit` the processing's spectral edit of a map at those
    /// targets (kept lines, aliases relocated or nulled; the series in
    /// absolute angle). `g` is corrected until the edit of `T_g` sampled at
    /// the targets equals the edit of the map: the products of the lines
    /// alias at the targets as they did in the survey, so a product that
    /// lands on a kept bin is not taken for a line.
    pub(crate) fn fit<E>(
        map: &[f64],
        targets: &[f64],
        mut edit: E,
        rows: usize,
        rs: &mut Resampler,
    ) -> Result<Self, crate::correction::CorrectionError>
    where
        E: FnMut(&[f64]) -> Result<Series, crate::correction::CorrectionError>,
    {
        let edited = edit(map)?;
        let mean = edited.amplitude(0);
        let kept: Vec<usize> =
            (1..edited.bins().min(rows.div_ceil(2))).filter(|&k| edited.coeff(k) != Complex64::default()).collect();
        let mut g = edited.clone();
        g.set_coeff(0, Complex64::default());
        g.truncate(rows.div_ceil(2) - 1);
        if kept.is_empty() {
            return Ok(Self { g, mean });
        }
        for _ in 0..PASSES {
            let grid = rs.synthesize(&g, GRID_FACTOR * rows);
            let got = edit(&through_true_angle(&grid, targets, 0.0))?;
            for &k in &kept {
                g.set_coeff(k, g.coeff(k) + edited.coeff(k) - got.coeff(k));
            }
        }
        Ok(Self { g, mean })
    }

    /// The column of `rows` rows these lines make, plus `extra` (lines of
    /// the true angle, no mean) and `offset` degrees (a constant that moves
    /// the frame of the true angle too): its mean is the measured column's
    /// plus `offset`.
    pub(crate) fn column(&self, extra: Option<&Series>, offset: f64, rows: usize, rs: &mut Resampler) -> Vec<f64> {
        let mut g = self.g.clone();
        if let Some(x) = extra {
            for k in 1..x.bins() {
                g.set_coeff(k, g.coeff(k) + x.coeff(k));
            }
        }
        g.truncate(rows.div_ceil(2) - 1);
        let readouts: Vec<f64> = (0..rows).map(|i| 360.0 * i as f64 / rows as f64).collect();
        let grid = rs.synthesize(&g, GRID_FACTOR * rows);
        let mut table = through_true_angle(&grid, &readouts, offset);
        let shift = self.mean + offset - mean(&table);
        table.iter_mut().for_each(|v| *v += shift);
        table
    }
}

/// A full-circle column of `rows` rows from the measured column `map` at
/// the survey's `targets` ([`TrueLines::fit`], then its column).
pub(crate) fn full_circle_column<E>(
    map: &[f64],
    targets: &[f64],
    edit: E,
    rows: usize,
    rs: &mut Resampler,
) -> Result<Vec<f64>, crate::correction::CorrectionError>
where
    E: FnMut(&[f64]) -> Result<Series, crate::correction::CorrectionError>,
{
    Ok(TrueLines::fit(map, targets, edit, rows, rs)?.column(None, 0.0, rows, rs))
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// A partial-span column of `rows` rows: the least-squares fit of `samples`
/// (uniform over `span`, both ends included) taken as a function of the true
/// angle. Cubic interpolation passes through the samples and is returned as
/// the fit gives it. Rows beyond the span follow the fit's own rule
/// ([`PartialFit::column`]), shifted to meet the corrected ends.
pub(crate) fn partial_column(
    span: Span,
    samples: &[f64],
    method: &PartialMethod,
    rows: usize,
) -> Result<Vec<f64>, PartialError> {
    let fit = fit_partial(span, samples, method)?;
    if matches!(method, PartialMethod::Cubic) {
        return fit.column(rows);
    }
    let m = samples.len();
    let step = span.width_deg() / (m - 1) as f64;
    let at: Vec<f64> = (0..m).map(|j| span.start_deg + j as f64 * step).collect();
    // g = the fit of `a`; a <- a + (samples - T_g at the targets).
    let mut a = samples.to_vec();
    let mut g = fit;
    for _ in 0..PASSES {
        let t = partial_through(&g, &at);
        for j in 0..m {
            a[j] += samples[j] - t[j];
        }
        g = fit_partial(span, &a, method)?;
    }
    let base = g.column(rows)?;
    let h = 360.0 / rows as f64;
    let inside: Vec<usize> = (0..rows).filter(|&i| within(&span, i as f64 * h)).collect();
    let readouts: Vec<f64> = inside.iter().map(|&i| span.unwrap(i as f64 * h)).collect();
    let values = partial_through(&g, &readouts);
    let ends = partial_through(&g, &[span.start_deg, span.end_deg]);
    let shift_start = ends[0] - g.eval(span.start_deg);
    let shift_end = ends[1] - g.eval(span.end_deg);
    let mut col: Vec<f64> = base
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let x = span.unwrap(i as f64 * h);
            if x < span.start_deg { v + shift_start } else { v + shift_end }
        })
        .collect();
    for (i, v) in inside.into_iter().zip(values) {
        col[i] = v;
    }
    Ok(col)
}

fn within(span: &Span, theta_deg: f64) -> bool {
    let x = span.unwrap(theta_deg);
    (span.start_deg..=span.end_deg).contains(&x)
}

/// `T_g` at `readouts` (inside the span) for a partial fit `g`, the frame's
/// zero at the mean of `g` over the span.
fn partial_through(g: &PartialFit, readouts: &[f64]) -> Vec<f64> {
    let span = g.span();
    let n = 512;
    let mean =
        (0..=n).map(|j| g.eval(span.start_deg + span.width_deg() * j as f64 / n as f64)).sum::<f64>() / (n + 1) as f64;
    readouts
        .iter()
        .map(|&r| {
            let mut theta = r;
            for _ in 0..THETA_ITERATIONS {
                theta = r - (g.eval(theta) - mean);
            }
            g.eval(theta)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `e(theta) = sum A sin(k theta + phase)` and the error at readout `r`.
    fn truth(lines: &[(f64, f64, f64)], offset: f64) -> impl Fn(f64) -> f64 + '_ {
        move |r: f64| {
            let e = |t: f64| offset + lines.iter().map(|(k, a, p)| a * (k * t + p).to_radians().sin()).sum::<f64>();
            let mut t = r;
            for _ in 0..50 {
                t = r - e(t);
            }
            e(t)
        }
    }

    /// The Figure 8 gear pass (20 and 40 cycles) with half a backlash on top:
    /// the measured map keeps 20 and 40 cycles only, and the column made
    /// through the true angle matches the true error as a function of the
    /// readout (with its 60-cycle product of 1e-5 deg) to 2e-8 deg, where the
    /// kept lines alone miss it by 1e-5.
    #[test]
    fn a_full_circle_column_holds_the_products_of_its_lines() {
        let lines = [(20.0, 0.0078, 0.0), (40.0, 0.0025, 60.0)];
        let e = truth(&lines, 0.004);
        let n = 1800;
        let map: Vec<f64> = (0..n).map(|j| e(360.0 * j as f64 / n as f64)).collect();
        let mut rs = Resampler::new();
        let full = rs.analyze(&map);
        let mut edited = Series::default();
        for k in [0, 20, 40] {
            edited.set_coeff(k, full.coeff(k));
        }
        let rows = 4096;
        let plain = rs.synthesize(&edited, rows);
        let targets: Vec<f64> = (0..n).map(|j| 360.0 * j as f64 / n as f64).collect();
        let keep = |m: &[f64]| {
            let full = Resampler::new().analyze(m);
            let mut s = Series::default();
            for k in [0, 20, 40] {
                s.set_coeff(k, full.coeff(k));
            }
            Ok(s)
        };
        let col = full_circle_column(&map, &targets, keep, rows, &mut rs).unwrap();
        let worst = |c: &[f64]| (0..rows).map(|i| (c[i] - e(360.0 * i as f64 / rows as f64)).abs()).fold(0.0, f64::max);
        assert!(worst(&plain) > 8e-6, "the kept lines alone: {:e}", worst(&plain));
        assert!(worst(&col) < 2e-8, "through the true angle: {:e}", worst(&col));
    }

    /// The Figure 1 elevation axis over -10..90 deg: least squares at 6, 12
    /// and 72 cycles plus a cubic; the products (66 and 78 cycles, 1.1e-4 deg)
    /// are in the column made through the true angle (within 3e-6 deg of the
    /// truth over the span), not in the plain fit (off by 1e-4).
    #[test]
    fn a_partial_column_holds_the_products_of_its_lines() {
        let lines = [(6.0, 0.028, 20.0), (12.0, 0.003, 75.0), (72.0, 0.006, 0.0), (1.0, 0.002, 150.0)];
        let e = truth(&lines, 0.0);
        let span = Span { start_deg: -9.9, end_deg: 89.9 };
        let m = 721;
        let samples: Vec<f64> =
            (0..m).map(|j| e(span.start_deg + span.width_deg() * j as f64 / (m - 1) as f64)).collect();
        let method = PartialMethod::LeastSquares { cycles: vec![6.0, 12.0, 72.0], poly_degree: 3 };
        let rows = 7200;
        let plain = fit_partial(span, &samples, &method).unwrap().column(rows).unwrap();
        let col = partial_column(span, &samples, &method, rows).unwrap();
        let worst = |c: &[f64]| {
            (0..rows)
                .map(|i| 360.0 * i as f64 / rows as f64)
                .map(|x| span.unwrap(x))
                .enumerate()
                .filter(|(_, x)| (span.start_deg..=span.end_deg).contains(x))
                .map(|(i, x)| (c[i] - e(x)).abs())
                .fold(0.0, f64::max)
        };
        assert!(worst(&plain) > 5e-5, "the plain fit: {:e}", worst(&plain));
        assert!(worst(&col) < 3e-6, "through the true angle: {:e}", worst(&col));
    }
}
