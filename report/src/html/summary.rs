//! The summary: what a customer reads first, each figure with the
//! uncertainty that belongs to it, and the verdict against a tolerance
//! ([`crate::conformity`]) when one is given.

use super::{Page, Section};
use crate::conformity::{self, Decision};
use crate::page::{self, escape};
use crate::rounding;
use survey_processing::Sample;
use survey_processing::iso230::iso230_2;

/// The section: the figures, their uncertainties, the verdict.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let (d, units) = (p.d, p.units);
    let reference_u = p.cert.reference_uncertainty_deg.as_ref().map(|u| u.value);
    let measured_u = conformity::accuracy_u_deg(reference_u, d.reference_systematic_u_deg, d.axis_u_deg);
    // ILAC-P14: U to two significant digits at most, the figure to U's last decimal place.
    let row = |what: String, value: f64, u: Option<f64>, whose: &str| -> Vec<String> {
        let (v, u) = rounding::show(units, value, u);
        vec![what, v, u.map_or_else(|| "not known".to_string(), |u| u + whose)]
    };
    let mut rows: Vec<Vec<String>> = Vec::new();
    if let Ok(iso) = &p.iso {
        rows.push(row("ISO 230-2 accuracy A, as measured".into(), iso.a, measured_u, ""));
        // R has no U of its own: to the place of the U beside it (ILAC-P14: one rounding).
        rows.push(vec!["ISO 230-2 repeatability R".into(), rounding::show(units, iso.r, measured_u).0, "-".into()]);
    }
    let table_u = d.uncertainty.as_ref().map(|b| b.table_u_deg);
    if let Ok(processed) = &d.processed {
        let prediction = &processed.prediction;
        rows.push(row(
            "native peak error ± (the largest error of any sample from the mean, no correction)".into(),
            prediction.native_peak_deg,
            measured_u,
            "",
        ));
        rows.push(row(
            "corrected peak error ±, predicted from this survey (the same, the table applied)".into(),
            prediction.corrected_peak_deg,
            table_u,
            " (the table's)",
        ));
        if let Some(floor) = processed.floor.deg {
            rows.push(vec![
                format!(
                    "repeatability floor: {}; a scale of the scatter no table removes, not a bound on the peak \
                     (R is the worst target's ± 2 s band, the peak one sample's error)",
                    escape(&units.text(&processed.floor.what))
                ),
                units.show(floor),
                "-".into(),
            ]);
        }
        let own = (d.survey.id, d.samples.as_slice());
        rows.extend(super::verification::verdict_rows(
            processed,
            (table_u, d.reference_systematic_u_deg.map(|u| survey_tables::uncertainty::K * u)),
            d.verification.as_ref(),
            own,
            units,
        ));
    }
    let corrected_a =
        d.verification.as_ref().and_then(|v| iso230_2(v.corrected(&d.samples)).ok().map(|iso| (v, iso.a)));
    if let Some(v) = &d.verification {
        let errors: Vec<f64> = v.corrected(&d.samples).iter().map(Sample::error_deg).collect();
        let peak = survey_tables::correction::ErrorFigures::of(&errors, None).peak_deg;
        rows.push(row(
            format!("corrected peak error ±, measured (survey {})", v.verification_id),
            peak,
            measured_u,
            "",
        ));
    }
    if let Some((v, a)) = corrected_a {
        rows.push(row(
            format!("ISO 230-2 accuracy A, corrected, measured (survey {})", v.verification_id),
            a,
            measured_u,
            "",
        ));
    }
    let mut body = String::new();
    if let Some(tolerance) = &p.cert.tolerance_deg {
        let (what, figure) = match corrected_a {
            Some((v, a)) => (
                format!(
                    "the corrected accuracy A per ISO 230-2, measured by verification survey {} with the table of \
                     survey {} applied",
                    v.verification_id, v.native_id
                ),
                Some(a),
            ),
            None => (
                "the native accuracy A per ISO 230-2 of this survey (no correction applied)".to_string(),
                p.iso.as_ref().ok().map(|iso| iso.a),
            ),
        };
        body += &verdict(figure, measured_u, tolerance.value, &what, p);
    }
    body += &page::table(
        "tbl-summary",
        &["figure", "value", "expanded uncertainty U (k = 2, coverage probability about 95 %)"],
        &rows,
    );
    let measured = match &d.environment {
        survey_lab::environment::Environment::Tracker(m) => Some(m.temperature_c),
        _ => None,
    };
    let environment = match (&p.cert.temperature_c, measured) {
        (_, Some(t)) => {
            format!("the environment's contribution is not included (the air measured {:.2} to {:.2} °C)", t.min, t.max)
        }
        (Some(t), None) => format!(
            "the environment's contribution is not included (the air temperature was stated as {:.1} °C, not \
             measured)",
            t.value
        ),
        (None, None) => "the environment's contribution is not included (no air temperature was measured)".to_string(),
    };
    body += &format!(
        "<p class=\"note\">U of a measured figure: k √(u<sub>ref</sub>² + u<sub>sys</sub>² + u<sub>axis</sub>²), the \
         reference instrument's stated standard uncertainty of one angle{}, its systematic part at an angle (a \
         tracker's own error from its MPE, the same in every run{}) and, with a tracker, the located axis's{} \
         (ISO 230-2 Annex A's measuring instrument and set-up); the scatter over the runs is already inside A (its \
         ±2 s bands), and {environment}. U of the predicted corrected peak is the table's, as a correction (section \
         Uncertainty of the table). The figures' {}. {}</p>\n",
        reference_u.map_or(" (not stated: no U)".to_string(), |u| format!(" ({})", units.show(u))),
        d.reference_systematic_u_deg.map_or(String::new(), |u| format!(": {}", units.show(u))),
        d.axis_u_deg.map_or(String::new(), |u| format!(" ({})", units.show(u))),
        escape(d.axis.text()),
        escape(rounding::COVERAGE),
    );
    Ok(Some(Section { id: "summary", title: "Summary".into(), new_page: false, body }))
}

