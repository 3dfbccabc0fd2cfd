//! A positioner's life (issue 22): the surveys of one asset measured again
//! and again, what changed between them ([`survey_modelgap::compare`]),
//! whether the table in force still holds, and the history
//! ([`history`]) and the recalibration loop ([`check`]) built on it.
//!
//! A survey is measured here as `survey process` would process it: its
//! samples around the axis fitted again from every SMR position (tracker
//! surveys), corrected for drift when it asked for that, processed without a
//! recipe with its stored model's design and its check points (quietly: no
//! notes on stderr), and
//! its table's uncertainty budgeted. The table of a survey, applied to
//! another, is this table.

pub mod cache;
pub mod check;
mod codec;
pub mod control;
pub mod due;
pub mod history;
pub mod interval;
#[cfg(test)]
mod rates_tests;
#[cfg(test)]
mod year_sim_tests;
#[cfg(test)]
mod year_tests;

pub use cache::lines_seen;

use crate::load::{Axis, load};
use serde_json::{Value, json};
use std::borrow::Cow;
use survey_modelgap::ReferenceInfo;
use survey_modelgap::compare::seen::Unseen;
use survey_modelgap::compare::{
    CompareError, CompareOptions, Comparison, Decision, TableCheck, compare, decide, table_on,
};
use survey_processing::Sample;
use survey_processing::iso230::{Iso230, iso230_2};
use survey_processing::model::Design;
use survey_processing::table::CorrectionTable;
use survey_store::Store;
use survey_store::survey::{SurveyRecord, SurveyRef, SurveySource};
use survey_tables::pipeline::{Processed, process_with_checks};
use survey_tables::recipe::LineAction;

/// The false-alarm rate every comparison is made at.
pub const FALSE_ALARM_RATE: f64 = 0.01;

/// One survey, measured for comparison: its samples and what a comparison
/// takes of its processing (the table and the lines it corrects), not the
/// processing itself.
#[derive(Debug)]
pub struct Measured {
    /// The survey.
    pub survey: SurveyRecord,
    /// Its samples as processed (around the refitted axis, drift corrected).
    pub samples: Vec<Sample>,
    /// Its processing's table, or why there is none.
    pub table: Result<CorrectionTable, String>,
    /// The lines its table corrects, largest first.
    pub lines: Vec<MainLine>,
    /// The lines its own targets cannot place ([`Measured::lines_in_doubt`]).
    pub doubt: Vec<(f64, Vec<f64>)>,
    /// Every frequency its design predicts (gear passes, tooth meshes,
    /// their harmonics and sidebands, 1 and 2), cycles/rev: a check's grid
    /// keeps them off its lines' bins.
    pub design_frequencies: Vec<f64>,
    /// Its ISO 230-2 figures, when it allows them.
    pub iso: Option<Iso230>,
    /// Its table's expanded uncertainty `U` (k = 2), degrees.
    pub table_u_deg: Option<f64>,
    /// `U` beside the reference's systematic part (`sqrt(U^2 - (k
    /// u_sys)^2)`), degrees: what a later survey with the same reference can
    /// hold the table to, its reference's own error being in both alike.
    pub table_u_beside_reference_deg: Option<f64>,
    /// The once-per-revolution standard error of its tracker's axis, degrees (0 otherwise).
    pub axis_se_deg: f64,
    /// Its axis's total radial and axial error motions (a tracker survey's).
    pub motions: Option<MotionTotals>,
}

/// The error motions of two surveys side by side (`compare --json`): each
/// survey's totals, and where both are above the detection limit, the
/// change with its `U` (the two surveys' in quadrature: the same tracker's
/// error may be in both, so this is conservative) and whether it exceeds it.
fn motions_change(a: Option<&MotionTotals>, b: Option<&MotionTotals>) -> Value {
    let change = |x: Option<f64>, y: Option<f64>, ux: f64, uy: f64| match (x, y) {
        (Some(x), Some(y)) => {
            let u = ux.hypot(uy);
            json!({"change": y - x, "u": u, "significant": (y - x).abs() > u})
        }
        _ => Value::Null,
    };
    // A total the SMRs separate (where both surveys have it).
    let separated = |of: fn(&MotionTotals) -> Option<Total>| match (a.and_then(of), b.and_then(of)) {
        (Some(a), Some(b)) => change(a.total, b.total, a.u, b.u),
        _ => Value::Null,
    };
    json!({
        "a": a.map(MotionTotals::json),
        "b": b.map(MotionTotals::json),
        "radial_total_change_um": match (a, b) {
            (Some(a), Some(b)) => change(a.radial_um, b.radial_um, a.u_radial_um, b.u_radial_um),
            _ => Value::Null,
        },
        "axial_total_change_um": match (a, b) {
            (Some(a), Some(b)) => change(a.axial_um, b.axial_um, a.u_axial_um, b.u_axial_um),
            _ => Value::Null,
        },
        "axial_on_axis_total_change_um": separated(|m| m.axial_on_axis_um),
        "tilt_total_change_urad": separated(|m| m.tilt_urad),
        "tilt_across_total_change_urad": separated(|m| m.tilt_across_urad),
    })
}

