//! What the comparison measures on one survey: the mean error of each cell
//! (a target in a direction) over the runs, the repeatability that says how
//! well a cell mean is known, and the least-squares fit of the lines and the
//! backlash with the covariance of its coefficients.

use std::collections::BTreeMap;
use survey_processing::lstsq::Qr;
use survey_processing::{Direction, Sample};

/// A cell: a target (to a nanodegree) in a direction.
pub(super) type CellKey = (i64, Direction);

/// The samples of one cell.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Cell {
    /// The target, degrees.
    pub theta_deg: f64,
    /// The mean error over the runs, degrees.
    pub mean_deg: f64,
    /// Samples in the cell.
    pub n: usize,
}

/// The cells of a survey and its repeatability.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Cells {
    pub cells: BTreeMap<CellKey, Cell>,
    /// The pooled variance of one sample about its cell's mean, deg^2: the
    /// run-to-run scatter (slow run-to-run offsets included: they only make
    /// the tests more cautious).
    pub var: f64,
    /// Its degrees of freedom (samples - cells).
    pub dof: usize,
}

/// The key of the cell of a sample at `theta_deg` approached in `direction`.
pub(super) fn key(theta_deg: f64, direction: Direction) -> CellKey {
    ((theta_deg * 1e9).round() as i64, direction)
}

/// The cells of `samples`; `None` when no cell holds two samples (one run:
/// the repeatability is unknown).
pub(super) fn cells(samples: &[Sample]) -> Option<Cells> {
    let mut groups: BTreeMap<CellKey, (f64, Vec<f64>)> = BTreeMap::new();
    for s in samples {
        groups
            .entry(key(s.target_deg, s.direction))
            .or_insert_with(|| (s.target_deg, Vec::new()))
            .1
            .push(s.error_deg());
    }
    let (mut ss, mut n) = (0.0, 0usize);
    let cells = groups
        .into_iter()
        .map(|(k, (theta_deg, e))| {
            let mean_deg = e.iter().sum::<f64>() / e.len() as f64;
            ss += e.iter().map(|v| (v - mean_deg).powi(2)).sum::<f64>();
            n += e.len();
            (k, Cell { theta_deg, mean_deg, n: e.len() })
        })
        .collect::<BTreeMap<_, _>>();
    let dof = n - cells.len();
    (dof > 0).then(|| Cells { var: ss / dof as f64, dof, cells })
}

/// The columns the error of a survey is fitted with: an offset, the backlash
/// (`+1/2` forward, `-1/2` reverse) when both surveys go both ways, and a
/// cosine and a sine of every line.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Layout {
    pub backlash: bool,
    pub lines: Vec<f64>,
}

impl Layout {
    /// The index of the backlash's coefficient.
    pub fn backlash_index(&self) -> Option<usize> {
        self.backlash.then_some(1)
    }

    /// The index of line `i`'s cosine coefficient (its sine is the next).
    pub fn line_index(&self, i: usize) -> usize {
        1 + usize::from(self.backlash) + 2 * i
    }

    /// The columns at the samples.
    fn columns(&self, samples: &[Sample]) -> Vec<Vec<f64>> {
        let mut cols = vec![vec![1.0; samples.len()]];
        if self.backlash {
            cols.push(samples.iter().map(|s| s.direction.sign() / 2.0).collect());
        }
        for &k in &self.lines {
            let (c, s): (Vec<f64>, Vec<f64>) =
                samples.iter().map(|x| (k * x.target_deg.to_radians()).sin_cos()).map(|(s, c)| (c, s)).unzip();
            cols.push(c);
            cols.push(s);
        }
        cols
    }
}

/// A survey's fit: the coefficients and `(A^T A)^-1`, the covariance per
/// unit variance of one sample.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Fit {
    pub coef: Vec<f64>,
    pub unit_cov: Vec<Vec<f64>>,
}

/// Fit `samples` with `layout`; `Err(column)` when a column cannot be told
/// apart from those before it at these targets (an alias of another line or
/// of the offset), or vanishes there (a line's sine on the Nyquist bin).
/// Every column's values are of order one (an offset of 1, the backlash's
/// `1/2`, a cosine or a sine), so a column is degenerate when what it adds
/// is below `1e-6 sqrt(n)`, whatever its own norm (a vanishing column's
/// norm is rounding noise: measured against itself it would pass, and its
/// coefficient be noise over noise).
pub(super) fn fit(samples: &[Sample], layout: &Layout) -> Result<Fit, usize> {
    let cols = layout.columns(samples);
    let scale = (samples.len() as f64).sqrt();
    let qr = Qr::new(cols, |_| 1e-6 * scale)?;
    let y: Vec<f64> = samples.iter().map(Sample::error_deg).collect();
    let (coef, _) = qr.solve(&y);
    Ok(Fit { coef, unit_cov: unit_covariance(&qr) })
}

