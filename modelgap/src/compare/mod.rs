//! Has the positioner changed between two surveys, and does the table made
//! from the first still correct the second? (`survey compare A B`, `survey
//! history`, and the recalibration loop's check.) Pure: two surveys' samples
//! in, the tests and the decision out.
//!
//! # What is tested
//!
//! Each survey's error (readout - actual) is fitted by least squares with an
//! offset, the backlash (`+1/2` forward, `-1/2` reverse, when both surveys go
//! both ways) and a cosine and a sine of every line asked for, at the target
//! angles. A survey's repeatability is the pooled scatter of its samples about
//! their cell's mean (a cell: a target in a direction, over the runs), so a
//! coefficient's variance is that scatter times `(A^T A)^-1` (a sparse check
//! survey, whose lines alias, is fitted with the same columns: a line that
//! aliases onto another at its targets is left out and said). Then:
//!
//! - **every line**: the change of its phasor (amplitude and phase together),
//!   `d`, against its covariance `C` (both surveys'; on the once-per-revolution
//!   line, plus the variance of where each survey's tracker put the axis):
//!   `T^2 = d^T C^-1 d` is `2 F(2, nu)` when nothing changed, `nu` the
//!   Welch-Satterthwaite degrees of freedom of the two repeatabilities;
//! - **the backlash**: its change over its standard error, Student's t;
//! - **the mean error map**: at the cells both surveys measured, the change
//!   of each cell's mean, its zero reference (an offset between the surveys
//!   is no change) fitted out by generalised least squares with the
//!   covariance of the cell means (and the axis term): `Q / (cells - 1)` is
//!   `F(cells - 1, nu)` when nothing changed. It sees what no named line
//!   shows: a line neither survey's processing named, a change spread thinly.
//!
//! The stated false-alarm rate `alpha` (1 % by default) is the whole
//! comparison's: each of the `m` tests is made at `alpha / m` (Bonferroni),
//! so the same positioner surveyed twice is called "changed" in at most
//! about `alpha` of pairs. Measured on control pairs, the same simulated
//! positioner surveyed twice with different seeds: see `tests.rs`
//! (`false_alarms_on_control_pairs`) and `docs/validation.md`.
//!
//! # Does the table in force still hold
//!
//! [`table_on`] applies a table (made from the first survey) to both
//! surveys' samples and takes each cell's mean corrected error, less their
//! mean (the table's zero reference): on the first survey, what the table
//! was predicted to leave; on the second, what it leaves now. What was
//! stated is that prediction within `U` (k = 2, at 95 % of readouts): at the
//! cells both surveys measured, a cell is outside when its corrected error
//! moved by more than `U + 2 s_d` (`s_d` the noise of the two cell means'
//! difference: the table itself cancels, so a cell is outside by chance in at
//! most 4.55 % of surveys while the error moved by less than `U`). The table
//! holds unless more cells are outside than `p0 = 0.05 + 0.95 x 0.0455` of
//! them allows (a binomial count at half the stated rate). The second survey's
//! cells between the first's targets (a check designed to fall between the
//! calibration's targets, where the table interpolates) have no measurement
//! of the first to move from: there, and everywhere without common cells,
//! the second survey's residual itself is held to `U + 2 s / sqrt(n)`, and
//! counted with the rest. A cell tells little when its noise is near `U`
//! (a check's two-sample means), so the same values are also pooled (at the
//! other half of the rate): their mean square less what their noise puts
//! into it is the best estimate of what the table leaves beyond its
//! statement, in rms; when its one-sided lower bound is beyond the rms of
//! the largest line that stays within `U` at 95 % of the readouts (`0.7093
//! U`: a line of `1.0031 U`), the table no longer holds (a new line no
//! survey names, twice `U`, passes every cell and fails here). It is
//! a test of a change that matters against the table's own statement; a
//! change too small for it is what the tests of the lines and of the map are
//! for (a change can be significant and still within `U`). A check's few
//! noisy cells test little, so [`decide`] also holds the best estimate of
//! what the table now leaves to `U` ([`changes_left`]: every significant
//! change at its best estimate): beyond `U` at more than 5 % of the
//! readouts, the table no longer holds.
//!
//! # The decision
//!
//! [`decide`]: recalibrate when the table in force no longer holds, or when
//! a change exceeds the tolerance stated for the asset; a change beyond what
//! the two surveys' repeatability allows within a table that holds is named
//! ("changed, the table holds") and recalibrates nothing; the
//! reason names each change with its size.

