//! The folds of a survey ([`crate::left::folds`]) as check points measure
//! them.

use super::{Resolution, consistent, noise_var};
use crate::left::folds::{Fold, Measured, carried_under, fit, phase_at};
use crate::left::{Left, LeftKind, LeftLine};
use survey_processing::table::CorrectionTable;
use survey_processing::types::Sample;

/// `left` with its folds measured by `checks` (the table `table` applied to
/// them: `d = error - table`), and what was measured, a resolution a bin:
/// fitted jointly with the lines still in doubt at their best hypothesis
/// ([`fit`]); when that explains the check points down to their noise
/// (the test of [`crate::resolve::decide`]), each fold measured is a line
/// the table leaves ([`LeftKind::Folded`]: its size and phase, its
/// components' standard deviation from the check points' noise) in place
/// of the bin's doubt; a bin with a fold the points cannot resolve stays
/// in doubt. When it does not (another line the design does not name), the
/// folds are measured all the same, their standard deviations from the
/// residual's own variance, and the residual's rms beyond the noise is
/// returned for `U` (which is also at least what the check points measure
/// the table leaves).
pub fn measure_folds(mut left: Left, table: &CorrectionTable, checks: &[Sample]) -> Folds {
    let none = |left| Folds { left, resolutions: Vec::new(), unexplained_deg: None };
    if left.folds.is_empty() || left.points == 0 {
        return none(left);
    }
    let Some((sigma2, noise_dof)) = noise_var(checks, table).filter(|(v, _)| *v > 0.0) else {
        return none(left);
    };
    let d: Vec<(f64, f64)> =
        checks.iter().map(|s| (s.readout_deg, s.error_deg() - table.error_at(s.readout_deg, s.direction))).collect();
    let (n, start) = (left.points as f64, left.start_deg);
    let view = left.for_decision();
    let best = view
        .hypotheses()
        .into_iter()
        .filter_map(|h| {
            let y: Vec<(f64, f64)> = d.iter().map(|&(r, v)| (r, v - view.at(&h, r))).collect();
            fit(&y, &left.folds, &|f: &Fold| carried_under(&view, &h, f), n, start).map(|j| (h, j))
        })
        .min_by(|a, b| a.1.ssr.total_cmp(&b.1.ssr));
    let Some((_, joint)) = best.filter(|(_, j)| j.dof >= 3) else { return none(left) };
    let explained = consistent(joint.ssr, joint.dof, sigma2, noise_dof);
    // The residual's own variance where it is more than the noise's: what
    // no fold and no hypothesis holds widens what is known of each fold (as
    // a regression's residual variance does), and is itself a term of U.
    let residual2 = joint.ssr / joint.dof as f64;
    let scale2 = if explained { sigma2 } else { residual2.max(sigma2) };
    let unexplained_deg = (!explained).then(|| (residual2 - sigma2).max(0.0).sqrt());
    let mut bins: Vec<f64> = left.folds.iter().map(|f| f.observed_cycles).collect();
    bins.sort_by(f64::total_cmp);
    bins.dedup();
    let mut resolutions = Vec::new();
    let mut lines = Vec::new();
    for &b in &bins {
        let at: Vec<(usize, &Fold)> = left.folds.iter().enumerate().filter(|(_, f)| f.observed_cycles == b).collect();
        let got: Vec<(&Fold, &Measured)> =
            at.iter().filter_map(|&(i, f)| joint.measured.iter().find(|m| m.fold == i).map(|m| (f, m))).collect();
        let sd = |m: &Measured| (scale2 * m.unit_var).sqrt();
        let figures: Vec<String> = got
            .iter()
            .map(|(f, m)| format!("{} cycles/rev {:.2e} deg (+/-{:.1e})", f.true_cycles, m.amplitude_deg, sd(m)))
            .collect();
        let unresolved: Vec<String> = at
            .iter()
            .filter(|(i, _)| !joint.measured.iter().any(|m| m.fold == *i))
            .map(|(_, f)| f.true_cycles.to_string())
            .collect();
        let whole = unresolved.is_empty();
        let why = if !explained {
            format!(
                "bin {b}: the {} check points fitted with what the design does not name folded onto it ({}) are \
                 still not explained down to their noise (residual {:.1} sigma^2 over {} degrees of freedom): another \
                 line the design does not name; they measure {} against the residual's own variance, the table \
                 leaves them, and U counts what is unexplained (at least what they measure the table leaves)",
                d.len(),
                at.iter().map(|(_, f)| f.true_cycles.to_string()).collect::<Vec<_>>().join(", "),
                joint.ssr / sigma2,
                joint.dof,
                if figures.is_empty() { "nothing they resolve".to_string() } else { figures.join(", ") },
            )
        } else {
            format!(
                "bin {b}: the {} check points measure what the design does not name folded onto it: {}{}; the table \
                 leaves {}, in U",
                d.len(),
                if figures.is_empty() { "nothing they resolve".to_string() } else { figures.join(", ") },
                if whole {
                    String::new()
                } else {
                    format!(
                        " ({} cycles/rev they cannot tell from their offset and once-per-revolution term)",
                        unresolved.join(", ")
                    )
                },
                if whole { "them" } else { "the bin in doubt" }
            )
        };
        resolutions.push(Resolution {
            observed_cycles: b,
            kind: LeftKind::Folded,
            decided_cycles: None,
            // (What each fold measured is in `why` and in the `folded` lines
            // of `left`: these pairs are hypotheses' residuals.)
            candidates: Vec::new(),
            rest_deg: 0.0,
            explained,
            why,
        });
        // A bin the table does not carry is left whole by it at its
        // candidate already; one with a fold the points do not resolve
        // stays in doubt whole.
        if !whole || at.iter().any(|(_, f)| f.carried_cycles.is_none()) {
            continue;
        }
        for (f, m) in got {
            let c = f.carried_cycles.unwrap_or(b);
            lines.push(LeftLine {
                observed_cycles: b,
                amplitude_deg: m.amplitude_deg,
                phase_deg: phase_at(m.phase_deg, f.true_cycles, b, n, start),
                noise_sd_deg: sd(m),
                kind: LeftKind::Folded,
                candidates: vec![f.true_cycles],
                carried_cycles: Some(c),
                why: format!(
                    "{} cycles/rev ({}) folds onto bin {b} at {} points: the check points measure {:.2e} deg \
                     (+/-{:.1e}); the table, carrying the bin at {c} cycles/rev, leaves it between the targets",
                    f.true_cycles,
                    f.what,
                    left.points,
                    m.amplitude_deg,
                    sd(m)
                ),
            });
        }
        left.lines.retain(|l| !(l.kind == LeftKind::MayFold && l.observed_cycles == b));
    }
    left.lines.extend(lines);
    left.lines.sort_by(|a, b| b.amplitude_deg.total_cmp(&a.amplitude_deg));
    // Made from the survey's targets: the lines' phases are of them.
    let targets: Vec<f64> = (0..left.points).map(|j| start + 360.0 * j as f64 / n).collect();
    left.worst = left.least_favourable(&targets);
    Folds { left, resolutions, unexplained_deg }
}

/// What check points measured of a survey's folds ([`measure_folds`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Folds {
    /// What the table leaves, the folds measured in it.
    pub left: Left,
    /// What was measured, a resolution a bin with folds.
    pub resolutions: Vec<Resolution>,
    /// When the joint fit does not explain the check points: the rms of its
    /// residual beyond their noise, degrees (what no fold and no hypothesis
    /// holds: another line the design does not name).
    pub unexplained_deg: Option<f64>,
}
