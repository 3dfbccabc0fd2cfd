//! The survey resolves its own doubts: where the analysis cannot tell a line
//! from an alias at its bin ([`crate::left`]: two design
//! harmonics at one bin, or a line of an unknown design that may be the
//! alias of a frequency above the sampling's resolution), a reference that
//! can measure anywhere (a tracker) measures check points between the
//! targets, and the processing decides the line's true frequency from them.
//!
//! # Where to measure ([`plan_checks`])
//!
//! Each candidate true frequency of a line predicts a different error
//! between the targets (at the targets they all agree: that is the
//! ambiguity). The check points are chosen where the candidates' predictions
//! differ most: on a grid of a quarter, a half and three quarters of every
//! gap between the targets, the spread `max_c s_c(r) - min_c s_c(r)` of each
//! line's candidates is summed over the lines, and the angles of the largest
//! spread are taken (at most one per gap, so they cover the circle), four per
//! candidate frequency and at least twelve.
//!
//! # What decides ([`decide`])
//!
//! At a check point the table made without the answer leaves
//! `d(r) = error(r) - table(r)`; under hypothesis `h` (one true frequency per
//! line) the table leaves `s_h(r)` ([`crate::left::Left::at`]).
//! Each hypothesis is a least-squares fit of `d - s_h` by an offset and a
//! once-per-revolution term (the check points are measured around the axis
//! located before the runs, the table around the refitted one: their
//! difference is once per revolution) and its residual sum of squares
//! `SSR_h` is set against the noise `sigma` of the check points (the scatter
//! of their runs about their per-point, per-direction means): the best
//! hypothesis is **decided** when its residual is what the noise makes
//! (`SSR / dof <= sigma^2 (1 + 3 sqrt(2 / dof + 2 / dof_sigma))`, three
//! standard deviations of the ratio, an `F(dof, dof_sigma)`: `sigma^2` is
//! itself estimated from `dof_sigma` degrees of freedom) and every other is worse by more
//! than `25 sigma^2` (a likelihood ratio of 5 standard deviations);
//! otherwise nothing is decided and the table states what it leaves. A line
//! decided at a frequency above `N/2` is relocated there; one decided where
//! it is seen stays, no longer in doubt. What the check points cannot
//! exclude stays in `U`: a second, smaller line at another candidate, up to
//! `k` standard deviations of an amplitude fitted to them (`sigma sqrt(2/n)`),
//! which the table (carrying the bin's mix at the decided frequency) misses
//! at both frequencies ([`Resolution::rest_deg`]).

mod folded;

pub use folded::{Folds, measure_folds};

use crate::left::{Left, LeftKind, LeftLine};
use serde::Serialize;
use survey_processing::analysis::alias;
use survey_processing::table::CorrectionTable;
use survey_processing::types::Sample;

/// Check points per candidate frequency.
const PER_CANDIDATE: usize = 4;
/// The fewest check points planned.
const MIN_CHECKS: usize = 12;
/// The likelihood ratio (in `sigma^2`) the runner-up must lose by.
const MARGIN: f64 = 25.0;