/// `(A^T A)^-1 = R^-1 R^-T`.
fn unit_covariance(qr: &Qr) -> Vec<Vec<f64>> {
    let p = qr.cols();
    // Column c of R^-1, by back substitution of R x = e_c.
    let columns: Vec<Vec<f64>> = (0..p)
        .map(|c| {
            let mut x = vec![0.0; p];
            for i in (0..=c).rev() {
                let e = if i == c { 1.0 } else { 0.0 };
                let s: f64 = (i + 1..=c).map(|k| qr.r(i, k) * x[k]).sum();
                x[i] = (e - s) / qr.r(i, i);
            }
            x
        })
        .collect();
    (0..p).map(|i| (0..p).map(|j| columns.iter().map(|col| col[i] * col[j]).sum()).collect()).collect()
}

/// Why line `k` was left out of the fit of `samples` (survey `name`), the
/// lines `before` it kept.
fn left_out_why(samples: &[Sample], name: &str, before: &[f64], k: f64) -> String {
    let targets: Vec<f64> = samples.iter().map(|s| s.target_deg).collect();
    let mut lines = before.to_vec();
    lines.push(k);
    match super::seen::points_per_rev(&targets).and_then(|n| super::seen::unseen(&lines, n, false).pop()) {
        Some(u) if u.cycles_per_rev == k => format!("survey {name}: {}", u.why),
        _ => format!(
            "survey {name}: at its targets the {k} cycles/rev line cannot be told apart from the offset, the backlash \
             and the lines before it"
        ),
    }
}

/// The largest amplitude a fit of `samples` can honestly give a line: the
/// span of the survey's cell means (a line larger than the whole error's
/// peak to peak is the fit's arithmetic, not the positioner).
fn span(samples: &[Sample]) -> f64 {
    cells(samples).map_or(f64::INFINITY, |c| {
        let (lo, hi) = c
            .cells
            .values()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x.mean_deg), h.max(x.mean_deg)));
        hi - lo
    })
}

/// Fit both surveys with the lines of `lines` that both resolve (a line
/// that one of them cannot tell from the lines before it, or whose fitted
/// amplitude exceeds the span of that survey's cell means, is left out and
/// returned with why in the last list); the backlash only when both resolve
/// it. `None` when not even the offset can be fitted (no samples).
pub(super) fn fit_both(
    a: &[Sample],
    b: &[Sample],
    backlash: bool,
    lines: &[f64],
) -> Option<(Layout, [Fit; 2], Vec<super::seen::Unseen>)> {
    let mut layout = Layout { backlash, lines: lines.to_vec() };
    let mut left_out = Vec::new();
    let spans = [span(a), span(b)];
    loop {
        let (j, name, samples) = match (fit(a, &layout), fit(b, &layout)) {
            (Ok(fa), Ok(fb)) => {
                // A line the fit made larger than the error itself is ill-conditioned there.
                let first_line = layout.line_index(0);
                let too_large = (0..layout.lines.len()).find_map(|i| {
                    let j = first_line + 2 * i;
                    [(&fa, "A", 0), (&fb, "B", 1)]
                        .into_iter()
                        .find(|(f, _, s)| f.coef[j].hypot(f.coef[j + 1]) > spans[*s])
                        .map(|(f, name, s)| (i, name, f.coef[j].hypot(f.coef[j + 1]), spans[s]))
                });
                let Some((i, name, amplitude, span)) = too_large else {
                    return Some((layout, [fa, fb], left_out));
                };
                let k = layout.lines.remove(i);
                left_out.push(super::seen::Unseen {
                    cycles_per_rev: k,
                    why: format!(
                        "survey {name}: the fit gives the {k} cycles/rev line {amplitude:.2e} deg, more than the whole \
                         error's span ({span:.2e} deg): at these targets it is not estimable"
                    ),
                });
                continue;
            }
            (Err(j), _) => (j, "A", a),
            (_, Err(j)) => (j, "B", b),
        };
        let first_line = layout.line_index(0);
        if j >= first_line && (j - first_line) / 2 < layout.lines.len() {
            let i = (j - first_line) / 2;
            let why = left_out_why(samples, name, &layout.lines[..i], layout.lines[i]);
            left_out.push(super::seen::Unseen { cycles_per_rev: layout.lines.remove(i), why });
        } else if j >= 1 && layout.backlash {
            layout.backlash = false;
        } else {
            return None;
        }
    }
}
