//! What a table leaves uncorrected that the survey saw, as functions of the
//! readout: the honest part of the prediction and of the uncertainty.
//!
//! A full-circle table of `N` targets holds the lines the recipe kept. Two
//! kinds of repeatable error are seen by the survey and still not corrected
//! between the targets:
//!
//! - **A line the table does not carry** (nulled: two design harmonics alias
//!   to its bin and cannot be separated; or removed: aliased and not
//!   relocated, or removed by the recipe). The table holds nothing there, so
//!   the positioner keeps the whole line: `A sin(f r + phi_f)` at its true
//!   frequency `f`, one of the design frequencies that land on the bin
//!   (`phi_f` from the observed phase, [`survey_processing::analysis::unalias_phase_deg`]).
//!   Its size is the measured amplitude `A` of the bin (the sum of what lands
//!   there: the truth may split it between candidates, which the measured
//!   size bounds in rms).
//! - **A line that may be an alias** (the risk an unknown design hides above
//!   the sampling's resolution). A line that matches no design part sits at
//!   bin `k`; if the positioner's true line is at `N - k` (or `N + k`), the
//!   table's `A sin(k r + phi)` agrees with it at every target and differs
//!   between them: `A sin(f r + phi_f) - A sin(k r + phi)`, up to `2 A`. The
//!   risk is counted when the survey's spectrum has not died out within what
//!   it resolves: its highest repeatable line lies above `N / 4` (a
//!   positioner's errors fall with frequency; a spectrum whose lines reach
//!   into the top half of the band says nothing of what lies above it, one
//!   that stops in the bottom half leaves an alias no place to come from).
//!   A design that names the line (or another design frequency that lands
//!   on it) decides it instead (the analysis relocates or nulls it).
//!
//! Each line's true frequency is one of its candidates; a **hypothesis** is
//! one choice per line. The lines of one part are harmonics of each other,
//! so their relative phase is fixed, not random: what is left is evaluated as
//! the function it is, over the readouts of the table's range, for every
//! hypothesis (up to [`MAX_HYPOTHESES`]: the largest lines' alternatives
//! first), and the least favourable one is stated.

pub mod folds;

use crate::correction::Prediction;
use crate::recipe::{Decisions, LineAction};
use serde::Serialize;
use survey_processing::Sample;
use survey_processing::analysis::{Analysis, alias, unalias_phase_deg};
use survey_processing::errormap::Coverage;
use survey_processing::iso230::TargetGroups;
use survey_processing::model::PeriodicKind;

/// The most hypotheses evaluated (each line's true frequency one of its
/// candidates); beyond it the smaller lines keep their first candidate.
pub const MAX_HYPOTHESES: usize = 64;
/// Readouts at which what is left is evaluated: a Weyl sequence (golden
/// ratio steps) over the range, equidistributed for every frequency, so its
/// values have the distribution of the function over the readouts (to about
/// `1 / sqrt(READOUTS)` in probability).
pub const READOUTS: usize = 4096;

/// Why a line is left.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LeftKind {
    /// The table holds nothing at its bin (nulled or removed).
    NotCarried,
    /// The table holds it at its bin, which may be the alias of its true frequency.
    MaybeAlias,
    /// A line that may be there and was not excluded, up to its size: a
    /// second line sharing a bin the check points decided, at another of its
    /// candidates (the table would miss it wholly). A line the survey could
    /// have missed, like one below the detection threshold: the uncertainty
    /// counts at most one missed line, the largest of these and the
    /// threshold's.
    Possible,
    /// A line the table carries at its bin that may be in part a line the
    /// design does not name folded onto it ([`folds`]: a tooth
    /// mesh's once-per-revolution sidebands above the sampling's
    /// resolution), not measured between the targets: like a possible
    /// alias, the whole line may be at one of them.
    MayFold,
    /// A line the design does not name, folded onto a bin the table
    /// carries, as check points between the targets measured it (its size
    /// and phase fitted to them, jointly with every other fold and the
    /// lines in doubt): the table carries its alias at the bin and leaves
    /// the line between the targets.
    Folded,
}