/// Where to measure to decide what `left` leaves in doubt, between `targets`
/// (a full circle, ascending); empty when nothing is in doubt.
pub fn plan_checks(left: &Left, targets: &[f64]) -> Vec<f64> {
    let doubtful: Vec<usize> = (0..left.lines.len()).filter(|&i| in_doubt(left, i)).collect();
    if (doubtful.is_empty() && left.folds.is_empty()) || targets.len() < 2 {
        return Vec::new();
    }
    let candidates: usize = doubtful.iter().map(|&i| left.lines[i].candidates.len()).sum::<usize>() + left.folds.len();
    let wanted = (PER_CANDIDATE * candidates).max(MIN_CHECKS).min(targets.len());
    // The grid: a quarter, a half and three quarters of every gap (wrapping
    // round); eighths where folds are to be measured: a line at `m N + s` is,
    // at the fraction `q` of every step, a line of `s` cycles/rev at the
    // phase `360 m q`, so three fractions give as many columns as three
    // folds take and measure them no better than the points' noise allows
    // through an exactly determined fit; seven give each its own.
    let fractions: &[f64] =
        if left.folds.is_empty() { &[0.25, 0.5, 0.75] } else { &[0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875] };
    let grid: Vec<(usize, f64)> = (0..targets.len())
        .flat_map(|g| {
            let a = targets[g];
            let b = if g + 1 < targets.len() { targets[g + 1] } else { targets[0] + 360.0 };
            fractions.iter().map(move |q| (g, (a + q * (b - a)).rem_euclid(360.0)))
        })
        .collect();
    // Every pair of candidates of a line, and how they differ at each grid angle.
    let view = left.for_decision();
    let base: Vec<f64> = view.lines.iter().map(|l| l.candidates[0]).collect();
    let alone = |i: usize, c: f64, r: f64| {
        let mut h = base.clone();
        h[i] = c;
        view.at(&h, r) - view.at(&base, r)
    };
    // The folds' columns (each fitted beside the others: see `decide`).
    let (n, start) = (left.points as f64, left.start_deg);
    let folds: Vec<Vec<f64>> = left
        .folds
        .iter()
        .flat_map(|f| {
            let c = crate::left::folds::carried_under(&view, &base, f);
            let grid = &grid;
            [0.0, 90.0].map(move |ph| {
                grid.iter()
                    .map(|&(_, r)| crate::left::folds::delta(f.true_cycles, ph, f.observed_cycles, c, n, start, r))
                    .collect()
            })
        })
        .collect();
    let pairs: Vec<(Vec<f64>, Option<usize>)> = doubtful
        .iter()
        .flat_map(|&i| {
            let cs = &left.lines[i].candidates;
            (0..cs.len()).flat_map(move |p| (p + 1..cs.len()).map(move |q| (i, cs[p], cs[q])))
        })
        .map(|(i, c1, c2)| (grid.iter().map(|&(_, r)| alone(i, c1, r) - alone(i, c2, r)).collect(), None))
        .chain(
            // A line on the Nyquist bin: the component the targets do not
            // see, which the check points must tell from their offset (half
            // steps of both parities).
            doubtful.iter().filter(|&&i| left.on_nyquist(i)).map(|&i| {
                let l = &left.lines[i];
                (grid.iter().map(|&(_, r)| (l.observed_cycles * r + l.phase_deg).to_radians().cos()).collect(), None)
            }),
        )
        // Each fold's column, to be told from the rest.
        .chain(folds.iter().enumerate().map(|(k, c)| (c.clone(), Some(k))))
        .collect();
    // Greedy, at most one angle per gap: each next angle the one after which
    // the pair told apart least is told apart most, what separates a pair
    // being its differences less an offset, a once-per-revolution term and
    // the folds' columns (which the decision fits away); ties (the first
    // few angles) by the sum of the squared differences.
    let mut used = vec![false; targets.len()];
    let mut chosen: Vec<usize> = Vec::new();
    while chosen.len() < wanted {
        let score = |j: usize| {
            let at: Vec<usize> = chosen.iter().copied().chain([j]).collect();
            let worst = pairs
                .iter()
                .map(|(d, own)| {
                    let pts: Vec<(f64, f64)> = at.iter().map(|&k| (grid[k].1, d[k])).collect();
                    let extra: Vec<Vec<f64>> = folds
                        .iter()
                        .enumerate()
                        .filter(|(k, _)| Some(*k) != *own)
                        .map(|(_, c)| at.iter().map(|&k| c[k]).collect())
                        .collect();
                    ssr_offset_once_per_rev_and(&pts, extra)
                })
                .fold(f64::INFINITY, f64::min);
            (worst, pairs.iter().map(|(d, _)| d[j] * d[j]).sum::<f64>())
        };
        let best = (0..grid.len())
            .filter(|&j| !used[grid[j].0])
            .map(|j| (score(j), j))
            .max_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal));
        let Some((_, j)) = best else { break };
        used[grid[j].0] = true;
        chosen.push(j);
    }
    let mut out: Vec<f64> = chosen.into_iter().map(|j| grid[j].1).collect();
    out.sort_by(f64::total_cmp);
    out
}