mod fit;
pub mod seen;
#[cfg(test)]
mod tests;

use crate::stats::{f_sf, normal_two_sided_isf, normal_two_sided_sf, t_two_sided_isf, t_two_sided_sf};
use fit::{CellKey, Cells, cells, fit_both};
use serde::Serialize;
use survey_processing::Sample;
use survey_processing::table::CorrectionTable;

/// What the comparison is told besides the samples.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareOptions {
    /// The whole comparison's false-alarm rate (default 0.01).
    pub false_alarm_rate: f64,
    /// The lines to test, cycles per revolution (the main lines of both
    /// surveys); duplicates and the zero frequency are ignored.
    pub lines: Vec<f64>,
    /// Each survey's once-per-revolution standard error of its reference's
    /// axis (a tracker's fitted centre), degrees per quadrature component;
    /// 0 for an autocollimator or when unknown.
    pub axis_se_deg: [f64; 2],
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions { false_alarm_rate: 0.01, lines: Vec::new(), axis_se_deg: [0.0; 2] }
    }
}

/// Why two surveys cannot be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompareError {
    /// A survey has no two samples of one cell: its repeatability is unknown.
    #[error("survey {0} has no target measured twice in one direction (one run): its repeatability is unknown")]
    NoRepeatability(&'static str),
    /// No fit is possible (no samples).
    #[error("the surveys hold no samples to compare")]
    NoSamples,
}

/// `unchanged` or `changed`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// Nothing changed beyond what the repeatability allows.
    Unchanged,
    /// At least one test found a change.
    Changed,
}

impl Verdict {
    /// The name in the JSON documents.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Unchanged => "unchanged",
            Verdict::Changed => "changed",
        }
    }
}

/// One line, in both surveys.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LineChange {
    /// The line, cycles per revolution.
    pub cycles_per_rev: f64,
    /// Its amplitude in the first survey, degrees.
    pub amplitude_from_deg: f64,
    /// Its amplitude in the second survey, degrees.
    pub amplitude_to_deg: f64,
    /// Its phase in the first survey, degrees (`A sin(k theta + phase)`).
    pub phase_from_deg: f64,
    /// Its phase in the second survey, degrees.
    pub phase_to_deg: f64,
    /// How far the line moved, amplitude and phase together (the length of
    /// the phasor's change), degrees.
    pub change_deg: f64,
    /// The change the test calls significant: what the two surveys'
    /// repeatability allows at the test's false-alarm rate, degrees.
    pub change_u_deg: f64,
    /// Whether the line changed.
    pub significant: bool,
    /// `P(a change this large | nothing changed)`.
    pub p_value: f64,
}

/// The backlash (forward error minus reverse error), in both surveys.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BacklashChange {
    /// In the first survey, degrees.
    pub from_deg: f64,
    /// In the second survey, degrees.
    pub to_deg: f64,
    /// The change the test calls significant, degrees.
    pub change_u_deg: f64,
    /// Whether it changed.
    pub significant: bool,
    /// `P(a change this large | nothing changed)`.
    pub p_value: f64,
}

/// The mean error map, at the cells both surveys measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapChange {
    /// Cells compared.
    pub cells: usize,
    /// The change of the cell means, its zero reference removed: rms, degrees.
    pub rms_change_deg: f64,
    /// Its largest magnitude, degrees.
    pub peak_change_deg: f64,
    /// `Q / (cells - 1)`: 1 on average when nothing changed.
    pub statistic: f64,
    /// Degrees of freedom of the F test.
    pub dof: [usize; 2],
    /// Whether the map changed.
    pub significant: bool,
    /// `P(F > statistic | nothing changed)`.
    pub p_value: f64,
}

/// Everything the comparison found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// `changed` when any test found a change.
    pub verdict: Verdict,
    /// Every line tested.
    pub lines: Vec<LineChange>,
    /// Lines asked for that the surveys cannot tell apart from another line
    /// at their targets (a sparse survey's aliases), cycles per revolution.
    pub lines_not_tested: Vec<f64>,
    /// The same lines, each with why it is not estimable (the mean, the
    /// Nyquist bin or another line at its alias; a fit larger than the
    /// error's span): no amplitude is computed for them.
    pub not_estimable: Vec<seen::Unseen>,
    /// The backlash, when both surveys go both ways.
    pub backlash: Option<BacklashChange>,
    /// The mean error map, when the surveys share at least three cells.
    pub map: Option<MapChange>,
    /// The whole comparison's false-alarm rate.
    pub false_alarm_rate: f64,
    /// The rate each test is made at: `false_alarm_rate / tests`.
    pub per_test_rate: f64,
    /// Each survey's repeatability: the standard deviation of one sample about its cell's mean, degrees.
    pub repeatability_deg: [f64; 2],
}

