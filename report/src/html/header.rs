//! The certificate's header: its fields ([`crate::certificate`]),
//! each with where it came from, the survey, its plan and dates.

use super::{Page, Section};
use crate::certificate::Issue;
use crate::certificate::{BENCH, Certificate, Stated, address_line, calibration_line, equipment_line};
use crate::page::escape;
use std::fmt::Write as _;
use survey_lab::environment::Environment;
use survey_store::survey::{Setup, SurveyRecord};

/// The plan in words.
pub fn plan_text(survey: &SurveyRecord) -> String {
    let Some(plan) = survey.plan() else {
        return format!(
            "{} targets x {} runs, {} (as imported)",
            survey.points.map_or("?".into(), |p| p.to_string()),
            survey.runs.map_or("?".into(), |p| p.to_string()),
            if survey.bidirectional { "bidirectional" } else { "one direction" }
        );
    };
    let t = &plan.targets_deg;
    let step = if t.len() > 1 { t[1] - t[0] } else { 0.0 };
    let mut s = format!(
        "{} targets from {:.4} to {:.4} deg (every {:.4} deg), {} runs, {}, overrun {:.3} deg",
        t.len(),
        t[0],
        t[t.len() - 1],
        step,
        plan.runs,
        if plan.bidirectional { "forward and reverse" } else { "forward only" },
        plan.overrun_deg
    );
    if let Setup::Simulated(sim) = &survey.setup {
        let _ = write!(s, "; reference {}, seed {}", sim.reference.as_str(), sim.seed);
    }
    s
}

/// ISO 230-2's edition, and the procedure this program follows.
pub fn method_text(survey: &SurveyRecord) -> String {
    format!(
        "ISO 230-2:2014 (accuracy and repeatability of positioning of numerically controlled axes), a rotary axis \
         measured against the reference instrument; procedure and processing of survey {} (plan: {})",
        env!("CARGO_PKG_VERSION"),
        plan_text(survey)
    )
}

/// The environment in words: the ranges the tracker measured, else what
/// was stated (marked so), else "not measured".
pub fn environment_text(cert: &Certificate, measured: &Environment, simulated: bool) -> String {
    let stated = cert.temperature_c.as_ref().map(|t| {
        format!(
            "air temperature {:.1} °C, stated, not measured by this program; its uncertainty is not stated",
            t.value
        )
    });
    match measured {
        Environment::Tracker(m) => {
            let station = if simulated {
                "the simulated tracker's room (this program's own model of a laboratory, exact)"
            } else {
                "the tracker's weather station (its uncertainty as its manufacturer states it, not stated here)"
            };
            let mut s = format!(
                "air temperature {:.2} to {:.2} °C (mean {:.2} °C), pressure {:.1} to {:.1} hPa, relative humidity \
                 {:.1} to {:.1} %, measured with each of the {} measurements by {station}",
                m.temperature_c.min,
                m.temperature_c.max,
                m.temperature_c.mean,
                m.pressure_hpa.min,
                m.pressure_hpa.max,
                m.humidity_pct.min,
                m.humidity_pct.max,
                m.count
            );
            if let Some(t) = stated {
                s += &format!("; also {t}");
            }
            s
        }
        _ => stated.unwrap_or_else(|| "not measured: no air temperature was measured or stated".into()),
    }
}

/// The time the survey measured on the instruments' clock, seconds: its
/// first to its last stored moment, times the instruments' speed-up (a
/// rehearsal at `[timing] time_scale`), as `survey run --json` says it.
pub fn instrument_time_s(survey: &SurveyRecord) -> Option<f64> {
    match (survey.started_at_s, survey.ended_at_s) {
        (Some(a), Some(b)) if b >= a => Some((b - a) * survey.setup.time_scale()),
        _ => None,
    }
}

/// A duration in words a reader takes in: seconds, minutes or hours.
pub fn duration_words(s: f64) -> String {
    if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.1} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

/// The calibration's dates: the survey's first and last stored change, as dates.
pub fn performed(survey: &SurveyRecord) -> (String, String) {
    let day = |t: &str| t.get(..10).unwrap_or(t).to_string();
    (day(&survey.created_at), day(&survey.updated_at))
}