/// Whether line `i` of `left` has more than one candidate frequency, or
/// sits on the Nyquist bin (its size is in doubt: the targets see one
/// quadrature component of it, the check points between them the other).
/// A line that may hold folds is not: its folds are fitted beside the
/// lines in doubt ([`crate::left::folds`]).
fn in_doubt(left: &Left, i: usize) -> bool {
    left.lines[i].kind != LeftKind::MayFold && (left.lines[i].candidates.len() > 1 || left.on_nyquist(i))
}

/// Whether a residual `ssr` over `dof` degrees of freedom is what the noise
/// `sigma2` (itself estimated from `noise_dof` degrees of freedom) makes:
/// the ratio is an `F(dof, noise_dof)`, whose spread both add to; three
/// standard deviations of it.
pub(crate) fn consistent(ssr: f64, dof: usize, sigma2: f64, noise_dof: usize) -> bool {
    ssr / dof as f64 <= sigma2 * (1.0 + 3.0 * (2.0 / dof as f64 + 2.0 / noise_dof as f64).sqrt())
}

/// What the check points decided about one line.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Resolution {
    /// The line's bin.
    pub observed_cycles: f64,
    /// Why it was in doubt.
    pub kind: LeftKind,
    /// Its true frequency, when decided.
    pub decided_cycles: Option<f64>,
    /// The candidates and the residual sum of squares of the best
    /// hypothesis that gives the line each, in units of `sigma^2`.
    pub candidates: Vec<(f64, f64)>,
    /// For a decided line, the amplitude the check points cannot exclude at
    /// its other candidates (a second, smaller line sharing the bin), degrees:
    /// `k` times the standard deviation of a line's amplitude fitted to them,
    /// `sigma sqrt(2 / n)`; the table, carrying the bin's mix at the decided
    /// frequency, errs by such a line at both, which as one sinusoid of the
    /// same rms is `sqrt 2` times larger.
    pub rest_deg: f64,
    /// Whether some hypothesis explains the check points down to their noise
    /// (when not, the bin holds more than one line: see [`measured_left_deg`]).
    pub explained: bool,
    /// In words.
    pub why: String,
}