/// Compare survey `a` (the first, e.g. the calibration in force) with
/// survey `b` (see the module documentation).
pub fn compare(a: &[Sample], b: &[Sample], opts: &CompareOptions) -> Result<Comparison, CompareError> {
    let ca = cells(a).ok_or(CompareError::NoRepeatability("A"))?;
    let cb = cells(b).ok_or(CompareError::NoRepeatability("B"))?;
    let bidirectional = |c: &Cells| {
        let fwd = c.cells.keys().any(|k| k.1 == survey_processing::Direction::Forward);
        fwd && c.cells.keys().any(|k| k.1 == survey_processing::Direction::Reverse)
    };
    let mut lines: Vec<f64> = Vec::new();
    for &k in &opts.lines {
        if k > 0.0 && !lines.iter().any(|l| (l - k).abs() < 1e-9) {
            lines.push(k);
        }
    }
    let (layout, [fa, fb], not_estimable) =
        fit_both(a, b, bidirectional(&ca) && bidirectional(&cb), &lines).ok_or(CompareError::NoSamples)?;
    let lines_not_tested = not_estimable.iter().map(|u| u.cycles_per_rev).collect();
    let common: Vec<(&fit::Cell, &fit::Cell)> =
        ca.cells.iter().filter_map(|(k, x)| cb.cells.get(k).map(|y| (x, y))).collect();
    let tests = layout.lines.len() + usize::from(layout.backlash) + usize::from(common.len() >= 3);
    let alpha = opts.false_alarm_rate;
    let per_test = alpha / tests.max(1) as f64;
    let nu = |va: f64, vb: f64| welch(va, ca.dof, vb, cb.dof);
    let axis_var = opts.axis_se_deg[0].powi(2) + opts.axis_se_deg[1].powi(2);

    let lines_out: Vec<LineChange> = layout
        .lines
        .iter()
        .enumerate()
        .map(|(i, &k)| {
            let j = layout.line_index(i);
            let block = |f: &fit::Fit, var: f64| {
                [
                    [f.unit_cov[j][j] * var, f.unit_cov[j][j + 1] * var],
                    [f.unit_cov[j + 1][j] * var, f.unit_cov[j + 1][j + 1] * var],
                ]
            };
            let (ka, kb) = (block(&fa, ca.var), block(&fb, cb.var));
            let extra = if (k - 1.0).abs() < 1e-9 { axis_var } else { 0.0 };
            let c = [
                [ka[0][0] + kb[0][0] + extra, ka[0][1] + kb[0][1]],
                [ka[1][0] + kb[1][0], ka[1][1] + kb[1][1] + extra],
            ];
            let d = [fb.coef[j] - fa.coef[j], fb.coef[j + 1] - fa.coef[j + 1]];
            let det = c[0][0] * c[1][1] - c[0][1] * c[1][0];
            let t2 = (d[0] * d[0] * c[1][1] - 2.0 * d[0] * d[1] * c[0][1] + d[1] * d[1] * c[0][0]) / det;
            let v = nu(ka[0][0] + ka[1][1], kb[0][0] + kb[1][1]);
            let p_value = (1.0 + t2 / v).powf(-v / 2.0);
            let threshold = v * (per_test.powf(-2.0 / v) - 1.0);
            let (amp_a, ph_a) = polar(fa.coef[j], fa.coef[j + 1]);
            let (amp_b, ph_b) = polar(fb.coef[j], fb.coef[j + 1]);
            LineChange {
                cycles_per_rev: k,
                amplitude_from_deg: amp_a,
                amplitude_to_deg: amp_b,
                phase_from_deg: ph_a,
                phase_to_deg: ph_b,
                change_deg: d[0].hypot(d[1]),
                change_u_deg: (threshold * (c[0][0] + c[1][1]) / 2.0).sqrt(),
                significant: p_value < per_test,
                p_value,
            }
        })
        .collect();

    let backlash = layout.backlash_index().map(|j| {
        let (va, vb) = (fa.unit_cov[j][j] * ca.var, fb.unit_cov[j][j] * cb.var);
        let v = nu(va, vb).round().max(1.0) as usize;
        let se = (va + vb).sqrt();
        let t = (fb.coef[j] - fa.coef[j]) / se;
        let p_value = t_two_sided_sf(t, v);
        BacklashChange {
            from_deg: fa.coef[j],
            to_deg: fb.coef[j],
            change_u_deg: t_two_sided_isf(per_test, v) * se,
            significant: p_value < per_test,
            p_value,
        }
    });

    let map = (common.len() >= 3).then(|| map_change(&common, &ca, &cb, axis_var, per_test));
    let any = |l: &LineChange| l.significant;
    let changed = lines_out.iter().any(any)
        || backlash.as_ref().is_some_and(|b| b.significant)
        || map.as_ref().is_some_and(|m| m.significant);
    Ok(Comparison {
        verdict: if changed { Verdict::Changed } else { Verdict::Unchanged },
        lines: lines_out,
        lines_not_tested,
        not_estimable,
        backlash,
        map,
        false_alarm_rate: alpha,
        per_test_rate: per_test,
        repeatability_deg: [ca.var.sqrt(), cb.var.sqrt()],
    })
}