/// One line the table leaves, wholly or possibly.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LeftLine {
    /// Where the survey sees it, cycles/rev (its bin).
    pub observed_cycles: f64,
    /// Its measured amplitude, degrees.
    pub amplitude_deg: f64,
    /// Its phase at the bin, degrees (the contract's convention).
    pub phase_deg: f64,
    /// The noise of each quadrature component of its measured phasor,
    /// degrees (how well its size is known).
    pub noise_sd_deg: f64,
    /// Why it is left.
    pub kind: LeftKind,
    /// The true frequencies it may have, cycles/rev (for `maybe_alias`, the
    /// bin itself first: the line where it is seen).
    pub candidates: Vec<f64>,
    /// For a line that may be folded or is (`may_fold`, `folded`): the
    /// frequency the table carries its bin at (the bin, or where the recipe
    /// relocated it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub carried_cycles: Option<f64>,
    /// In words.
    pub why: String,
}

/// What the table leaves: its lines and the sampling they were seen with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Left {
    /// The lines.
    pub lines: Vec<LeftLine>,
    /// Points per revolution of the survey (0 for a partial range: nothing here).
    pub points: usize,
    /// The first target, degrees (the phase reference of the bins).
    pub start_deg: f64,
    /// The least favourable hypothesis' figures (see [`Left::worst`]).
    pub worst: Option<Worst>,
    /// The standard deviation of what is left that the lines' functions of
    /// the readout leave out (see [`Left::second_order_deg`]), degrees.
    pub second_order_deg: f64,
    /// The lines the design does not name that may fold onto a bin the
    /// table holds at this count ([`folds`]): what check points fit
    /// beside the lines in doubt.
    pub folds: Vec<folds::Fold>,
}

/// The least favourable hypothesis and its figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Worst {
    /// The true frequency of each line, in the order of [`Left::lines`].
    pub true_cycles: Vec<f64>,
    /// The largest `|left|` over the readouts, degrees.
    pub peak_deg: f64,
    /// The largest `|left|` at the survey's targets, degrees.
    pub peak_at_targets_deg: f64,
    /// The RMS over the readouts, degrees.
    pub rms_deg: f64,
}

impl Left {
    /// Nothing left (a partial range, or every line carried).
    pub fn none() -> Self {
        Left { lines: Vec::new(), points: 0, start_deg: 0.0, worst: None, second_order_deg: 0.0, folds: Vec::new() }
    }