/// The decision from `checks` (samples at the check points) for the doubts
/// of `left`, with `table` the table made without the answer.
pub fn decide(left: &Left, table: &CorrectionTable, checks: &[Sample]) -> Vec<Resolution> {
    let doubtful: Vec<usize> = (0..left.lines.len()).filter(|&i| in_doubt(left, i)).collect();
    if doubtful.is_empty() {
        return Vec::new();
    }
    let d: Vec<(f64, f64)> =
        checks.iter().map(|s| (s.readout_deg, s.error_deg() - table.error_at(s.readout_deg, s.direction))).collect();
    let sigma2 = noise_var(checks, table);
    let dof = d.len().saturating_sub(3);
    let undecided = |why: String| {
        doubtful
            .iter()
            .map(|&i| Resolution {
                observed_cycles: left.lines[i].observed_cycles,
                kind: left.lines[i].kind,
                decided_cycles: None,
                candidates: Vec::new(),
                rest_deg: 0.0,
                explained: true,
                why: why.clone(),
            })
            .collect()
    };
    let Some((sigma2, noise_dof)) = sigma2.filter(|(v, _)| *v > 0.0 && dof >= 3) else {
        return undecided("the check points do not give their own noise (one run, or too few points)".into());
    };
    // Every hypothesis fitted jointly with the folds of the survey (lines
    // the design does not name, folded onto the bins the table holds): their
    // energy at the check points is not a failure of the hypothesis.
    let view = left.for_decision();
    let (n, start) = (left.points as f64, left.start_deg);
    let fits: Vec<(Vec<f64>, f64, usize)> = view
        .hypotheses()
        .into_iter()
        .map(|h| {
            let y: Vec<(f64, f64)> = d.iter().map(|&(r, v)| (r, v - view.at(&h, r))).collect();
            let carried = |f: &crate::left::folds::Fold| crate::left::folds::carried_under(&view, &h, f);
            let (ssr, k) =
                crate::left::folds::fit(&y, &left.folds, &carried, n, start).map_or((0.0, dof), |j| (j.ssr, j.dof));
            (h, ssr, k)
        })
        .collect();
    let (best_h, best, best_dof) =
        fits.iter().min_by(|a, b| a.1.total_cmp(&b.1)).map(|(h, s, k)| (h.clone(), *s, *k)).unwrap();
    let consistent = best_dof >= 3 && consistent(best, best_dof, sigma2, noise_dof);
    let dof = best_dof;
    doubtful
        .iter()
        .map(|&i| {
            let l = &left.lines[i];
            let per: Vec<(f64, f64)> = l
                .candidates
                .iter()
                .map(|&c| {
                    let s = fits.iter().filter(|(h, _, _)| h[i] == c).map(|(_, s, _)| *s).fold(f64::INFINITY, f64::min);
                    (c, s / sigma2)
                })
                .collect();
            let chosen = best_h[i];
            let runner_up =
                per.iter().filter(|(c, _)| *c != chosen).map(|(_, s)| *s).fold(f64::INFINITY, f64::min);
            // Where no hypothesis explains the points (a line no hypothesis
            // holds: another line the design does not name, two lines in one
            // bin), the candidates are judged against the residual's own
            // variance instead of the noise's: what is unexplained adds to
            // every hypothesis alike except where it resembles one's
            // difference, and then the margin in its own variance is small.
            let scale = if consistent { 1.0 } else { (best / sigma2 / dof as f64).max(1.0) };
            let margin = (runner_up - best / sigma2) / scale;
            let decided = margin > MARGIN;
            let why = if decided && !consistent {
                format!(
                    "bin {}: no candidate explains the {} check points down to their noise (best residual {:.1} \
                     sigma^2 over {dof} degrees of freedom), but against that residual's own variance they decide \
                     {chosen} cycles/rev (the next candidate {margin:.0} times it worse): U is at least what they \
                     measure the table leaves",
                    l.observed_cycles,
                    d.len(),
                    best / sigma2,
                )
            } else if decided {
                format!(
                    "bin {}: the {} check points decide {chosen} cycles/rev (residual {:.1} sigma^2 over {dof} degrees \
                     of freedom; the next candidate {:.0} sigma^2 worse)",
                    l.observed_cycles,
                    d.len(),
                    best / sigma2,
                    margin
                )
            } else if !consistent {
                format!(
                    "bin {}: no candidate explains the {} check points down to their noise (best residual {:.1} sigma^2 \
                     over {dof} degrees of freedom): the line is left as it is, in U",
                    l.observed_cycles,
                    d.len(),
                    best / sigma2
                )
            } else {
                format!(
                    "bin {}: the {} check points do not separate {chosen} cycles/rev from the next candidate \
                     ({margin:.1} sigma^2 apart, {MARGIN} needed): the line is left as it is, in U",
                    l.observed_cycles,
                    d.len()
                )
            };
            Resolution {
                observed_cycles: l.observed_cycles,
                kind: l.kind,
                decided_cycles: decided.then_some(chosen),
                candidates: per,
                rest_deg: if decided {
                    std::f64::consts::SQRT_2
                        * survey_processing::coverage::K
                        * (scale * sigma2 * 2.0 / d.len() as f64).sqrt()
                } else {
                    0.0
                },
                explained: consistent,
                why,
            }
        })
        .collect()
}