/// Amplitude and phase of `c cos + s sin = A sin(x + phase)`.
fn polar(c: f64, s: f64) -> (f64, f64) {
    (c.hypot(s), c.atan2(s).to_degrees())
}

/// The Welch-Satterthwaite degrees of freedom of `va + vb`, each estimated
/// with `da` and `db` degrees of freedom.
fn welch(va: f64, da: usize, vb: f64, db: usize) -> f64 {
    let den = va * va / da.max(1) as f64 + vb * vb / db.max(1) as f64;
    if den > 0.0 { ((va + vb).powi(2) / den).max(1.0) } else { 1.0 }
}

/// The map test on the common cells `(a, b)`.
fn map_change(common: &[(&fit::Cell, &fit::Cell)], ca: &Cells, cb: &Cells, axis_var: f64, per_test: f64) -> MapChange {
    let c = common.len();
    let d: Vec<f64> = common.iter().map(|(x, y)| y.mean_deg - x.mean_deg).collect();
    let dinv: Vec<f64> = common.iter().map(|(x, y)| 1.0 / (ca.var / x.n as f64 + cb.var / y.n as f64)).collect();
    let ones = vec![1.0; c];
    // x^T S^-1 y with S = D + axis_var (u u^T + w w^T) (Woodbury).
    let u: Vec<f64> = common.iter().map(|(x, _)| x.theta_deg.to_radians().cos()).collect();
    let w: Vec<f64> = common.iter().map(|(x, _)| x.theta_deg.to_radians().sin()).collect();
    let dot = |x: &[f64], y: &[f64]| -> f64 { x.iter().zip(y).zip(&dinv).map(|((a, b), s)| a * b * s).sum() };
    let inner = |x: &[f64], y: &[f64]| -> f64 {
        if axis_var <= 0.0 {
            return dot(x, y);
        }
        let m = [[1.0 / axis_var + dot(&u, &u), dot(&u, &w)], [dot(&w, &u), 1.0 / axis_var + dot(&w, &w)]];
        let (px, py) = ([dot(&u, x), dot(&w, x)], [dot(&u, y), dot(&w, y)]);
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let minv_py = [(m[1][1] * py[0] - m[0][1] * py[1]) / det, (m[0][0] * py[1] - m[1][0] * py[0]) / det];
        dot(x, y) - (px[0] * minv_py[0] + px[1] * minv_py[1])
    };
    let (dd, d1, oo) = (inner(&d, &d), inner(&d, &ones), inner(&ones, &ones));
    let q = dd - d1 * d1 / oo;
    let offset = d1 / oo;
    let changes: Vec<f64> = d.iter().map(|v| v - offset).collect();
    let n_a = common.iter().map(|(x, _)| x.n as f64).sum::<f64>() / c as f64;
    let n_b = common.iter().map(|(_, y)| y.n as f64).sum::<f64>() / c as f64;
    let nu = welch(ca.var / n_a, ca.dof, cb.var / n_b, cb.dof).round() as usize;
    let dof = [c - 1, nu.max(1)];
    let statistic = q / dof[0] as f64;
    let p_value = f_sf(statistic, dof[0], dof[1]);
    MapChange {
        cells: c,
        rms_change_deg: (changes.iter().map(|v| v * v).sum::<f64>() / c as f64).sqrt(),
        peak_change_deg: changes.iter().fold(0.0, |m, v| m.max(v.abs())),
        statistic,
        dof,
        significant: p_value < per_test,
        p_value,
    }
}

