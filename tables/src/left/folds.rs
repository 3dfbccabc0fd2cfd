//! Lines the design does not name that fold onto a line the table holds
//! (issue 49): a named line's bin can be in doubt.
//!
//! A tooth mesh above the sampling's resolution is named by the design, and
//! so are its sidebands at the gear pass; its **once-per-revolution
//! sidebands** (`h T +/- 1`: the runout of the gear that carries the mesh
//! modulating it, the commonest sideband of a mesh) are not. At `N` points
//! a revolution they land on bin `|h T +/- 1 - N m|`; at `N = T` on bin 1,
//! the eccentricity's, and the mesh itself on bin 0, where the targets
//! cannot see it at all (a constant). A line the table carries at such a
//! bin may then be in part a line at another frequency: at the targets the
//! table matches it, between them it does not.
//!
//! [`of`] lists these folds for a survey: for each mesh harmonic `h T` that
//! carries sidebands (`h` up to the analysis' `sideband_tooth_harmonics`,
//! default 1), each sideband `h T +/- 1` above `N / 2` the design does not
//! name, landing on a bin that holds a repeatable line (or on bin 0), and
//! the mesh harmonic itself where it lands on bin 0; not the Nyquist bin
//! (its own doubt). Three columns of check points (a quarter, a half and
//! three quarters of a step) cannot tell more folds apart than that: at
//! them every line at a multiple of `N` is one offset a column.
//!
//! What the survey does with them:
//!
//! - **Without check points** (an autocollimator, an import) a bin the table
//!   carries is in doubt like a possible alias ([`crate::left::LeftKind::MayFold`]):
//!   its whole line may be at one of its folds, and `U` counts the least
//!   favourable (up to twice the line between the targets). A fold on bin 0
//!   is not seen and not counted: the processing says so.
//! - **With check points** (a tracker) every fold is fitted jointly with the
//!   lines in doubt ([`fit`]: an offset, a once-per-revolution term and two
//!   columns a fold, the difference between the fold at its frequency and
//!   its alias carried at the bin), so that energy folded onto one bin no
//!   longer makes every hypothesis of another fail
//!   ([`crate::resolve::decide`]); what they measure of each fold (its size
//!   `+ k` its standard deviation) is left by the table and counted in `U`
//!   ([`crate::resolve::measure_folds`]). When even the joint fit does not explain the check
//!   points (another line the design does not name), `U` is at least what
//!   they measure the table leaves ([`crate::resolve::measured_left_deg`]).

use super::{Left, LeftKind, LeftLine, second_order};
use crate::recipe::{Decisions, LineAction};
use serde::Serialize;
use survey_processing::analysis::{Analysis, AnalysisOptions, alias, design_candidates, unalias_phase_deg};
use survey_processing::errormap::Coverage;
use survey_processing::model::{Design, PeriodicKind};

/// A line the design does not name that lands on a bin the table holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fold {
    /// Its true frequency, cycles/rev.
    pub true_cycles: f64,
    /// The bin it lands on at the survey's count.
    pub observed_cycles: f64,
    /// The frequency the table carries that bin at (the bin; a relocated
    /// line's true frequency; 0 for bin 0, the zero reference); `None`
    /// when the table does not carry it (nulled or removed: the bin's line
    /// is in doubt itself).
    pub carried_cycles: Option<f64>,
    /// What it is, in words.
    pub what: String,
}

/// The folds of a survey analysed as `analysis` with `design` (the orders
/// of `options`), the table `decisions` made (see the module documentation).
pub fn of(analysis: &Analysis, design: &Design, options: &AnalysisOptions, decisions: &Decisions) -> Vec<Fold> {
    let Coverage::FullCircle { n } = analysis.error_map.coverage else { return Vec::new() };
    let nf = n as f64;
    let named = design_candidates(design, options);
    let is_named = |f: f64| named.iter().any(|c| (c.cycles_per_rev - f).abs() < 1e-9);
    let line_at =
        |b: f64| decisions.lines.iter().find(|d| d.significant && d.repeatable && d.cycles_per_rev.round() == b);
    let mut out: Vec<Fold> = Vec::new();
    // The mesh harmonics the options say carry sidebands (the design's own
    // at the gear pass are named; these are the ones it does not name).
    let carrying = |c: &&survey_processing::analysis::Candidate| {
        c.kind == PeriodicKind::ToothMesh && c.sideband.is_none() && c.harmonic <= options.sideband_tooth_harmonics
    };
    for c in named.iter().filter(carrying) {
        let mesh = c.cycles_per_rev;
        let mut push = |f: f64, what: String| {
            // Below N / 2 a line is seen at its own bin: no fold.
            if f <= nf / 2.0 + 1e-9 || out.iter().any(|x| x.true_cycles == f) {
                return;
            }
            let b = alias(f, nf).observed.round();
            if 2.0 * b == nf {
                return;
            }
            let carried = if b == 0.0 {
                Some(0.0)
            } else {
                match line_at(b).map(|d| (d.action, d.true_cycles_per_rev)) {
                    None => return,
                    Some((LineAction::Kept, _)) => Some(b),
                    Some((LineAction::Relocated, t)) => Some(t),
                    Some((LineAction::Nulled | LineAction::Removed, _)) => None,
                }
            };
            out.push(Fold { true_cycles: f, observed_cycles: b, carried_cycles: carried, what });
        };
        if alias(mesh, nf).observed < 0.5 {
            push(mesh, format!("the {} itself", c.description));
        }
        for s in [-1.0, 1.0] {
            if !is_named(mesh + s) {
                push(
                    mesh + s,
                    format!(
                        "a once-per-revolution sideband of the {} (its gear's runout modulating the mesh)",
                        c.description
                    ),
                );
            }
        }
    }
    out
}