/// A survey's total radial and axial error motions (ISO 230-7), as a history
/// shows them across surveys: a growing wobble (a worn bearing) seen like a
/// growing line. A figure below the detection limit is `None`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionTotals {
    /// Total radial error motion, um.
    pub radial_um: Option<f64>,
    /// Total axial (face) error motion, um.
    pub axial_um: Option<f64>,
    /// The `U` (k = 2) of the radial and the axial total, um.
    pub u_radial_um: f64,
    pub u_axial_um: f64,
    /// The detection limit, um.
    pub limit_um: f64,
    /// The total axial error motion on the axis (um), the total tilt in the
    /// first SMR's radial direction (urad) and the total tilt at 90 deg to
    /// it (urad, three or more SMRs at spread phases), where the SMRs
    /// separate them: each its total (`None` below its detection limit),
    /// `U` and detection limit.
    pub axial_on_axis_um: Option<Total>,
    pub tilt_urad: Option<Total>,
    pub tilt_across_urad: Option<Total>,
}

/// One total error motion as a history keeps it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Total {
    pub total: Option<f64>,
    pub u: f64,
    pub limit: f64,
}

impl Total {
    fn of(b: &survey_motions::Block) -> Self {
        Total { total: b.total, u: b.u_total, limit: b.detection_limit }
    }

    fn json(&self) -> serde_json::Value {
        serde_json::json!({"total": self.total, "u": self.u, "below_detection_limit": self.total.is_none(),
            "detection_limit": self.limit})
    }
}

impl MotionTotals {
    /// The totals of `m`.
    pub fn of(m: &survey_motions::ErrorMotions) -> Self {
        MotionTotals {
            radial_um: m.radial_um.total,
            axial_um: m.axial_um.total,
            u_radial_um: m.radial_um.u_total,
            u_axial_um: m.axial_um.u_total,
            limit_um: m.detection_limit_um,
            axial_on_axis_um: m.axial_on_axis_um.as_ref().map(Total::of),
            tilt_urad: m.tilt_urad.as_ref().map(|t| Total::of(&t.block)),
            tilt_across_urad: m.tilt_across_urad.as_ref().map(|t| Total::of(&t.block)),
        }
    }

    /// The history's keys: `radial_um` and `axial_um`, each `{"total", "u",
    /// "below_detection_limit"}`; `axial_on_axis_um`, `tilt_urad` and
    /// `tilt_across_urad` the same where the SMRs separate them, else `null`.
    pub fn json(&self) -> serde_json::Value {
        let one = |v: Option<f64>, u: f64| Total { total: v, u, limit: self.limit_um }.json();
        serde_json::json!({"radial_um": one(self.radial_um, self.u_radial_um), "axial_um": one(self.axial_um, self.u_axial_um),
            "axial_on_axis_um": self.axial_on_axis_um.map(|t| t.json()), "tilt_urad": self.tilt_urad.map(|t| t.json()),
            "tilt_across_urad": self.tilt_across_urad.map(|t| t.json())})
    }
}

/// A main line of a survey's table: a line the table corrects.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MainLine {
    /// Its true frequency, cycles per revolution.
    pub cycles_per_rev: f64,
    /// Its amplitude, degrees.
    pub amplitude_deg: f64,
    /// Its phase, degrees (`A sin(k theta + phase)`).
    pub phase_deg: f64,
}