/// A table applied to a survey: does it still correct as stated?
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TableCheck {
    /// The largest systematic error the table leaves on the second survey
    /// (a cell's mean corrected error, less their mean), degrees.
    pub residual_peak_deg: f64,
    /// Its rms over the cells, degrees.
    pub residual_rms_deg: f64,
    /// The same on the first survey, the one the table was made from (what
    /// it was predicted to leave), at the cells both measured, degrees.
    pub predicted_peak_deg: Option<f64>,
    /// The table's stated expanded uncertainty `U` (k = 2), degrees.
    pub stated_u_deg: f64,
    /// Cells tested: those both surveys measured, else every cell of the second.
    pub cells: usize,
    /// Cells outside: where the error moved by more than `U` (with the cell
    /// means' noise), or without common cells, where the residual exceeds it.
    pub cells_outside: usize,
    /// The most cells that may be outside while the table holds.
    pub allowed_outside: usize,
    /// The best estimate of the rms of what the table leaves beyond its
    /// statement at the tested cells (a common cell's move, a cell between
    /// the first survey's targets its residual), the cell means' noise
    /// removed, degrees (0 when the noise explains it all).
    pub left_rms_deg: f64,
    /// The least that rms is at the test's rate (its one-sided lower
    /// confidence bound), degrees.
    pub left_rms_least_deg: f64,
    /// The rms of the largest line that stays within `U` at 95 % of the
    /// readouts (amplitude `1.0031 U`, rms `0.7093 U`), degrees.
    pub left_rms_allowed_deg: f64,
    /// Whether the table still holds: no more cells outside than allowed,
    /// and what it leaves no larger in rms than the line it may leave.
    pub holds: bool,
}

/// The rms of a sine that exceeds `U` at exactly 5 % of its readouts, per
/// unit `U`: amplitude `1 / sin(0.475 pi)`, over the square root of 2.
pub const LINE_RMS_WITHIN_U: f64 = 0.709_294;

/// The mean square of `x` less what the noise `s2` (each value's variance,
/// the centring's `1 - 1/n` applied) puts into it, and the least it is at
/// one-sided rate `rate`; `dof`: the degrees of freedom of the noise's
/// estimate.
fn mean_square_left(x: &[(f64, f64)], dof: usize, rate: f64) -> (f64, f64) {
    let n = x.len() as f64;
    if x.is_empty() {
        return (0.0, 0.0);
    }
    let keep = 1.0 - 1.0 / n;
    let ms = x.iter().map(|(v, _)| v * v).sum::<f64>() / n;
    let noise = x.iter().map(|(_, s2)| s2 * keep).sum::<f64>() / n;
    let left = ms - noise;
    // Var(v^2) = 4 m^2 s^2 + 2 s^4 for v ~ N(m, s^2), m^2 estimated by
    // v^2 - s^2; and the noise's own estimate, 2 s^4 / dof.
    let var = x.iter().map(|(v, s2)| 4.0 * (v * v - s2).max(0.0) * s2 + 2.0 * s2 * s2).sum::<f64>() / (n * n)
        + 2.0 * noise * noise / dof.max(1) as f64;
    let z = normal_two_sided_isf(2.0 * rate);
    (left.max(0.0), left - z * var.sqrt())
}

