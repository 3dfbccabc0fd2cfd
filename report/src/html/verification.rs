//! Native against corrected accuracy on the same scale (the paper's Figures
//! 8 and 9), when a verification survey (`survey run --verify`) measured the
//! positioner with the table applied.

use super::errors;
use super::{Page, Section};
use crate::page::{escape, figure, table};
use crate::plot::padded;
use crate::units::Units;
use survey_processing::Sample;
use survey_processing::errormap::ErrorMap;

/// A calibration survey and the verification of its table. One side is the
/// survey the report is of: its samples are the report's own (`None` here,
/// given to [`Verification::native`] and [`Verification::corrected`]).
#[derive(Debug, Clone)]
pub struct Verification {
    /// The survey the table was made from.
    pub native_id: i64,
    /// Its samples, or `None`: the report's own.
    pub native: Option<Vec<Sample>>,
    /// The verification survey.
    pub verification_id: i64,
    /// Its samples as stored, measured with the table applied, or `None`: the report's own.
    pub corrected: Option<Vec<Sample>>,
    /// Whether the table had forward and reverse columns.
    pub directional: bool,
    /// The highest line the native survey's positioner plausibly has
    /// (`survey_lab::verify::plausible_max`): what the verdict asks the
    /// verification to have been able to see.
    pub plausible_max_cycles: f64,
}

impl Verification {
    /// The native survey's samples; `own` are the report's.
    pub fn native<'a>(&'a self, own: &'a [Sample]) -> &'a [Sample] {
        self.native.as_deref().unwrap_or(own)
    }

    /// The verification survey's samples; `own` are the report's.
    pub fn corrected<'a>(&'a self, own: &'a [Sample]) -> &'a [Sample] {
        self.corrected.as_deref().unwrap_or(own)
    }
}

/// The section: both error figures over one y range, and the figures side
/// by side; `own` are the report's samples.
pub fn section(v: &Verification, own: &[Sample], units: Units) -> anyhow::Result<String> {
    let (native_samples, corrected_samples) = (v.native(own), v.corrected(own));
    let (Ok(native), Ok(corrected)) =
        (ErrorMap::from_samples(native_samples), ErrorMap::from_samples(corrected_samples))
    else {
        return Ok(
            "<p class=\"note\">The verification is incomplete (a target or run is missing): no comparison.</p>\n"
                .into(),
        );
    };
    let (a, b) = (errors::y_extent(&native, units), errors::y_extent(&corrected, units));
    let y = padded(a.0.min(b.0), a.1.max(b.1), 0.06);
    let (native_svg, legend_html) = errors::svg(&native, units, Some(y.clone()))?;
    let (corrected_svg, _) = errors::svg(&corrected, units, Some(y))?;
    let doc = survey_lab::verify::figures(
        v.verification_id,
        v.native_id,
        native_samples,
        corrected_samples,
        None,
        v.directional,
        units,
    )?
    .doc;
    let f = |k: &str| doc[k].as_f64().unwrap_or(f64::NAN);
    let iso = |k: &str| doc["iso230_2"][k].as_f64();
    let native_iso = survey_processing::iso230::iso230_2(native_samples).ok();
    let spacing = |m: &ErrorMap| {
        let t = &m.targets_deg;
        if t.len() > 1 { format!("{} targets, {:.4} to {:.4} deg", t.len(), t[0], t[t.len() - 1]) } else { "-".into() }
    };
    let mut html = figure(
        "fig-native",
        &native_svg,
        "",
        &format!("Native: survey {}, without correction ({}).", v.native_id, spacing(&native)),
    );
    html += &figure(
        "fig-corrected",
        &corrected_svg,
        &legend_html,
        &format!(
            "Corrected: survey {}, measured with the table of survey {} applied in the positioner's feedback path \
             ({}). Same vertical scale as the native figure above.",
            v.verification_id,
            v.native_id,
            spacing(&corrected)
        ),
    );
    let u = units.symbol();
    let rows = vec![
        vec![
            "peak error ± (max |e − mean e|)".into(),
            units.num(f("native_peak_deg")),
            units.num(f("corrected_peak_deg")),
        ],
        vec![
            "systematic peak ± (means over the runs)".into(),
            units.num(f("native_systematic_peak_deg")),
            units.num(f("corrected_systematic_peak_deg")),
        ],
        vec!["ISO 230-2 A".into(), units.opt(native_iso.as_ref().map(|i| i.a)), units.opt(iso("A"))],
        vec!["ISO 230-2 R".into(), units.opt(native_iso.as_ref().map(|i| i.r)), units.opt(iso("R"))],
        vec!["ISO 230-2 B".into(), units.opt(native_iso.as_ref().and_then(|i| i.b)), units.opt(iso("B"))],
    ];
    html += &table("tbl-verification", &["", &format!("native, {u}"), &format!("corrected, {u}")], &rows);
    html += &format!(
        "<p class=\"note\">Improvement of the peak error: {:.1}×. {}</p>\n",
        f("improvement"),
        escape(&placement(&native, &corrected))
    );
    Ok(html)
}