/// The lines the table of `p` corrects, largest first.
fn main_lines(p: &Processed) -> Vec<MainLine> {
    let mut lines: Vec<MainLine> = p
        .analysis
        .lines
        .iter()
        .filter_map(|l| {
            let d = p.decisions.lines.iter().find(|d| d.significant && d.cycles_per_rev == l.cycles_per_rev)?;
            matches!(d.action, LineAction::Kept | LineAction::Relocated).then(|| MainLine {
                cycles_per_rev: d.true_cycles_per_rev,
                amplitude_deg: l.amplitude_deg,
                phase_deg: l.true_phase_deg,
            })
        })
        .collect();
    lines.sort_by(|a, b| b.amplitude_deg.total_cmp(&a.amplitude_deg));
    lines
}

impl Measured {
    /// The lines the table corrects, largest first.
    pub fn main_lines(&self) -> &[MainLine] {
        &self.lines
    }

    /// The lines its own targets cannot place: seen at a bin that more than
    /// one frequency could alias onto (an unknown design's line that may be
    /// an alias, two design harmonics at one bin), by the bin they were seen
    /// at, with the candidates. On another grid of targets the true line
    /// shows at another bin: such a line compares only on the same grid.
    pub fn lines_in_doubt(&self) -> &[(f64, Vec<f64>)] {
        &self.doubt
    }

    /// `calibration`, `check`, `verification` or `corrected`.
    pub fn kind(&self) -> &'static str {
        kind(&self.survey)
    }

    /// Whether it measured the positioner as it is (a calibration or a
    /// check), not with a table applied (a verification, a survey of the
    /// corrected axis kept on purpose): only those compare.
    pub fn is_native(&self) -> bool {
        !matches!(self.kind(), "verification" | "corrected")
    }
}

/// `calibration`, `check`, `verification` or `corrected` (the corrected
/// axis measured on purpose: `--correction keep`).
pub fn kind(s: &SurveyRecord) -> &'static str {
    match (&s.check_of, &s.source) {
        (Some(_), _) => "check",
        (None, SurveySource::Verification) => "verification",
        _ if s.measured_corrected() => "corrected",
        _ => "calibration",
    }
}

/// Measure the survey `r` of `store` (see the module documentation).
pub async fn measure(store: &Store, r: SurveyRef) -> anyhow::Result<Measured> {
    let mut loaded = load(store, Some(r), Axis::Refitted).await?;
    // The samples as analysed, taken over (not copied) when no drift
    // correction makes new ones.
    let samples = match loaded.analysed() {
        Cow::Owned(corrected) => corrected,
        Cow::Borrowed(_) => std::mem::take(&mut loaded.samples),
    };
    let design = loaded.survey.model.as_ref().map_or_else(Design::default, |m| m.design.clone());
    // With its check points, as `survey process` takes them in.
    let processed = process_with_checks(&samples, &design, None, None, &loaded.checks_corrected(&loaded.checks))
        .map_err(|e| e.to_string());
    let inputs = loaded.uncertainty_inputs();
    let u = processed.as_ref().ok().map(|p| survey_tables::uncertainty::uncertainty(p, &samples, &inputs));
    let table_u_deg = u.as_ref().map(|u| u.table_u_deg);
    let table_u_beside_reference_deg = u.as_ref().map(|u| {
        let shared = u.reference_systematic_u_deg().unwrap_or(0.0) * u.k;
        (u.table_u_deg.powi(2) - shared * shared).max(0.0).sqrt()
    });
    let axis_se_deg = match loaded.reference_info() {
        ReferenceInfo::Tracker { axis_se_deg, .. } => axis_se_deg,
        _ => 0.0,
    };
    let motions = loaded.refit.as_ref().and_then(|r| r.error_motions.as_ref()).map(MotionTotals::of);
    let lines = processed.as_ref().map_or_else(|_| Vec::new(), main_lines);
    let doubt = processed.as_ref().map_or_else(
        |_| Vec::new(),
        |p| {
            let doubtful = p.left.lines.iter().filter(|l| l.candidates.len() > 1);
            doubtful.map(|l| (l.observed_cycles, l.candidates.clone())).collect()
        },
    );
    let table = processed.map(|p| p.built.table);
    let options = survey_processing::analysis::AnalysisOptions::default();
    let design_frequencies =
        survey_processing::analysis::design_candidates(&design, &options).iter().map(|c| c.cycles_per_rev).collect();
    Ok(Measured {
        iso: iso230_2(&samples).ok(),
        survey: loaded.survey,
        samples,
        table,
        lines,
        doubt,
        design_frequencies,
        table_u_deg,
        motions,
        table_u_beside_reference_deg,
        axis_se_deg,
    })
}