    /// What the table `decisions` made from `analysis` leaves (see the module
    /// documentation); `resolved` are bins whose line check points showed to
    /// be where it is seen ([`crate::resolve`]).
    ///
    /// `unknown_design`: the positioner's design names no part (no gear
    /// ratio, no tooth count). Then nothing but the spectrum's reach says a
    /// line is where it is seen, and a strong line above the sampling's
    /// resolution aliased to a low bin defeats that (the spectrum then looks
    /// as if it had died out): every line it sees may be an alias while the
    /// sampling's resolution, `N / 2`, lies below the highest line a
    /// positioner plausibly has ([`crate::verification::aliases::PLAUSIBLE_MAX_CYCLES`]).
    pub fn of(analysis: &Analysis, decisions: &Decisions, resolved: &[f64], unknown_design: bool) -> Self {
        let Coverage::FullCircle { n } = analysis.error_map.coverage else { return Left::none() };
        let start_deg = analysis.error_map.targets_deg.first().copied().unwrap_or(0.0);
        let nf = n as f64;
        let highest = analysis.lines.iter().filter(|l| l.repeatable).map(|l| l.cycles_per_rev).fold(0.0, f64::max);
        let unresolved = unknown_design && nf / 2.0 < crate::verification::aliases::PLAUSIBLE_MAX_CYCLES;
        let sparse = highest > nf / 4.0 || unresolved;
        let mut lines = Vec::new();
        for l in analysis.lines.iter().filter(|l| l.repeatable) {
            let bin = l.cycles_per_rev.round();
            // Bin 0 is the zero reference (an alias there is not seen at all).
            if bin == 0.0 {
                continue;
            }
            // At the Nyquist bin one quadrature component is seen, `A |sin psi|`
            // of the line's `A`: its size is taken as sqrt 2 times what is seen
            // (the rms of `|sin psi|` over a phase nothing fixes is 1 / sqrt 2).
            let nyquist = 2.0 * bin == nf;
            let amplitude_deg = if nyquist { l.amplitude_deg * std::f64::consts::SQRT_2 } else { l.amplitude_deg };
            let Some(d) = decisions.lines.iter().find(|d| d.significant && d.cycles_per_rev == l.cycles_per_rev) else {
                continue;
            };
            let design: Vec<f64> = {
                let mut c: Vec<f64> = l.candidates.iter().map(|c| c.cycles_per_rev).collect();
                c.sort_by(f64::total_cmp);
                c.dedup();
                c
            };
            let (kind, candidates, why) = match d.action {
                LineAction::Nulled | LineAction::Removed => {
                    let candidates = if design.is_empty() { vec![l.true_cycles_per_rev] } else { design };
                    let what = if d.action == LineAction::Nulled { "nulled" } else { "removed" };
                    let names: Vec<String> = candidates.iter().map(|c| format!("{c}")).collect();
                    let why = format!(
                        "the repeatable line at bin {bin} ({:.2e} deg{}) is {what} ({}): the table leaves it whole, at {} \
                         cycles/rev",
                        amplitude_deg,
                        if nyquist { ", sqrt 2 times what the Nyquist bin shows" } else { "" },
                        d.reason,
                        names.join(" or ")
                    );
                    (LeftKind::NotCarried, candidates, why)
                }
                LineAction::Kept
                    if sparse
                        && !nyquist
                        && (l.kind == PeriodicKind::Harmonic || unresolved)
                        && !l.aliased
                        && !resolved.contains(&bin) =>
                {
                    let (low, high) = (nf - bin, nf + bin);
                    let why = if highest > nf / 4.0 {
                        format!(
                            "the line at bin {bin} ({:.2e} deg) matches no design part and the spectrum reaches \
                             {highest} of the {} cycles/rev {n} points resolve: it may be the alias of {low} or {high} \
                             cycles/rev, which the table would correct at the targets only (up to twice the line \
                             between them)",
                            l.amplitude_deg,
                            nf / 2.0
                        )
                    } else {
                        format!(
                            "the line at bin {bin} ({:.2e} deg) is of a positioner whose design names no part, and {n} \
                             points resolve only {} cycles/rev: it may be the alias of {low} or {high} cycles/rev, which \
                             the table would correct at the targets only (up to twice the line between them)",
                            l.amplitude_deg,
                            nf / 2.0
                        )
                    };
                    (LeftKind::MaybeAlias, vec![bin, low, high], why)
                }
                // Kept on the Nyquist bin: the table carries the quadrature
                // component the targets see; the other, unseen, it leaves.
                LineAction::Kept | LineAction::Relocated if nyquist => {
                    let why = format!(
                        "the repeatable line at bin {bin} sits on the Nyquist bin: the table carries the part the \
                         targets see ({:.2e} deg) and leaves the quadrature component they cannot see, taken as \
                         {amplitude_deg:.2e} deg (sqrt 2 times what they see) until check points measure it",
                        l.amplitude_deg
                    );
                    (LeftKind::NotCarried, vec![bin], why)
                }
                _ => continue,
            };
            lines.push(LeftLine {
                observed_cycles: bin,
                amplitude_deg,
                phase_deg: l.phase_deg,
                noise_sd_deg: l.noise_sd_deg,
                kind,
                candidates,
                carried_cycles: None,
                why,
            });
        }
        // The largest first: their alternatives are the ones enumerated.
        lines.sort_by(|a, b| b.amplitude_deg.total_cmp(&a.amplitude_deg));
        let second_order_deg = second_order(&lines, analysis);
        let mut left = Left { lines, points: n, start_deg, worst: None, second_order_deg, folds: Vec::new() };
        left.worst = left.least_favourable(&analysis.error_map.targets_deg);
        left
    }