/// What check points measure a table leaves between the targets: the
/// coverage interval (95.45 %, [`survey_processing::coverage::coverage_probability`])
/// of `|d - mean d|` over them, `d = error - table`, less their own noise in
/// quadrature (`k` times one sample's standard deviation, from the scatter
/// of their runs). Used when no hypothesis
/// explains the check points: the lines of one bin are then several, in part
/// cancelling at the targets, and their measured size understates what the
/// table leaves; the check points measure it.
///
/// Returns the interval and the largest `|d - mean d|` (what the prediction
/// of the corrected peak must not go below).
pub fn measured_left_deg(table: &CorrectionTable, checks: &[Sample]) -> Option<(f64, f64)> {
    if checks.len() < MIN_CHECKS {
        return None;
    }
    let d: Vec<f64> = checks.iter().map(|s| s.error_deg() - table.error_at(s.readout_deg, s.direction)).collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let mut size: Vec<f64> = d.iter().map(|v| (v - mean).abs()).collect();
    size.sort_by(f64::total_cmp);
    let at = (survey_processing::coverage::coverage_probability() * size.len() as f64).ceil() as usize;
    // Their own noise (one sample's, from the scatter of their runs) removed
    // in quadrature from the interval: what is left of the table's error.
    let q = size[at.clamp(1, size.len()) - 1];
    let noise = noise_var(checks, table)
        .map_or(0.0, |(v, _)| survey_processing::coverage::K * survey_processing::coverage::K * v);
    Some(((q * q - noise).max(0.0).sqrt(), size[size.len() - 1]))
}

/// What check points measure of the lines on the Nyquist bin of `left`
/// that the table leaves: the targets see one quadrature component of such
/// a line, `A sin psi`, and the check points between them (at a half step,
/// where that component is zero) the other. Each line's size becomes the
/// part of the seen component the table does not carry (what it shows at
/// the targets, `(-1)^j`, against what the survey saw), its noise counted
/// (`+ k u_A`), with the component the check points measure: the amplitude
/// of `d = error - table` at the line's frequency, fitted to them with an
/// offset and a once-per-revolution term (the quadrature column they cannot
/// resolve left out), `+ k` its standard deviation; the largest over its
/// candidate frequencies; one they cannot resolve (all at half steps of
/// one parity, where it is their offset) is bounded as if none measured it
/// ([`Left::nyquist_bounded`]). `left` unchanged without enough check
/// points; `targets` the survey's.
pub fn measure_nyquist(mut left: Left, table: &CorrectionTable, checks: &[Sample], targets: &[f64]) -> Left {
    if checks.len() < MIN_CHECKS || targets.is_empty() {
        return left;
    }
    let d: Vec<(f64, f64)> =
        checks.iter().map(|s| (s.readout_deg, s.error_deg() - table.error_at(s.readout_deg, s.direction))).collect();
    let y: Vec<f64> = d.iter().map(|p| p.1).collect();
    let scale = (d.len() as f64).sqrt();
    let column = |f: &dyn Fn(f64) -> f64| -> Vec<f64> { d.iter().map(|(r, _)| f(*r)).collect() };
    // One fit: offset, once per revolution and `extra` columns; the
    // amplitude of the extra terms, + k its standard deviation.
    let fit = |extra: Vec<Vec<f64>>| -> Option<f64> {
        let mut columns =
            vec![vec![1.0; d.len()], column(&|r| r.to_radians().sin()), column(&|r| r.to_radians().cos())];
        let n = extra.len();
        columns.extend(extra);
        let qr = survey_processing::lstsq::Qr::new(columns, |_| 1e-6 * scale).ok()?;
        let (x, ssr) = qr.solve(&y);
        let dof = d.len().checked_sub(3 + n).filter(|&k| k > 0)? as f64;
        let var = qr.unit_var();
        let a = x[3..].iter().map(|v| v * v).sum::<f64>().sqrt();
        let sd = (ssr / dof * var[3..].iter().fold(0.0f64, |m, v| m.max(*v))).sqrt();
        Some(a + survey_processing::coverage::K * sd)
    };
    let amplitude_at = |f: f64| -> Option<f64> {
        let (s, c) = (column(&|r| (f * r).to_radians().sin()), column(&|r| (f * r).to_radians().cos()));
        fit(vec![s.clone(), c.clone()]).or_else(|| match (fit(vec![s]), fit(vec![c])) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        })
    };
    // What the table holds at the targets on the Nyquist bin.
    let carried = (targets
        .iter()
        .enumerate()
        .map(|(j, &t)| if j % 2 == 0 { 1.0 } else { -1.0 } * table.error_at(t, survey_processing::types::Direction::Forward))
        .sum::<f64>()
        / targets.len() as f64)
        .abs();
    for i in 0..left.lines.len() {
        if !left.on_nyquist(i) {
            continue;
        }
        let candidates = left.lines[i].candidates.clone();
        let hidden = candidates
            .into_iter()
            .filter_map(amplitude_at)
            .fold(None, |m: Option<f64>, a| Some(m.map_or(a, |m| m.max(a))));
        if let Some(h) = hidden {
            let l = &mut left.lines[i];
            let seen = l.amplitude_deg / std::f64::consts::SQRT_2;
            let seen_left = (seen - carried).abs() + survey_processing::coverage::K * l.noise_sd_deg;
            let a = seen_left.hypot(h);
            l.why = format!(
                "{}; the {} check points measure the component the targets do not see, up to {h:.2e} deg: the line \
                 left is up to {a:.2e} deg",
                l.why,
                d.len()
            );
            l.amplitude_deg = a;
            l.noise_sd_deg = 0.0;
        } else {
            // The check points cannot tell it from their offset (all at
            // half steps of one parity): bounded as if none measured it.
            let bound = 1.0 / (std::f64::consts::PI / 40.0).sin() / std::f64::consts::SQRT_2;
            let l = &mut left.lines[i];
            l.amplitude_deg *= bound;
            l.noise_sd_deg *= bound;
            l.why = format!(
                "{}; the check points cannot separate the component the targets do not see from their own offset: \
                 bounded as the seen part over sin(pi/40), {:.2e} deg",
                l.why, l.amplitude_deg
            );
        }
    }
    left.lines.sort_by(|a, b| b.amplitude_deg.total_cmp(&a.amplitude_deg));
    left.worst = left.least_favourable(targets);
    left
}