/// Apply `table`, made from survey `a` and stated to leave at most
/// `stated_u_deg` (k = 2), to survey `b` (see the module documentation);
/// `None` when `b` has no repeatability (one run).
pub fn table_on(
    table: &CorrectionTable,
    stated_u_deg: f64,
    a: &[Sample],
    b: &[Sample],
    alpha: f64,
    axis_se_deg: [f64; 2],
) -> Option<TableCheck> {
    let axis_var = axis_se_deg[0].powi(2) + axis_se_deg[1].powi(2);
    let corrected = |samples: &[Sample]| -> Vec<Sample> {
        samples
            .iter()
            .map(|s| Sample { readout_deg: s.readout_deg - table.error_at(s.readout_deg, s.direction), ..*s })
            .collect()
    };
    let cb = cells(&corrected(b))?;
    let ca = cells(&corrected(a));
    let centred = |c: &Cells| {
        let mean = c.cells.values().map(|x| x.mean_deg).sum::<f64>() / c.cells.len() as f64;
        c.cells.iter().map(move |(k, x)| (*k, x.mean_deg - mean, x.n)).collect::<Vec<_>>()
    };
    let residual = centred(&cb);
    let peak = |r: &mut dyn Iterator<Item = f64>| r.fold(0.0, |m: f64, v| m.max(v.abs()));
    let common: Vec<(f64, f64, f64)> = match &ca {
        // The change of each common cell's corrected mean (the table cancels),
        // less the mean change, and the noise of that change.
        Some(ca) => {
            let pairs: Vec<(f64, f64, f64)> = ca
                .cells
                .iter()
                .filter_map(|(k, x)| {
                    let y = cb.cells.get(k)?;
                    Some((x.mean_deg, y.mean_deg, (ca.var / x.n as f64 + cb.var / y.n as f64).sqrt()))
                })
                .collect();
            let (ma, mb) = pairs.iter().fold((0.0, 0.0), |(p, q), (x, y, _)| (p + x, q + y));
            let n = pairs.len().max(1) as f64;
            pairs.iter().map(|(x, y, s)| (x - ma / n, (y - mb / n) - (x - ma / n), *s)).collect()
        }
        None => Vec::new(),
    };
    // Each tested cell's value (a common cell's move, else its residual) and
    // its noise variance, the axis each survey's reference fitted included.
    let mut tested: Vec<(f64, f64)> = Vec::new();
    let (cells_tested, outside, predicted) = if common.len() >= 3 {
        let outside = common.iter().filter(|(_, d, s)| d.abs() > stated_u_deg + 2.0 * s).count();
        tested.extend(common.iter().map(|(_, d, s)| (*d, s * s + axis_var)));
        // B's cells between A's targets: what the table leaves where it
        // interpolates, held to U itself (no measurement of A to move from).
        let between: Vec<&(CellKey, f64, usize)> =
            residual.iter().filter(|(k, _, _)| ca.as_ref().is_some_and(|ca| !ca.cells.contains_key(k))).collect();
        let beyond =
            between.iter().filter(|(_, r, n)| r.abs() > stated_u_deg + 2.0 * (cb.var / *n as f64).sqrt()).count();
        tested.extend(between.iter().map(|(_, r, n)| (*r, cb.var / *n as f64 + axis_var)));
        (common.len() + between.len(), outside + beyond, Some(peak(&mut common.iter().map(|c| c.0))))
    } else {
        let outside =
            residual.iter().filter(|(_, r, n)| r.abs() > stated_u_deg + 2.0 * (cb.var / *n as f64).sqrt()).count();
        tested.extend(residual.iter().map(|(_, r, n)| (*r, cb.var / *n as f64 + axis_var)));
        (residual.len(), outside, None)
    };
    // Two tests, each at half the rate: the count of cells outside, and the
    // rms of what the table leaves against the largest line it may leave.
    let p0 = 0.05 + 0.95 * normal_two_sided_sf(2.0);
    let allowed = binomial_isf(cells_tested, p0, alpha / 2.0);
    let dof = ca.as_ref().map_or(cb.dof, |ca| ca.dof.min(cb.dof));
    let (left_ms, least_ms) = mean_square_left(&tested, dof, alpha / 2.0);
    let rms_allowed = LINE_RMS_WITHIN_U * stated_u_deg;
    let rms_beyond = least_ms > rms_allowed * rms_allowed;
    Some(TableCheck {
        residual_peak_deg: peak(&mut residual.iter().map(|r| r.1)),
        residual_rms_deg: (residual.iter().map(|r| r.1 * r.1).sum::<f64>() / residual.len() as f64).sqrt(),
        predicted_peak_deg: predicted,
        stated_u_deg,
        cells: cells_tested,
        cells_outside: outside,
        allowed_outside: allowed,
        left_rms_deg: left_ms.sqrt(),
        left_rms_least_deg: least_ms.max(0.0).sqrt(),
        left_rms_allowed_deg: rms_allowed,
        holds: outside <= allowed && !rms_beyond,
    })
}