    /// The same lines, each at the upper end of its size's coverage
    /// interval, `A + k u_A` (`u_A` its phasor's noise per component): the
    /// size is one for every readout (systematic), so it is not averaged
    /// over them like noise; `U` is stated for the largest size the survey
    /// allows.
    pub fn at_upper_size(&self, k: f64) -> Left {
        let mut out = self.clone();
        for l in &mut out.lines {
            l.amplitude_deg += k * l.noise_sd_deg;
        }
        out
    }

    /// Whether line `i` sits on the Nyquist bin (half the points per
    /// revolution): the targets see `A sin psi` of it, nothing of the rest.
    pub fn on_nyquist(&self, i: usize) -> bool {
        self.points > 0 && 2.0 * self.lines[i].observed_cycles == self.points as f64
    }

    /// The same lines, each on the Nyquist bin bounded as a whole line when
    /// nothing measured it between the targets: the targets see `A |sin
    /// psi|` of a line whose phase `psi` against them is unknown, so the line
    /// is taken as the seen part over `sin(pi / 40)`, what all but the 5 %
    /// of phases nearest the targets' zeros allow (its size is otherwise
    /// `sqrt 2` times what is seen, the rms over the phases, which a line
    /// near a zero exceeds many times).
    pub fn nyquist_bounded(&self) -> Left {
        let mut out = self.clone();
        let bound = 1.0 / (std::f64::consts::PI / 40.0).sin() / std::f64::consts::SQRT_2;
        for i in 0..out.lines.len() {
            if out.on_nyquist(i) {
                out.lines[i].amplitude_deg *= bound;
                out.lines[i].noise_sd_deg *= bound;
            }
        }
        out
    }

    /// Whether anything is left.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// The readouts what is left is evaluated at (a full circle).
    pub fn readouts() -> Vec<f64> {
        let golden = (5f64.sqrt() - 1.0) / 2.0;
        (0..READOUTS).map(|j| 360.0 * ((j as f64 + 0.5) * golden).fract()).collect()
    }

    /// Every hypothesis: one true frequency per line, the largest lines'
    /// alternatives enumerated first, at most [`MAX_HYPOTHESES`].
    pub fn hypotheses(&self) -> Vec<Vec<f64>> {
        let mut out: Vec<Vec<f64>> = vec![Vec::new()];
        for l in &self.lines {
            let room = (MAX_HYPOTHESES / out.len()).max(1);
            let choices = &l.candidates[..l.candidates.len().min(room)];
            out = out.iter().flat_map(|h| choices.iter().map(move |&c| [h.as_slice(), &[c]].concat())).collect();
        }
        out
    }

    /// What is left at readout `r` (true error - table) under hypothesis `h`.
    pub fn at(&self, h: &[f64], r: f64) -> f64 {
        let nf = self.points as f64;
        self.lines
            .iter()
            .zip(h)
            .map(|(l, &f)| {
                let line = |cycles: f64, phase: f64| l.amplitude_deg * (cycles * r + phase).to_radians().sin();
                let phase_f = unalias_phase_deg(l.phase_deg, alias(f, nf), nf, self.start_deg);
                match l.kind {
                    LeftKind::NotCarried | LeftKind::Possible => line(f, phase_f),
                    LeftKind::MaybeAlias if f == l.observed_cycles => 0.0,
                    LeftKind::MaybeAlias => line(f, phase_f) - line(l.observed_cycles, l.phase_deg),
                    // The table carries the bin at `c`; bin 0 is its zero
                    // reference (a constant, not an error of the table).
                    LeftKind::MayFold | LeftKind::Folded => {
                        let c = l.carried_cycles.unwrap_or(l.observed_cycles);
                        if f == c {
                            0.0
                        } else if l.observed_cycles == 0.0 {
                            line(f, phase_f)
                        } else {
                            line(f, phase_f) - line(c, unalias_phase_deg(l.phase_deg, alias(c, nf), nf, self.start_deg))
                        }
                    }
                }
            })
            .sum()
    }