/// The verdict's paragraph and the rule it follows.
fn verdict(figure: Option<f64>, u: Option<f64>, tolerance: f64, what: &str, p: &Page<'_>) -> String {
    let units = p.units;
    let (class, text) = match figure {
        None => ("", format!("Verdict: not decidable: there is no ISO 230-2 accuracy A to judge ({what}).")),
        Some(a) => {
            let decision = conformity::decide(a, u, tolerance);
            // Each figure as P14 rounds it beside U.
            let at_u = |v: f64| rounding::show(units, v, u).0;
            let why = match (decision, u) {
                (_, None) => "its uncertainty is not known: state the reference's uncertainty \
                              (--reference-uncertainty or [certificate] reference_uncertainty_deg)"
                    .to_string(),
                (Decision::Pass, Some(u)) => format!("A + U = {} ≤ {}", at_u(a + u), units.show(tolerance)),
                (Decision::Fail, Some(u)) => format!("A − U = {} > {}", at_u(a - u), units.show(tolerance)),
                (Decision::NotDecidable, Some(u)) => {
                    format!("the tolerance lies between A − U = {} and A + U = {}", at_u(a - u), at_u(a + u))
                }
            };
            let class = match decision {
                Decision::Pass => " pass",
                Decision::Fail => " fail",
                Decision::NotDecidable => "",
            };
            let u_text = u.map_or("U not known".to_string(), |u| format!("U = {} (k = 2)", rounding::show_u(units, u)));
            (
                class,
                format!(
                    "Verdict against the tolerance {}: {}. A = {}, {u_text}, {why}. Judged: {what}.",
                    units.show(tolerance),
                    decision.word().to_uppercase(),
                    at_u(a),
                ),
            )
        }
    };
    format!("<p class=\"verdict{class}\" id=\"verdict\">{}</p>\n{}", escape(&text), decision_rule())
}

/// The decision rule, stated with every verdict against a tolerance.
pub fn decision_rule() -> String {
    format!("<p class=\"note\" id=\"decision-rule\">{}</p>\n", escape(conformity::RULE))
}