/// The smallest `q` with `P(Bin(n, p) > q) <= alpha`.
fn binomial_isf(n: usize, p: f64, alpha: f64) -> usize {
    // P(X = k) by the recurrence from P(X = 0) = (1 - p)^n, in logs for large n.
    let mut log_pk = n as f64 * (1.0 - p).ln();
    let mut cdf = log_pk.exp();
    let mut q = 0;
    while 1.0 - cdf > alpha && q < n {
        log_pk += ((n - q) as f64 / (q + 1) as f64).ln() + (p / (1.0 - p)).ln();
        q += 1;
        cdf += log_pk.exp();
    }
    q
}

/// Whether to recalibrate, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Decision {
    /// Recalibrate: the table in force no longer holds, or a change exceeds
    /// the tolerance stated for the asset.
    pub recalibrate: bool,
    /// Something changed beyond what the two surveys' repeatability allows
    /// (with the table still holding: "changed, the table holds").
    pub changed: bool,
    /// Why, in words, each change named with its size.
    pub reason: String,
}

/// The decision from a comparison and, when a table was applied, its
/// check; `tolerance_deg`: the tolerance stated for the asset (its
/// configuration's `[certificate] tolerance_deg`), which a change may not
/// exceed. What a laboratory pays a recalibration for: the table in force
/// no longer holds (its residual beyond its stated U at the stated rate), or
/// a change exceeds the tolerance. A significant change within a table that
/// still holds is named ("changed, the table holds") and recalibrates nothing.
pub fn decide(c: &Comparison, table: Option<&TableCheck>, tolerance_deg: Option<f64>) -> Decision {
    // Each significant change: its words and its size.
    let mut changes: Vec<(String, f64)> = Vec::new();
    for l in c.lines.iter().filter(|l| l.significant) {
        changes.push((
            format!(
                "the {} cycles/rev line changed from {:.3e} to {:.3e} deg (by {:.2e} deg; the repeatability allows \
                 {:.2e})",
                fmt_cycles(l.cycles_per_rev),
                l.amplitude_from_deg,
                l.amplitude_to_deg,
                l.change_deg,
                l.change_u_deg
            ),
            l.change_deg,
        ));
    }
    if let Some(b) = c.backlash.as_ref().filter(|b| b.significant) {
        changes.push((
            format!(
                "the backlash changed from {:.3e} to {:.3e} deg (the repeatability allows {:.2e})",
                b.from_deg, b.to_deg, b.change_u_deg
            ),
            (b.to_deg - b.from_deg).abs(),
        ));
    }
    if let Some(m) = c.map.as_ref().filter(|m| m.significant) {
        changes.push((
            format!(
                "the mean error map changed: {:.2e} deg rms, {:.2e} deg at most over {} cells (F = {:.2}, p = {:.1e})",
                m.rms_change_deg, m.peak_change_deg, m.cells, m.statistic, m.p_value
            ),
            m.peak_change_deg,
        ));
    }
    let beyond = |size: f64| tolerance_deg.is_some_and(|t| size > t);
    // The cells' test has little power on a check's few noisy cells; the
    // changes the tests found are the best estimate of what the table now
    // leaves: held to U at the same rate, the table fails on either.
    let estimate = table.map(|t| (t, changes_left(c, t.stated_u_deg))).filter(|(_, l)| l.share > MAY_EXCEED);
    let fails = table.filter(|t| !t.holds);
    let held = match table {
        Some(t) => format!("; the table in force holds (it leaves {:.2e} deg)", t.residual_peak_deg),
        None => String::new(),
    };
    if fails.is_some() || estimate.is_some() || changes.iter().any(|(_, size)| beyond(*size)) {
        let mut why: Vec<String> = changes
            .iter()
            .map(|(w, size)| match tolerance_deg.filter(|_| beyond(*size)) {
                Some(t) => format!("{w}, beyond the asset's tolerance of {t:.2e} deg"),
                None => w.clone(),
            })
            .collect();
        if let Some(t) = fails.filter(|t| t.cells_outside > t.allowed_outside) {
            let predicted = t.predicted_peak_deg.map_or(String::new(), |p| format!(" where it left {p:.2e} deg"));
            why.push(format!(
                "the table in force no longer holds: it leaves {:.2e} deg{predicted}, {} of {} cells beyond its \
                 stated U {:.2e} deg where {} may be",
                t.residual_peak_deg, t.cells_outside, t.cells, t.stated_u_deg, t.allowed_outside
            ));
        } else if let Some(t) = fails {
            why.push(format!(
                "the table in force no longer holds: what it leaves beyond its statement is {:.2e} deg rms over {} \
                 cells, the noise removed (at least {:.2e} at the test's rate), where a line within its stated U \
                 {:.2e} deg at 95 % of readouts leaves {:.2e}",
                t.left_rms_deg, t.cells, t.left_rms_least_deg, t.stated_u_deg, t.left_rms_allowed_deg
            ));
        } else if let Some((t, left)) = estimate {
            why.push(format!(
                "the table in force no longer holds: what changed leaves {:.2e} deg ({:.2e} rms, the best estimate), beyond \
                 its stated U {:.2e} deg at {:.0} % of readouts where 5 % may be",
                left.peak_deg,
                left.rms_deg,
                t.stated_u_deg,
                100.0 * left.share
            ));
        }
        return Decision { recalibrate: true, changed: !changes.is_empty(), reason: why.join("; ") };
    }
    if !changes.is_empty() {
        let named: Vec<&str> = changes.iter().map(|(w, _)| w.as_str()).collect();
        let tolerance =
            tolerance_deg.map_or(String::new(), |t| format!(", within the asset's tolerance of {t:.2e} deg"));
        return Decision {
            recalibrate: false,
            changed: true,
            reason: format!("changed, the table holds: {}{tolerance}{held}", named.join("; ")),
        };
    }
    Decision {
        recalibrate: false,
        changed: false,
        reason: format!(
            "no change beyond what the two surveys' repeatability allows (false-alarm rate {}){held}",
            c.false_alarm_rate
        ),
    }
}