/// What changed from `a` to `b`, and whether the table of `a` holds on `b`.
#[derive(Debug)]
pub struct Compared {
    /// The tests.
    pub comparison: Comparison,
    /// The table of `a` applied to `b`, when `a` could be processed.
    pub table_of_a_on_b: Option<TableCheck>,
    /// Recalibrate, and why.
    pub decision: Decision,
}

/// Compare `a` (the earlier, or the calibration in force) with `b`: every
/// main line of either (and the once-per-revolution line, a mounting's),
/// the backlash and the mean error map; the table of `a` applied to `b`.
pub fn compared(a: &Measured, b: &Measured) -> anyhow::Result<Compared> {
    compared_placing(a, b, &[])
}

/// [`compared`], where a line either survey cannot place may also be placed
/// by one of `placing` (an earlier check of the same table on a denser grid,
/// [`placed_by`]).
pub fn compared_placing(a: &Measured, b: &Measured, placing: &[Measured]) -> anyhow::Result<Compared> {
    comparable(a, b)?;
    tested(a, b, placing).map_err(|e| not_comparable(a.survey.id, b.survey.id, &e.to_string()))
}

/// Why survey `a` cannot be compared with survey `b` (bad input): `why`,
/// the comparison's own reason.
pub(crate) fn not_comparable(a: i64, b: i64, why: &str) -> anyhow::Error {
    crate::error::bad_input(format!("survey {a} cannot be compared with survey {b}: {why}"))
}

/// `a` and `b` are surveys that compare: of one asset, neither a verification.
fn comparable(a: &Measured, b: &Measured) -> anyhow::Result<()> {
    if a.survey.asset != b.survey.asset {
        return Err(crate::error::bad_input(format!(
            "survey {} belongs to the asset {} and survey {} to {}: only surveys of one asset compare",
            a.survey.id, a.survey.asset, b.survey.id, b.survey.asset
        )));
    }
    // A verification measured the axis with a table applied: against a
    // native survey every line the table corrects would read as a change.
    if let Some(v) = [a, b].into_iter().find(|m| !m.is_native()) {
        let what = match &v.survey.verification {
            Some(x) => format!("a verification (measured with the table of survey {} applied)", x.verifies_survey),
            None if v.kind() == "verification" => "a verification (measured with the table applied)".into(),
            None => "a survey of the corrected axis (the correction kept on: --correction keep)".into(),
        };
        return Err(crate::error::bad_input(format!(
            "survey {} is {what}: it measures the corrected axis; compare calibrations and checks, which measure the \
             positioner as it is",
            v.survey.id
        )));
    }
    Ok(())
}

/// The tests of `a` against `b` (surveys that compare), or why the
/// comparison could not be made.
fn tested(a: &Measured, b: &Measured, placing: &[Measured]) -> Result<Compared, CompareError> {
    let lines: Vec<f64> =
        std::iter::once(1.0).chain(a.main_lines().iter().chain(b.main_lines()).map(|l| l.cycles_per_rev)).collect();
    // A line either survey's targets cannot place compares only on one grid.
    let doubt = in_doubt_across_grids(a, b, placing);
    let lines: Vec<f64> = lines.into_iter().filter(|k| !doubt.iter().any(|u| u.cycles_per_rev == *k)).collect();
    let opts =
        CompareOptions { false_alarm_rate: FALSE_ALARM_RATE, lines, axis_se_deg: [a.axis_se_deg, b.axis_se_deg] };
    let mut comparison = compare(&a.samples, &b.samples, &opts)?;
    for u in doubt {
        comparison.lines_not_tested.push(u.cycles_per_rev);
        comparison.not_estimable.push(u);
    }
    // Both surveys measured with the same reference set up in the same place
    // (the axis where the tracker located it, within 1 mm and 1 mrad): its
    // own systematic error is in both alike, and the table is held to its U
    // beside it; a reference set up anew adds the difference of its errors
    // at two places, and the table is held to its whole U.
    let held_to =
        if same_reference_setup(&a.survey, &b.survey) { a.table_u_beside_reference_deg } else { a.table_u_deg };
    let table_of_a_on_b = match (&a.table, held_to) {
        (Ok(table), Some(u)) => {
            table_on(table, u, &a.samples, &b.samples, FALSE_ALARM_RATE, [a.axis_se_deg, b.axis_se_deg])
        }
        _ => None,
    };
    let decision = decide(&comparison, table_of_a_on_b.as_ref(), asset_tolerance(a));
    Ok(Compared { comparison, table_of_a_on_b, decision })
}