/// Whether the verification measured between the calibration targets.
fn placement(native: &ErrorMap, corrected: &ErrorMap) -> String {
    let on = corrected.targets_deg.iter().filter(|t| native.targets_deg.iter().any(|n| (*t - n).abs() < 1e-6)).count();
    if on == 0 {
        "Every verification target lies between the calibration targets, so the table's interpolation is what was \
         measured."
            .into()
    } else {
        format!(
            "{on} of the {} verification targets are calibration targets (an autocollimator measures only at the \
             polygon's faces): there the table holds what was measured.",
            corrected.targets_deg.len()
        )
    }
}

/// The section, when there is a verification.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    match &p.d.verification {
        Some(v) => {
            Ok(Section::page("verification", "Native and corrected accuracy", section(v, &p.d.samples, p.units)?))
        }
        None => Ok(None),
    }
}

/// The summary's rows (figure, value, its U) on whether the table is a
/// result: the verification's verdict (when `v` verifies the table `p`
/// made, stated with `u_deg`, its reference's systematic part's expanded
/// uncertainty `shared_reference_u_deg` shared with a verification made
/// with the same reference; `own` are the report's samples), in plain
/// words, and a table predicted to make the axis no better.
pub fn verdict_rows(
    p: &survey_tables::pipeline::Processed,
    (u_deg, shared_reference_u_deg): (Option<f64>, Option<f64>),
    v: Option<&Verification>,
    (survey_id, own): (i64, &[Sample]),
    units: Units,
) -> Vec<Vec<String>> {
    use survey_tables::verification::{Claim, Verdict, judge, peak_deg};
    let mut rows = Vec::new();
    match p.prediction.not_a_result() {
        Some(survey_tables::correction::NotAResult::NoBetterThanNative) => rows.push(vec![
            "the table".into(),
            format!(
                "NOT A RESULT: predicted no better than the native axis (corrected ±{} against native ±{}, with what \
                 the table leaves between the targets)",
                units.show(p.prediction.corrected_peak_deg),
                units.show(p.prediction.native_peak_deg)
            ),
            "-".into(),
        ]),
        Some(survey_tables::correction::NotAResult::DriftNotCorrected) => rows.push(vec![
            "the table".into(),
            format!(
                "NOT A RESULT: the survey drifted in time in a way no straight line takes (a pass keeps up to ±{}): \
                 the table carries that drift",
                units.show(p.prediction.uncorrected_drift_deg.unwrap_or(0.0))
            ),
            "-".into(),
        ]),
        None => {}
    }
    if let (Some(v), Some(u)) = (v, u_deg)
        && v.native_id == survey_id
    {
        let target = |s: &[Sample]| s.iter().map(|x| x.target_deg).collect::<Vec<f64>>();
        let blind =
            survey_lab::verify::blind(&target(v.native(own)), &target(v.corrected(own)), v.plausible_max_cycles, p);
        let predicted = survey_tables::verification::predicted_for(&p.prediction, v.corrected(own).len());
        let claim = Claim {
            predicted_deg: predicted,
            u_deg: u,
            native_deg: peak_deg(v.native(own)),
            not_a_result: p.prediction.not_a_result(),
            shared_reference_u_deg,
        };
        let j = judge(&claim, v.corrected(own), &blind);
        let reason = units.text(&j.reason);
        let words = match j.verdict {
            Verdict::Confirmed => format!("confirmed by survey {}: {reason}", v.verification_id),
            Verdict::NotConfirmed => format!(
                "NOT CONFIRMED by survey {}: {reason}. The table is not a result: do not load it",
                v.verification_id
            ),
        };
        let rule = "decision rule: confirmed unless the measured corrected peak exceeds the prediction by more than \
                    the table's U, or is not better than native (no guard band beyond U)";
        rows.push(vec!["verification verdict".into(), escape(&format!("{words} ({rule})")), "-".into()]);
    }
    rows
}
