//! Native against corrected accuracy on the same scale (the paper's Figures
//! 8 and 9), when a verification survey (`survey run --verify`) measured the
//! positioner with the table applied.

use super::errors;
use super::page::{escape, figure, table};
use super::plot::padded;
use super::units::Units;
use survey_processing::Sample;
use survey_processing::errormap::ErrorMap;

/// A calibration survey and the verification of its table.
#[derive(Debug, Clone)]
pub struct Verification {
    /// The survey the table was made from.
    pub native_id: i64,
    /// Its samples.
    pub native: Vec<Sample>,
    /// The verification survey.
    pub verification_id: i64,
    /// Its samples, measured with the table applied.
    pub corrected: Vec<Sample>,
    /// Whether the table had forward and reverse columns.
    pub directional: bool,
}

/// The section: both error figures over one y range, and the figures side by side.
pub fn section(v: &Verification, units: Units) -> anyhow::Result<String> {
    let (Ok(native), Ok(corrected)) = (ErrorMap::from_samples(&v.native), ErrorMap::from_samples(&v.corrected)) else {
        return Ok(
            "<p class=\"note\">The verification is incomplete (a target or run is missing): no comparison.</p>\n"
                .into(),
        );
    };
    let (a, b) = (errors::y_extent(&native, units), errors::y_extent(&corrected, units));
    let y = padded(a.0.min(b.0), a.1.max(b.1), 0.06);
    let (native_svg, legend_html) = errors::svg(&native, units, Some(y.clone()))?;
    let (corrected_svg, _) = errors::svg(&corrected, units, Some(y))?;
    let doc = crate::verify::figures(v.verification_id, v.native_id, &v.native, &v.corrected, None, v.directional)?.doc;
    let f = |k: &str| doc[k].as_f64().unwrap_or(f64::NAN);
    let iso = |k: &str| doc["iso230_2"][k].as_f64();
    let native_iso = survey_processing::iso230::iso230_2(&v.native).ok();
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

/// The summary's rows on whether the table is a result: the verification's
/// verdict (when `v` verifies the table `p` made, stated with `u_deg`), in
/// plain words, and a table predicted to make the axis no better.
pub fn verdict_rows(
    p: &survey_processing::pipeline::Processed,
    u_deg: Option<f64>,
    v: Option<&Verification>,
    survey_id: i64,
    units: Units,
) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    if p.prediction.no_better_than_native() {
        rows.push(vec![
            "the table".into(),
            format!(
                "NOT A RESULT: predicted no better than the native axis (corrected ±{} against native ±{}, with what \
                 the table leaves between the targets)",
                units.show(p.prediction.corrected_peak_deg),
                units.show(p.prediction.native_peak_deg)
            ),
        ]);
    }
    if let (Some(v), Some(u)) = (v, u_deg)
        && v.native_id == survey_id
    {
        let peak = survey_processing::verification::peak_deg;
        let j = survey_processing::verification::judge(
            p.prediction.corrected_peak_deg,
            u,
            peak(&v.corrected),
            peak(&v.native),
        );
        let words = match j.verdict {
            survey_processing::verification::Verdict::Confirmed => {
                format!("confirmed by survey {}: {}", v.verification_id, j.reason)
            }
            survey_processing::verification::Verdict::NotConfirmed => format!(
                "NOT CONFIRMED by survey {}: {}. The table is not a result: do not load it",
                v.verification_id, j.reason
            ),
        };
        rows.push(vec!["verification verdict".into(), escape(&words)]);
    }
    rows
}