/// Whether two tracker surveys located the axis at the same place in the
/// tracker's frame (centres within 1 mm, normals within 1 mrad): the same
/// tracker set up in the same place, whose own error is the same in both.
fn same_reference_setup(a: &SurveyRecord, b: &SurveyRecord) -> bool {
    let (Some(x), Some(y)) = (&a.axis, &b.axis) else { return false };
    let moved = x.center_mm.iter().zip(&y.center_mm).map(|(p, q)| (p - q).powi(2)).sum::<f64>().sqrt();
    let cos = x.normal.iter().zip(&y.normal).map(|(p, q)| p * q).sum::<f64>();
    moved <= 1.0 && cos >= (1e-3f64).cos()
}

/// The tolerance stated for the asset of `a` (the calibration in force, or
/// the earlier survey): its configuration's `[certificate] tolerance_deg`.
fn asset_tolerance(a: &Measured) -> Option<f64> {
    match &a.survey.setup {
        survey_store::survey::Setup::Configured(c) => c.config.certificate.as_ref().and_then(|c| c.tolerance_deg),
        _ => None,
    }
}

/// The distinct targets of `m`, in millionths of a degree.
fn grid(m: &Measured) -> Vec<u64> {
    let mut t: Vec<u64> = m.samples.iter().map(|s| (s.target_deg * 1e6).round() as u64).collect();
    t.sort_unstable();
    t.dedup();
    t
}

/// Whether `other` (whose distinct targets are `targets`) places the line
/// another survey saw at `bin` and could not place among `candidates`:
/// `other` corrects a line at `bin` that its own targets place, and its
/// targets (a full circle) would have shown every other candidate at its
/// own bin (below their Nyquist bin), where it has no line. The line is
/// then the one at `bin` (a calibration's 120 targets place the 3
/// cycles/rev line a check of 36 cannot tell from 33 and 39: without this
/// every later check of a table with such a line went undecided, through
/// the simulators, `year_sim_tests`).
fn placed_by(other: &Measured, targets: &[u64], bin: f64, candidates: &[f64]) -> bool {
    let n = targets.len();
    let full_circle = n >= 2 && targets[0] == 0 && ((targets[1] as f64) * 1e-6 * n as f64 - 360.0).abs() < 1e-3;
    let has = |k: f64| other.main_lines().iter().any(|l| l.cycles_per_rev == k);
    full_circle
        && has(bin)
        && !other.lines_in_doubt().iter().any(|(b, _)| *b == bin)
        && candidates.iter().filter(|c| **c != bin).all(|&c| c < n as f64 / 2.0 && !has(c))
}

/// The lines of `a` or `b` that its own targets cannot place
/// ([`Measured::lines_in_doubt`]), when the two surveys' targets differ:
/// seen at one bin on one grid and at another on the other, their phasors do
/// not compare (the table's check judges what they leave).
fn in_doubt_across_grids(a: &Measured, b: &Measured, placing: &[Measured]) -> Vec<Unseen> {
    if grid(a) == grid(b) {
        return Vec::new();
    }
    let mut out: Vec<Unseen> = Vec::new();
    for (m, other, name) in [(a, b, "A"), (b, a, "B")] {
        for (bin, candidates) in m.lines_in_doubt() {
            let placed = |p: &Measured| placed_by(p, &grid(p), *bin, candidates);
            if out.iter().any(|u| u.cycles_per_rev == *bin) || placed(other) || placing.iter().any(placed) {
                continue;
            }
            let c: Vec<String> = candidates.iter().map(|c| format!("{c}")).collect();
            out.push(Unseen {
                cycles_per_rev: *bin,
                why: format!(
                    "survey {name}'s targets cannot place the line seen at bin {bin} (it may be {} cycles/rev): on \
                     the other survey's targets it shows at another bin, so the two do not compare line for line; \
                     the table's check judges what it leaves",
                    c.join(" or ")
                ),
            });
        }
    }
    out
}