/// The phase at `c` of the line there that agrees at every target (`start
/// + j 360 / n`) with `sin(f r + phase_f)`.
pub fn phase_at(phase_f: f64, f: f64, c: f64, n: f64, start: f64) -> f64 {
    let a = alias(f, n);
    let shift = n * a.m * start;
    let at_bin = if a.folded { 180.0 - phase_f - shift } else { phase_f + shift };
    unalias_phase_deg(at_bin, alias(c, n), n, start)
}

/// What a fold of phase `phase_f` at `f` leaves at readout `r`, the table
/// carrying its bin `bin` at `c`: the line less its alias at `c` (nothing
/// of it at bin 0, the table's zero reference).
pub fn delta(f: f64, phase_f: f64, bin: f64, c: f64, n: f64, start: f64, r: f64) -> f64 {
    let line = (f * r + phase_f).to_radians().sin();
    if bin == 0.0 { line } else { line - (c * r + phase_at(phase_f, f, c, n, start)).to_radians().sin() }
}

/// One fold as check points measured it.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    /// Which fold (of the list fitted).
    pub fold: usize,
    /// Its amplitude and phase at its true frequency, degrees.
    pub amplitude_deg: f64,
    pub phase_deg: f64,
    /// The larger variance of its two components per unit noise variance.
    pub unit_var: f64,
}

/// A joint fit of check points.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// The residual sum of squares.
    pub ssr: f64,
    /// Its degrees of freedom (points less the columns fitted).
    pub dof: usize,
    /// The folds the points resolve (a fold whose columns the others
    /// absorb at these points is not measured, and not fitted).
    pub measured: Vec<Measured>,
}

/// `y` (readout, value) fitted by an offset, a once-per-revolution term
/// (the check points' axis against the table's) and, for each of `folds`,
/// [`delta`] at phases 0 and 90 deg, its bin carried at `carried(fold)`.
/// Columns the points cannot tell from those before them are dropped with
/// their fold. `None` when even the first three cannot be fitted.
pub fn fit(y: &[(f64, f64)], folds: &[Fold], carried: &dyn Fn(&Fold) -> f64, n: f64, start: f64) -> Option<Joint> {
    let column = |g: &dyn Fn(f64) -> f64| -> Vec<f64> { y.iter().map(|(r, _)| g(*r)).collect() };
    let mut used: Vec<usize> = (0..folds.len()).collect();
    let values: Vec<f64> = y.iter().map(|p| p.1).collect();
    // Relative to the columns' size (about sqrt(n)): what rounding leaves
    // of a column the others span exactly (a fold at half steps only).
    let floor = 1e-6 * (y.len() as f64).sqrt();
    loop {
        let mut columns =
            vec![vec![1.0; y.len()], column(&|r| r.to_radians().sin()), column(&|r| r.to_radians().cos())];
        for &i in &used {
            let fd = &folds[i];
            let c = carried(fd);
            for ph in [0.0, 90.0] {
                columns.push(column(&|r| delta(fd.true_cycles, ph, fd.observed_cycles, c, n, start, r)));
            }
        }
        let cols = columns.len();
        if y.len() <= cols {
            if used.is_empty() {
                return None;
            }
            used.pop();
            continue;
        }
        match survey_processing::lstsq::Qr::new(columns, |_| floor) {
            Ok(qr) => {
                let (x, ssr) = qr.solve(&values);
                let var = qr.unit_var();
                let measured = used
                    .iter()
                    .enumerate()
                    .map(|(k, &i)| {
                        let (s, c) = (x[3 + 2 * k], x[4 + 2 * k]);
                        Measured {
                            fold: i,
                            amplitude_deg: s.hypot(c),
                            phase_deg: c.atan2(s).to_degrees().rem_euclid(360.0),
                            unit_var: var[3 + 2 * k].max(var[4 + 2 * k]),
                        }
                    })
                    .collect();
                return Some(Joint { ssr, dof: y.len() - cols, measured });
            }
            Err(j) if j >= 3 => {
                used.remove((j - 3) / 2);
            }
            Err(_) => return None,
        }
    }
}