/// The residual sum of squares of `y(r)` fitted by `c + a sin r + b cos r`
/// ([`survey_processing::lstsq`]; with fewer than four points, or points that cannot
/// resolve the three terms, nothing is left: 0).
/// `extra` columns (their values at the same points) are fitted too; an
/// extra column the points cannot tell from those before it is dropped (it
/// cannot hide what it cannot reach).
fn ssr_offset_once_per_rev_and(y: &[(f64, f64)], mut extra: Vec<Vec<f64>>) -> f64 {
    let scale = (y.len() as f64).sqrt();
    let values: Vec<f64> = y.iter().map(|p| p.1).collect();
    loop {
        let mut columns = vec![
            vec![1.0; y.len()],
            y.iter().map(|(r, _)| r.to_radians().sin()).collect(),
            y.iter().map(|(r, _)| r.to_radians().cos()).collect(),
        ];
        let count = 3 + extra.len();
        columns.extend(extra.iter().cloned());
        if y.len() <= count {
            if extra.is_empty() {
                return 0.0;
            }
            extra.pop();
            continue;
        }
        match survey_processing::lstsq::Qr::new(columns, |_| 1e-9 * scale) {
            Ok(qr) => return qr.solve(&values).1,
            Err(j) if j >= 3 => {
                extra.remove(j - 3);
            }
            Err(_) => return 0.0,
        }
    }
}

/// The variance of one check sample's error about its point's and
/// direction's mean over the runs (`None` without repeated points).
pub(crate) fn noise_var(checks: &[Sample], table: &CorrectionTable) -> Option<(f64, usize)> {
    let mut groups: std::collections::BTreeMap<(u64, bool), Vec<f64>> = Default::default();
    for s in checks {
        let e = s.error_deg() - table.error_at(s.readout_deg, s.direction);
        groups
            .entry((s.target_deg.to_bits(), s.direction == survey_processing::types::Direction::Forward))
            .or_default()
            .push(e);
    }
    let (ss, dof) = groups.values().fold((0.0, 0usize), |(ss, dof), v| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (ss + v.iter().map(|x| (x - m).powi(2)).sum::<f64>(), dof + v.len() - 1)
    });
    (dof > 0).then(|| (ss / dof as f64, dof))
}