/// `20` or `20.5`.
/// The share of readouts at which a table may leave more than its `U`.
const MAY_EXCEED: f64 = 0.05;

/// What the significant changes leave where the table in force was exact:
/// their best estimates (a changed line's phasor change as measured, the
/// backlash's change half to each direction), summed over a turn. Only
/// changes the tests found significant count, so an unchanged positioner
/// reaches this at most at the tests' false-alarm rate; a change's lower
/// bound instead would let a table leave its `U` for as long as the
/// check's noise stays near the change (issue 49: a wearing positioner
/// recalibrated 67 simulated days late).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChangesLeft {
    /// The largest magnitude, degrees.
    pub peak_deg: f64,
    /// The rms over the readouts, degrees.
    pub rms_deg: f64,
    /// The share of readouts (both directions where the backlash changed)
    /// where it is beyond `u_deg`.
    pub share: f64,
}

/// [`ChangesLeft`] of comparison `c` against a table's `u_deg`.
pub fn changes_left(c: &Comparison, u_deg: f64) -> ChangesLeft {
    let lines: Vec<(f64, f64, f64)> = c
        .lines
        .iter()
        .filter(|l| l.significant)
        .map(|l| {
            let (pa, pb) = (l.phase_from_deg.to_radians(), l.phase_to_deg.to_radians());
            // A sin(k t + p) = A cos p sin(k t) + A sin p cos(k t).
            let (s, co) = (
                l.amplitude_to_deg * pb.cos() - l.amplitude_from_deg * pa.cos(),
                l.amplitude_to_deg * pb.sin() - l.amplitude_from_deg * pa.sin(),
            );
            (l.cycles_per_rev, s, co)
        })
        .collect();
    let half_backlash =
        c.backlash.as_ref().filter(|b| b.significant).map_or(0.0, |b| (b.to_deg - b.from_deg).abs() / 2.0);
    const READOUTS: usize = 3600;
    let (mut peak, mut sum2, mut beyond, mut n) = (0.0f64, 0.0, 0usize, 0usize);
    for i in 0..READOUTS {
        let t = std::f64::consts::TAU * i as f64 / READOUTS as f64;
        let v: f64 = lines.iter().map(|(k, s, co)| s * (k * t).sin() + co * (k * t).cos()).sum();
        let sides: &[f64] = if half_backlash > 0.0 { &[1.0, -1.0] } else { &[0.0] };
        for side in sides {
            let r = v + side * half_backlash;
            peak = peak.max(r.abs());
            sum2 += r * r;
            beyond += usize::from(r.abs() > u_deg);
            n += 1;
        }
    }
    ChangesLeft { peak_deg: peak, rms_deg: (sum2 / n as f64).sqrt(), share: beyond as f64 / n as f64 }
}

fn fmt_cycles(k: f64) -> String {
    if k.fract() == 0.0 { format!("{k:.0}") } else { format!("{k}") }
}