/// The header as an HTML table (`tbl-header`).
fn fields(p: &Page<'_>) -> String {
    let (survey, cert, samples, units, generated) =
        (&p.d.survey, &p.cert, p.d.samples.len(), p.units, p.d.generated.as_str());
    let environment = &p.d.environment;
    let not_stated = "<i>not stated</i>".to_string();
    // What the bench says is the software's sentence (its errors in degrees); what a person stated stays as
    // written. Where each came from is not the customer's: the appendix says it ([`show_sources`]).
    let text = |v: &Option<Stated<String>>| {
        v.as_ref().map_or(not_stated.clone(), |s| {
            escape(&if s.from == BENCH { units.text(&s.value) } else { s.value.clone() })
        })
    };
    let (begin, end) = performed(survey);
    let instrument_time = match instrument_time_s(survey) {
        Some(t) => format!(" ({} of instrument time)", duration_words(t)),
        None => String::new(),
    };
    // What is stated of a field (an address, identifications) after it, on a line of its own, "; " between.
    let with = |field: String, more: &[Option<String>]| {
        let parts: Vec<&str> = more.iter().flatten().map(String::as_str).filter(|m| !m.is_empty()).collect();
        match parts.is_empty() {
            true => field,
            false => format!("{field}<br>{}", escape(&parts.join("; "))),
        }
    };
    let said = |id: &Option<String>| id.as_ref().map(|s| format!("identifies itself as \"{s}\""));
    let instrument = cert.reference_instrument.as_ref();
    let reference = with(
        text(&cert.reference),
        &[instrument.map(equipment_line), said(&cert.identified.reference), instrument.and_then(calibration_line)],
    );
    let item =
        with(text(&cert.positioner), &[cert.item.as_ref().map(equipment_line), said(&cert.identified.positioner)]);
    let rows: Vec<(&str, String)> = vec![
        ("Calibrating laboratory", with(text(&cert.laboratory), &[cert.laboratory_address.as_ref().map(address_line)])),
        ("Laboratory's country", text(&cert.country)),
        ("Customer (name, address)", with(text(&cert.customer), &[cert.customer_address.as_ref().map(address_line)])),
        ("Item calibrated", item),
        ("Item's condition", text(&cert.item_condition)),
        ("Date received", text(&cert.received)),
        ("Date of calibration", format!("{begin} to {end}{instrument_time}")),
        ("Location of calibration", text(&cert.location)),
        ("Method", escape(&method_text(survey))),
        ("Reference instrument", reference),
        (
            "Reference uncertainty",
            cert.reference_uncertainty_deg
                .as_ref()
                .map_or(not_stated.clone(), |u| format!("{} (standard uncertainty of one angle)", units.show(u.value))),
        ),
        ("Traceability", text(&cert.traceability)),
        ("Environment", escape(&environment_text(cert, environment, matches!(survey.setup, Setup::Simulated(_))))),
        ("Operator", text(&cert.operator)),
        (
            "Survey",
            format!(
                "{} ({}), status {}; {samples} samples; created {}, last changed {}",
                survey.id,
                escape(&survey.source.to_string()),
                survey.status,
                escape(&survey.created_at),
                escape(&survey.updated_at),
            ),
        ),
        ("Issued", issued_text(&p.d.issue, generated)),
        ("Units", format!("errors in {}; angles in degrees", units.symbol())),
    ];
    let mut html = String::from("<table class=\"header\" id=\"tbl-header\"><tbody>\n");
    for (k, v) in rows {
        let _ = writeln!(html, "<tr><td>{k}</td><td>{v}</td></tr>");
    }
    html + "</tbody></table>\n"
}

/// When the certificate was issued and what it replaces, or that it is a draft.
fn issued_text(issue: &Issue, generated: &str) -> String {
    let by = format!("by survey {}", env!("CARGO_PKG_VERSION"));
    match issue {
        Issue::Issued { issued_at, replaces: None, .. } => format!("{} {by}", escape(issued_at)),
        Issue::Issued { issued_at, replaces: Some(r), seq, .. } => format!(
            "{} {by}: amendment {} replacing certificate {} of {} ({})",
            escape(issued_at),
            seq - 1,
            escape(&r.number),
            escape(&r.issued_at),
            escape(&r.reason)
        ),
        Issue::Draft(why) => format!("not issued: a draft made {} {by} ({})", escape(generated), escape(why)),
    }
}

/// Where each field of the certificate came from: a flag of `survey
/// report`, the configuration's `[certificate]`, the bench, the survey
/// (an appendix: the customer's pages state the fields, not their provenance).
pub fn show_sources(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let c = &p.cert;
    let fields: [(&str, Option<&'static str>); 17] = [
        ("Certificate number", Some(c.number.from)),
        ("Calibrating laboratory", c.laboratory.as_ref().map(|s| s.from)),
        ("Laboratory's country", c.country.as_ref().map(|s| s.from)),
        ("Customer", c.customer.as_ref().map(|s| s.from)),
        ("Item calibrated", c.positioner.as_ref().map(|s| s.from)),
        ("Item's condition", c.item_condition.as_ref().map(|s| s.from)),
        ("Date received", c.received.as_ref().map(|s| s.from)),
        ("Location of calibration", c.location.as_ref().map(|s| s.from)),
        ("Reference instrument", c.reference.as_ref().map(|s| s.from)),
        ("Reference uncertainty", c.reference_uncertainty_deg.as_ref().map(|s| s.from)),
        ("Traceability", c.traceability.as_ref().map(|s| s.from)),
        ("Stated air temperature", c.temperature_c.as_ref().map(|s| s.from)),
        ("Tolerance", c.tolerance_deg.as_ref().map(|s| s.from)),
        ("Operator", c.operator.as_ref().map(|s| s.from)),
        ("Authorised by", c.signatory.as_ref().map(|s| s.from)),
        ("Method, dates, environment measured, survey", Some("the survey as stored")),
        ("Issued", Some("the store's record of the certificate (or a draft's time)")),
    ];
    let rows: Vec<Vec<String>> =
        fields.iter().map(|(k, f)| vec![k.to_string(), escape(f.unwrap_or("not stated anywhere"))]).collect();
    let body = crate::page::table_left("tbl-sources", &["field", "where it came from"], &rows, &[1]);
    Ok(Section::page("sources", "Where each field came from", body))
}

/// The section: the certificate's fields.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    Ok(Some(Section { id: "certificate", title: "Certificate".into(), new_page: false, body: fields(p) }))
}