impl Left {
    /// `self` with what check points that decided a line of `before` cannot
    /// exclude at its other candidates ([`Resolution::rest_deg`]),
    /// its figures made again at `targets`.
    pub fn with_rest(mut self, before: &Left, resolutions: &[Resolution], targets: &[f64]) -> Left {
        for r in resolutions.iter().filter(|r| r.rest_deg > 0.0) {
            let (Some(f), Some(l)) =
                (r.decided_cycles, before.lines.iter().find(|l| l.observed_cycles == r.observed_cycles))
            else {
                continue;
            };
            let others: Vec<f64> = l.candidates.iter().copied().filter(|&c| c != f).collect();
            if others.is_empty() {
                continue;
            }
            let names: Vec<String> = others.iter().map(|c| format!("{c}")).collect();
            self.lines.push(LeftLine {
                observed_cycles: l.observed_cycles,
                amplitude_deg: r.rest_deg,
                phase_deg: l.phase_deg,
                noise_sd_deg: 0.0,
                kind: LeftKind::Possible,
                candidates: others,
                carried_cycles: None,
                why: format!(
                    "bin {}: decided {f} cycles/rev; the check points cannot exclude a line of up to {:.2e} deg at {} \
                     cycles/rev sharing the bin, which the table would miss",
                    l.observed_cycles,
                    r.rest_deg,
                    names.join(" or ")
                ),
            });
        }
        self.points = before.points;
        self.start_deg = before.start_deg;
        self.lines.sort_by(|a, b| b.amplitude_deg.total_cmp(&a.amplitude_deg));
        self.worst = self.least_favourable(targets);
        self
    }
}

/// What a second orientation of an autocollimator's polygon would resolve
/// (`None` when nothing is in doubt): turned by half a face on the table,
/// its faces fall half way between the first ones, and both orientations
/// together sample the circle at `2N` points per revolution. A line in doubt
/// is resolved by that when its candidate frequencies land on distinct bins
/// at `2N` points; else even that does not separate them.
pub fn second_orientation(left: &Left) -> Option<String> {
    let n2 = 2.0 * left.points as f64;
    let (resolved, unresolved): (Vec<_>, Vec<_>) =
        left.lines.iter().filter(|l| l.candidates.len() > 1).partition(|l| {
            let mut bins: Vec<f64> = l.candidates.iter().map(|&c| alias(c, n2).observed).collect();
            bins.sort_by(f64::total_cmp);
            bins.windows(2).all(|w| (w[1] - w[0]).abs() > 0.5)
        });
    if resolved.is_empty() && !unresolved.is_empty() {
        let c: Vec<String> = unresolved.iter().map(|l| describe(l)).collect();
        return Some(format!(
            "the polygon's faces fix where this survey measured; a second orientation (the polygon turned by half a \
             face) would not separate {}: their candidates land on one bin at {} points per revolution too",
            c.join(", "),
            n2
        ));
    }
    (!resolved.is_empty()).then(|| {
        let r: Vec<String> = resolved.iter().map(|l| describe(l)).collect();
        let rest = if unresolved.is_empty() {
            String::new()
        } else {
            let c: Vec<String> = unresolved.iter().map(|l| describe(l)).collect();
            format!("; it would not separate {}", c.join(", "))
        };
        format!(
            "the polygon's faces fix where this survey measured: measured again with the polygon turned by half a \
             face on the table, the faces fall half way between these, and both orientations together ({n2} points \
             per revolution) would resolve {}{rest}",
            r.join(", ")
        )
    })
}

fn describe(l: &LeftLine) -> String {
    let c: Vec<String> = l.candidates.iter().map(|c| format!("{c}")).collect();
    let what = match l.kind {
        LeftKind::NotCarried => "not carried",
        LeftKind::MaybeAlias => "kept where it is seen",
        LeftKind::Possible => "possible, not excluded",
        LeftKind::MayFold => "may hold a line the design does not name",
        LeftKind::Folded => "a line the design does not name, measured",
    };
    format!("the line at bin {} ({} cycles/rev, {what})", l.observed_cycles, c.join(" or "))
}

#[cfg(test)]
mod tests;