/// The frequency the table carries fold `f`'s bin at under hypothesis `h`
/// of `left`'s lines: the table's, or, where the bin's own line is in
/// doubt, the hypothesis' (its part at the fold is moved from there).
pub fn carried_under(left: &Left, h: &[f64], f: &Fold) -> f64 {
    f.carried_cycles
        .or_else(|| left.lines.iter().zip(h).find(|(l, _)| l.observed_cycles == f.observed_cycles).map(|(_, &c)| c))
        .unwrap_or(f.observed_cycles)
}

impl Left {
    /// `self` with the folds of its survey ([`of`]): each bin the table
    /// carries that folds land on in doubt ([`LeftKind::MayFold`]: the whole
    /// line may be one of them) until check points measure them.
    pub fn with_folds(mut self, folds: Vec<Fold>, analysis: &Analysis) -> Left {
        let mut bins: Vec<(f64, f64)> =
            folds.iter().filter_map(|f| f.carried_cycles.map(|c| (f.observed_cycles, c))).collect();
        bins.dedup();
        for (b, c) in bins {
            if b == 0.0 || self.lines.iter().any(|l| l.observed_cycles == b) {
                continue;
            }
            let Some(l) = analysis.lines.iter().find(|l| l.repeatable && l.cycles_per_rev.round() == b) else {
                continue;
            };
            let at: Vec<&Fold> = folds.iter().filter(|f| f.observed_cycles == b).collect();
            let names: Vec<String> = at.iter().map(|f| format!("{} ({})", f.true_cycles, f.what)).collect();
            self.lines.push(LeftLine {
                observed_cycles: b,
                amplitude_deg: l.amplitude_deg,
                phase_deg: l.phase_deg,
                noise_sd_deg: l.noise_sd_deg,
                kind: LeftKind::MayFold,
                candidates: std::iter::once(c).chain(at.iter().map(|f| f.true_cycles)).collect(),
                carried_cycles: Some(c),
                why: format!(
                    "the line at bin {b} ({:.2e} deg) may be in part a line the design does not name folded onto it \
                     at {} points: {}; unmeasured between the targets, the table (carrying it at {c} cycles/rev) may \
                     leave up to twice it there",
                    l.amplitude_deg,
                    self.points,
                    names.join(", ")
                ),
            });
        }
        self.lines.sort_by(|a, b| b.amplitude_deg.total_cmp(&a.amplitude_deg));
        self.second_order_deg = second_order(&self.lines, analysis);
        self.folds = folds;
        self.worst = self.least_favourable(&analysis.error_map.targets_deg);
        self
    }

    /// The lines as check points decide them: a bin that may hold folds is
    /// fixed where the table carries it (its folds are fitted instead).
    pub fn for_decision(&self) -> Left {
        let mut out = self.clone();
        for l in out.lines.iter_mut().filter(|l| l.kind == LeftKind::MayFold) {
            l.candidates = vec![l.carried_cycles.unwrap_or(l.observed_cycles)];
        }
        out
    }

    /// What the processing says of the folds no check point measured: a
    /// fold on bin 0 is not seen by the targets at all.
    pub fn unseen_folds(&self) -> Vec<String> {
        self.folds
            .iter()
            .filter(|f| f.observed_cycles == 0.0)
            .filter(|f| !self.lines.iter().any(|l| l.kind == LeftKind::Folded && l.candidates == [f.true_cycles]))
            .map(|f| {
                format!(
                    "{} cycles/rev ({}) lands on bin 0 at {} points: the targets cannot see it, and U does not count \
                     it; check points between the targets (a tracker) or a survey at another count of points measure \
                     it",
                    f.true_cycles, f.what, self.points
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fold_and_its_alias_agree_at_the_targets() {
        for (n, start) in [(180.0, 0.0), (180.0, 0.7), (72.0, 2.5)] {
            for (f, c) in [(n - 1.0, 1.0), (n + 1.0, 1.0), (n + 12.0, 12.0), (2.0 * n - 5.0, 5.0), (n - 3.0, n + 3.0)] {
                let bin = alias(f, n).observed.round();
                for ph in [0.0, 37.0, 90.0] {
                    for j in 0..n as usize {
                        let t = start + 360.0 * j as f64 / n;
                        let v = delta(f, ph, bin, c, n, start, t);
                        assert!(v.abs() < 1e-9, "{f} at {c}, N {n}, phase {ph}, target {t}: {v}");
                    }
                    // Between them it is a line (at a quarter step: `2N - f` agrees at the
                    // half steps too).
                    let mid = (0..n as usize)
                        .map(|j| delta(f, ph, bin, c, n, start, start + 360.0 * (j as f64 + 0.25) / n).abs())
                        .fold(0.0, f64::max);
                    assert!(mid > 0.9, "{f} at {c}: {mid}");
                }
            }
        }
    }
}