    /// The values of what is left under `h` at `readouts`.
    pub fn values(&self, h: &[f64], readouts: &[f64]) -> Vec<f64> {
        readouts.iter().map(|&r| self.at(h, r)).collect()
    }

    /// The hypothesis whose left error peaks highest between the targets
    /// (beyond what the survey saw at them), with its figures.
    pub(super) fn least_favourable(&self, targets: &[f64]) -> Option<Worst> {
        if self.lines.is_empty() {
            return None;
        }
        let readouts = Self::readouts();
        self.hypotheses()
            .into_iter()
            .map(|h| {
                let v = self.values(&h, &readouts);
                let peak_deg = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let rms_deg = (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
                let peak_at_targets_deg = targets.iter().fold(0.0f64, |m, &t| m.max(self.at(&h, t).abs()));
                Worst { true_cycles: h, peak_deg, peak_at_targets_deg, rms_deg }
            })
            .max_by(|a, b| {
                (a.peak_deg - a.peak_at_targets_deg, a.rms_deg)
                    .partial_cmp(&(b.peak_deg - b.peak_at_targets_deg, b.rms_deg))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
    }

    /// How much higher the left error peaks between the targets than at
    /// them, under the least favourable hypothesis, degrees: what an
    /// in-sample prediction (made at the targets) cannot see.
    pub fn unseen_peak_deg(&self) -> f64 {
        self.worst.as_ref().map_or(0.0, |w| (w.peak_deg - w.peak_at_targets_deg).max(0.0))
    }
}

/// What the lines' functions of the readout leave out: a positioner's lines
/// are of the true angle, and the readout map holds their products
/// (`E(r) = e(theta) ~ e(r) - e'(r) e(r)`, [`crate::true_angle`]).
/// The table made through the true angle carries the products of its kept
/// lines; those that involve a line it leaves stay: `e_l' e + e' e_l`. Their
/// standard deviation, each product taken as of independent factors (the
/// rms of a product is the product of the rms): `sum_l (S_l^2/2) E^2 +
/// (A_l^2/2) D^2`, `E^2` and `D^2` the mean squares of the error and its
/// slope over the survey's repeatable lines, `S_l = A_l f_l pi / 180` the
/// left line's slope at its highest candidate frequency.
pub(crate) fn second_order(lines: &[LeftLine], analysis: &Analysis) -> f64 {
    let rad = std::f64::consts::PI / 180.0;
    let repeatable = analysis.lines.iter().filter(|l| l.repeatable);
    let e2: f64 = repeatable.clone().map(|l| l.amplitude_deg.powi(2) / 2.0).sum();
    let d2: f64 = repeatable.map(|l| (l.amplitude_deg * l.true_cycles_per_rev * rad).powi(2) / 2.0).sum();
    lines
        .iter()
        .map(|l| {
            let f = l.candidates.iter().copied().fold(l.observed_cycles, f64::max);
            let s2 = (l.amplitude_deg * f * rad).powi(2) / 2.0;
            s2 * e2 + l.amplitude_deg.powi(2) / 2.0 * d2
        })
        // From +0.0: an empty `sum` is -0.0, and a standard deviation is a
        // size (`process --json` wrote `"second_order_deg": -0.0`).
        .fold(0.0, |a, b| a + b)
        .sqrt()
}

/// The prediction with what the table leaves (here, beside [`Left`], so that
/// the tables below know nothing of what a recipe decided).
impl Prediction {
    /// The prediction of what a new survey of the same plan with the table
    /// applied measures (`survey run --verify`): the in-sample peak, plus
    /// what the table leaves between the targets
    /// ([`Left::unseen_peak_deg`]), plus the spread of a peak of noise
    /// (`samples`' corrected errors about their per-target, per-direction
    /// means give the noise `sigma`; the peak of `M` such samples has a
    /// Gumbel distribution of scale `sigma / sqrt(2 ln 2M)`, and the
    /// difference of two such peaks a logistic one, which exceeds
    /// `ln(19)` scales 5 % of the time).
    /// `corrected` are the samples' corrected errors ([`crate::correction::corrected_errors`]),
    /// `groups` their grouping by target ([`TargetGroups::of`]).
    pub fn with_left(self, left: &Left, samples: &[Sample], corrected: &[f64], groups: &TargetGroups) -> Self {
        let unseen = left.unseen_peak_deg();
        let spread = crate::correction::noise_sd(samples, corrected, groups).map_or(0.0, |sigma| {
            let m = samples.len().max(1) as f64;
            sigma * 19f64.ln() / (2.0 * (2.0 * m).ln()).sqrt()
        });
        Prediction {
            corrected_peak_deg: self.in_sample_corrected_peak_deg + unseen + spread,
            unseen_between_targets_deg: unseen,
            peak_spread_deg: spread,
            ..self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(kind: LeftKind, bin: f64, candidates: Vec<f64>) -> LeftLine {
        LeftLine {
            observed_cycles: bin,
            amplitude_deg: 0.01,
            phase_deg: 30.0,
            noise_sd_deg: 0.0,
            kind,
            candidates,
            carried_cycles: None,
            why: String::new(),
        }
    }

    #[test]
    fn a_possible_alias_agrees_at_the_targets_and_differs_between_them() {
        let left = Left {
            lines: vec![line(LeftKind::MaybeAlias, 16.0, vec![16.0, 20.0, 52.0])],
            points: 36,
            start_deg: 0.0,
            worst: None,
            second_order_deg: 0.0,
            folds: Vec::new(),
        };
        for f in [20.0, 52.0] {
            for j in 0..36 {
                let t = 10.0 * j as f64;
                assert!(left.at(&[f], t).abs() < 1e-12, "{f} at {t}: {}", left.at(&[f], t));
            }
            let mid = left.values(&[f], &Left::readouts()).iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(mid > 1.9 * 0.01 && mid <= 2.0 * 0.01 + 1e-12, "{mid}");
        }
        assert_eq!(left.at(&[16.0], 5.0), 0.0, "where it is seen, nothing is left");
    }

    #[test]
    fn a_line_not_carried_is_left_whole_at_its_true_frequency() {
        let left = Left {
            lines: vec![line(LeftKind::NotCarried, 4.0, vec![20.0, 100.0])],
            points: 24,
            start_deg: 0.0,
            worst: None,
            second_order_deg: 0.0,
            folds: Vec::new(),
        };
        for f in [20.0, 100.0] {
            for j in 0..24 {
                let t = 15.0 * j as f64;
                let seen = 0.01 * (4.0 * t + 30.0f64).to_radians().sin();
                assert!((left.at(&[f], t) - seen).abs() < 1e-12, "at the targets it is what was seen");
            }
        }
        let v = left.values(&[20.0], &Left::readouts());
        let rms = (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        assert!((rms - 0.01 / 2f64.sqrt()).abs() < 1e-4, "{rms}");
    }

    #[test]
    fn hypotheses_enumerate_the_largest_lines_first_and_stop_at_the_cap() {
        let mut lines = Vec::new();
        for i in 0..6 {
            lines.push(line(LeftKind::NotCarried, 4.0 + i as f64, vec![1.0, 2.0, 3.0]));
        }
        let left = Left { lines, points: 24, start_deg: 0.0, worst: None, second_order_deg: 0.0, folds: Vec::new() };
        let h = left.hypotheses();
        assert!(h.len() <= MAX_HYPOTHESES && h.len() >= 27, "{}", h.len());
        assert!(h.iter().all(|x| x.len() == 6));
        assert!(h.iter().all(|x| x[5] == 1.0), "the smallest line keeps its first candidate");
    }
}