impl Compared {
    /// The contract's change document (`from`, `to`, `verdict`, `lines`)
    /// and the rest of the tests.
    pub fn change_json(&self, a: &Measured, b: &Measured) -> Value {
        let c = &self.comparison;
        json!({
            "from": a.survey.id,
            "to": b.survey.id,
            "from_uid": a.survey.uid,
            "to_uid": b.survey.uid,
            "verdict": c.verdict.as_str(),
            "lines": c.lines,
            "lines_not_tested": c.lines_not_tested,
            "not_estimable": c.not_estimable,
            "backlash": c.backlash,
            "map": c.map,
            "false_alarm_rate": c.false_alarm_rate,
            "per_test_rate": c.per_test_rate,
            "repeatability_deg": c.repeatability_deg,
            "recalibrate": self.decision.recalibrate,
            "reason": self.decision.reason,
        })
    }

    /// `survey compare --json`: the change, the table of A on B and the decision.
    pub fn json(&self, a: &Measured, b: &Measured) -> Value {
        let mut doc = self.change_json(a, b);
        doc["asset"] = a.survey.asset.clone().into();
        doc["table_of_a_on_b"] = match &self.table_of_a_on_b {
            Some(t) => serde_json::to_value(t).unwrap_or_default(),
            None => json!({
                "residual_peak_deg": null, "stated_u_deg": null, "holds": null,
                "why": a.table.as_ref().err().cloned().unwrap_or_else(|| "no repeatability in B".into()),
            }),
        };
        doc["error_motions"] = motions_change(a.motions.as_ref(), b.motions.as_ref());
        doc
    }

    /// For people.
    pub fn text(&self, a: &Measured, b: &Measured) -> String {
        let c = &self.comparison;
        let mut s = format!(
            "survey {} -> survey {} (asset {}): {}\n",
            a.survey.id,
            b.survey.id,
            a.survey.asset,
            c.verdict.as_str()
        );
        s += &format!(
            "  {:>10}  {:>12}  {:>12}  {:>11}  {:>11}  {}\n",
            "cycles/rev", "from, deg", "to, deg", "change, deg", "allows, deg", "changed"
        );
        for l in &c.lines {
            s += &format!(
                "  {:>10}  {:>12.4e}  {:>12.4e}  {:>11.2e}  {:>11.2e}  {}\n",
                l.cycles_per_rev,
                l.amplitude_from_deg,
                l.amplitude_to_deg,
                l.change_deg,
                l.change_u_deg,
                if l.significant { "yes" } else { "no" }
            );
        }
        if let Some(b) = &c.backlash {
            s += &format!(
                "  {:>10}  {:>12.4e}  {:>12.4e}  {:>11.2e}  {:>11.2e}  {}\n",
                "backlash",
                b.from_deg,
                b.to_deg,
                (b.to_deg - b.from_deg).abs(),
                b.change_u_deg,
                if b.significant { "yes" } else { "no" }
            );
        }
        if let Some(m) = &c.map {
            s += &format!(
                "  mean error map: {} cells, change {:.2e} deg rms, F = {:.2} (p = {:.2e}): {}\n",
                m.cells,
                m.rms_change_deg,
                m.statistic,
                m.p_value,
                if m.significant { "changed" } else { "unchanged" }
            );
        }
        for u in &c.not_estimable {
            s += &format!("  {} cycles/rev: not estimable: {}\n", u.cycles_per_rev, u.why);
        }
        s += &format!("  false-alarm rate {} ({:.2e} per test)\n", c.false_alarm_rate, c.per_test_rate);
        match &self.table_of_a_on_b {
            Some(t) => {
                let predicted =
                    t.predicted_peak_deg.map_or(String::new(), |p| format!(" (on survey {}: {p:.2e})", a.survey.id));
                s += &format!(
                    "table of survey {} on survey {}: leaves {:.2e} deg at most{predicted}, {:.2e} rms; stated U {:.2e} \
                     deg; {} of {} cells beyond it ({} allowed): {}\n",
                    a.survey.id,
                    b.survey.id,
                    t.residual_peak_deg,
                    t.residual_rms_deg,
                    t.stated_u_deg,
                    t.cells_outside,
                    t.cells,
                    t.allowed_outside,
                    if t.holds { "holds" } else { "does not hold" }
                );
            }
            None => s += &format!("table of survey {}: none to apply\n", a.survey.id),
        }
        s += &format!(
            "recalibrate: {}: {}\n",
            if self.decision.recalibrate { "yes" } else { "no" },
            self.decision.reason
        );
        s
    }
}
