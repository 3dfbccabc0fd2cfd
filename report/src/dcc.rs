//! `DIR/dcc.xml`: the certificate as a Digital Calibration Certificate, PTB's
//! DCC schema 3.2.0 with D-SI 2.1.0 quantities (`../shared/data/dcc`). The
//! same fields and figures as the page ([`crate::html`] reads the same
//! [`Page`]): the administrative data (this software, the core data with the
//! certificate number as `uniqueIdentifier`, the item, the laboratory, the
//! responsible persons, the customer, the statements: results relate to the
//! item, traceability, the item's condition, the location, the decision rule
//! and its verdict), then one measurement result: the method (ISO 230-2:2014,
//! this program's procedure, the GUM's expanded uncertainty), the reference
//! instrument, the environment as an influence condition, ISO 230-2's A, R,
//! B, E and M, the native and the predicted corrected peak (and, after a
//! verification, the corrected peak and A measured), and the correction
//! table as list quantities. Angles in `\degree`; each figure rounded as the
//! page rounds it (ILAC-P14) with its expanded uncertainty, coverage factor
//! and coverage probability.
//!
//! A field the laboratory did not state is written as "not stated" where
//! the schema needs text; the country, which the schema needs as two
//! capital letters, is then `ZZ` (the user-assigned code for an unknown
//! country) and a statement says so.
//!
//! Written with quick-xml's [`Writer`] (every text escaped by it).

mod xml;

use crate::certificate::{IDENTIFIED_AS, Issue, REHEARSAL, calibration_line};
use crate::conformity::{self, Decision};
use crate::html::Page;
use crate::html::header::{environment_text, method_text, performed};
use crate::rounding;
use anyhow::Context as _;
use quick_xml::Writer;
use quick_xml::events::{BytesDecl, Event};
use survey_lab::environment::Environment;
use survey_processing::Direction;
use survey_processing::iso230::iso230_2;
use xml::Xml;

/// The D-SI unit of every angle.
const DEGREE: &str = "\\degree";
/// The coverage factor and probability of every expanded uncertainty.
const K: &str = "2";
use crate::rounding::{NORMAL, PROBABILITY, TABLE_DISTRIBUTION};
/// What a field the laboratory did not state says.
const NOT_STATED: &str = "not stated";

/// The DCC's `performanceLocation` from the location stated: the
/// customer's (or client's) premises or branch when it names the customer or
/// says on site, the laboratory's when it names a laboratory (or lab), else
/// `other` (not stated, or not said). A bare "site" says neither ("Lab North,
/// site B" is the laboratory's). `[certificate] performance_location`, where
/// stated, says it instead.
fn performance_location(location: Option<&str>) -> &'static str {
    let Some(l) = location.map(str::to_lowercase) else { return "other" };
    let words: Vec<&str> = l.split(|c: char| !c.is_alphanumeric()).filter(|w| !w.is_empty()).collect();
    let has = |w: &[&str]| words.iter().any(|x| w.contains(x));
    let on_site = words.windows(2).any(|p| p == ["on", "site"]) || has(&["onsite"]);
    match (has(&["customer", "customers", "client", "clients"]) || on_site, has(&["branch"])) {
        (true, true) => "customerBranch",
        (true, false) => "customer",
        (false, branch) if has(&["laboratory", "lab", "laboratories", "labs"]) => {
            if branch {
                "laboratoryBranch"
            } else {
                "laboratory"
            }
        }
        _ => "other",
    }
}

/// The DCC's `performanceLocation`: the configuration's `[certificate]
/// performance_location` where stated, else read from `location`.
fn performed_at<'a>(survey: &'a survey_store::survey::SurveyRecord, location: Option<&str>) -> &'a str {
    let stated = match &survey.setup {
        survey_store::survey::Setup::Configured(c) => {
            c.config.certificate.as_ref().and_then(|c| c.performance_location.as_deref())
        }
        _ => None,
    };
    stated.unwrap_or_else(|| performance_location(location))
}

/// `s` with its first letter a capital.
fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next().map_or_else(String::new, |f| f.to_uppercase().chain(c).collect())
}

/// A value of the page's number format, as the D-SI writes it (`1e-5`, `0.0350`).
fn decimal(shown: &str) -> String {
    shown.split_whitespace().next().unwrap_or(shown).to_string()
}

/// `value` and `u` (degrees) as ILAC-P14 rounds them, for the XML.
fn rounded(value: f64, u: Option<f64>) -> (String, Option<String>) {
    let (v, u) = rounding::show(crate::units::Units::Deg, value, u);
    let v = decimal(&v);
    match u {
        Some(u) => (v, Some(decimal(&u))),
        // Without a U: by significance, as the page shows it (no place is known to round to).
        None => (v, None),
    }
}

/// The certificate of `p` as DCC 3.2.0 XML.
pub fn document(p: &Page<'_>) -> anyhow::Result<String> {
    let mut x = Xml { w: Writer::new_with_indent(Vec::new(), b' ', 1), distribution: NORMAL };
    x.w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None))).context("writing the DCC")?;
    x.open(
        "dcc:digitalCalibrationCertificate",
        &[
            ("xmlns:dcc", "https://ptb.de/dcc"),
            ("xmlns:si", "https://ptb.de/si"),
            ("xmlns:xsi", "http://www.w3.org/2001/XMLSchema-instance"),
            ("xsi:schemaLocation", "https://ptb.de/dcc https://ptb.de/dcc/v3.2.0/dcc.xsd"),
            ("schemaVersion", "3.2.0"),
        ],
    )?;
    administrative(&mut x, p)?;
    results(&mut x, p)?;
    x.close("dcc:digitalCalibrationCertificate")?;
    String::from_utf8(x.w.into_inner()).context("the DCC is not UTF-8")
}

fn stated(v: &Option<crate::certificate::Stated<String>>) -> &str {
    v.as_ref().map_or(NOT_STATED, |s| s.value.as_str())
}

/// `dcc:administrativeData`.
fn administrative(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    let (cert, survey) = (&p.cert, &p.d.survey);
    x.open("dcc:administrativeData", &[])?;
    x.open("dcc:dccSoftware", &[])?;
    x.open("dcc:software", &[])?;
    x.words("dcc:name", "survey")?;
    x.leaf("dcc:release", env!("CARGO_PKG_VERSION"))?;
    x.leaf("dcc:type", "application")?;
    x.close("dcc:software")?;
    x.close("dcc:dccSoftware")?;

    let (begin, end) = performed(survey);
    x.open("dcc:coreData", &[])?;
    x.leaf("dcc:countryCodeISO3166_1", cert.country.as_ref().map_or("ZZ", |c| c.value.as_str()))?;
    x.leaf("dcc:usedLangCodeISO639_1", "en")?;
    x.leaf("dcc:mandatoryLangCodeISO639_1", "en")?;
    x.leaf("dcc:uniqueIdentifier", &cert.number.value)?;
    x.open("dcc:identifications", &[])?;
    x.open("dcc:identification", &[])?;
    x.leaf("dcc:issuer", "calibrationLaboratory")?;
    x.leaf("dcc:value", &survey.uid)?;
    x.words("dcc:name", "survey uid (the measurement's record)")?;
    x.close("dcc:identification")?;
    x.close("dcc:identifications")?;
    if let Some(r) = &cert.received {
        x.leaf("dcc:receiptDate", &r.value)?;
    }
    x.leaf("dcc:beginPerformanceDate", &begin)?;
    x.leaf("dcc:endPerformanceDate", &end)?;
    x.leaf("dcc:performanceLocation", performed_at(survey, cert.location.as_ref().map(|l| l.value.as_str())))?;
    let issued = match &p.d.issue {
        Issue::Issued { issued_at, .. } => issued_at,
        Issue::Draft(_) => &p.d.generated,
    };
    x.leaf("dcc:issueDate", issued.get(..10).unwrap_or(issued))?;
    if let Issue::Issued { replaces: Some(r), .. } = &p.d.issue {
        x.open("dcc:previousReport", &[])?;
        x.words(
            "dcc:referral",
            &format!(
                "calibration certificate {} issued {}, withdrawn: this certificate replaces it",
                r.number, r.issued_at
            ),
        )?;
        x.leaf("dcc:referralID", &r.number)?;
        x.leaf("dcc:procedure", "SHA-256 of its dcc.xml as issued")?;
        x.leaf("dcc:value", &r.dcc_sha256)?;
        x.words("dcc:description", &format!("Reason for the amendment: {}", r.reason))?;
        x.close("dcc:previousReport")?;
    }
    x.close("dcc:coreData")?;

    x.open("dcc:items", &[])?;
    x.open("dcc:item", &[])?;
    x.words("dcc:name", &p.cert.positioner_name(survey))?;
    x.words("dcc:description", stated(&cert.positioner))?;
    let mut more = vec![("calibrationLaboratory", survey.asset.as_str(), "asset (the axis calibrated)")];
    if let Some(said) = &cert.identified.positioner {
        more.push(("manufacturer", said.as_str(), IDENTIFIED_AS));
    }
    x.equipment(cert.item.as_ref(), true, &more)?;
    x.close("dcc:item")?;
    x.close("dcc:items")?;

    x.open("dcc:calibrationLaboratory", &[])?;
    x.contact(
        "dcc:contact",
        stated(&cert.laboratory),
        cert.laboratory_address.as_ref(),
        cert.country.as_ref().map(|c| c.value.as_str()),
    )?;
    x.close("dcc:calibrationLaboratory")?;

    x.open("dcc:respPersons", &[])?;
    x.open("dcc:respPerson", &[])?;
    x.open("dcc:person", &[])?;
    x.words("dcc:name", stated(&cert.signatory))?;
    x.close("dcc:person")?;
    x.leaf("dcc:role", "authorises the certificate (name and function)")?;
    // The main signer only when one is stated (a signatory "not stated" signs nothing).
    if cert.signatory.is_some() {
        x.leaf("dcc:mainSigner", "true")?;
    }
    x.close("dcc:respPerson")?;
    if let Some(op) = &cert.operator {
        x.open("dcc:respPerson", &[])?;
        x.open("dcc:person", &[])?;
        x.words("dcc:name", &op.value)?;
        x.close("dcc:person")?;
        x.leaf("dcc:role", "operator (measured)")?;
        x.close("dcc:respPerson")?;
    }
    x.close("dcc:respPersons")?;
    x.contact("dcc:customer", stated(&cert.customer), cert.customer_address.as_ref(), None)?;
    statements(x, p)?;
    x.close("dcc:administrativeData")
}

/// `dcc:statements`: what the page's header and closing statements say.
fn statements(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    let cert = &p.cert;
    x.open("dcc:statements", &[])?;
    x.statement(
        "basic_validity",
        Some(("ISO/IEC 17025:2017", "7.8.2.1")),
        "The results relate only to the item calibrated, as it was when calibrated.",
    )?;
    match &p.d.issue {
        Issue::Issued { replaces: Some(r), .. } => x.statement(
            "survey_amendment",
            Some(("ISO/IEC 17025:2017", "7.8.8")),
            &format!(
                "This certificate replaces certificate {} issued {}, which is withdrawn. Reason: {}",
                r.number, r.issued_at, r.reason
            ),
        )?,
        Issue::Draft(why) => x.statement("survey_draft", None, &format!("Draft, not issued: {why}."))?,
        Issue::Issued { .. } => {}
    }
    if let Some(why) = &cert.rehearsal {
        x.statement(
            "survey_rehearsal",
            None,
            &format!(
                "This is a {REHEARSAL}: {why}. Its figures show the method; they certify no instrument and are \
                 traceable to nothing."
            ),
        )?;
    }
    x.statement("basic_traceability", None, stated(&cert.traceability))?;
    x.statement("survey_itemCondition", None, &format!("Condition of the item: {}", stated(&cert.item_condition)))?;
    x.statement("survey_location", None, &format!("Location of the calibration: {}", stated(&cert.location)))?;
    if cert.country.is_none() {
        x.statement("survey_country", None, "The laboratory's country is not stated: ZZ stands for it.")?;
    }
    x.statement("basic_uncertainty", Some(("GUM", "ILAC-P14")), rounding::COVERAGE)?;
    if let Some(tolerance) = &cert.tolerance_deg {
        let (figure, what) = judged(p);
        let u = measured_u(p);
        let decision = figure.map_or(Decision::NotDecidable, |a| conformity::decide(a, u, tolerance.value));
        x.open("dcc:statement", &[("refType", "basic_conformity")])?;
        x.leaf("dcc:norm", "ILAC-G8:09/2019")?;
        x.words(
            "dcc:declaration",
            &format!(
                "Verdict against the tolerance {} deg on {what}: {}. {}",
                tolerance.value,
                decision.word(),
                conformity::RULE
            ),
        )?;
        match decision {
            Decision::Pass => x.leaf("dcc:conformity", "pass")?,
            Decision::Fail => x.leaf("dcc:conformity", "fail")?,
            Decision::NotDecidable => {}
        }
        x.close("dcc:statement")?;
    }
    x.close("dcc:statements")
}

/// The measured figures' expanded uncertainty (k = 2), degrees.
fn measured_u(p: &Page<'_>) -> Option<f64> {
    conformity::accuracy_u_deg(
        p.cert.reference_uncertainty_deg.as_ref().map(|u| u.value),
        p.d.reference_systematic_u_deg,
        p.d.axis_u_deg,
    )
}

/// The accuracy a tolerance judges, as the summary does: the corrected A measured, else the native A.
fn judged(p: &Page<'_>) -> (Option<f64>, String) {
    let d = p.d;
    match d.verification.as_ref().and_then(|v| iso230_2(v.corrected(&d.samples)).ok().map(|iso| (v, iso.a))) {
        Some((v, a)) => (
            Some(a),
            format!("the corrected accuracy A per ISO 230-2, measured by verification survey {}", v.verification_id),
        ),
        None => (p.iso.as_ref().ok().map(|i| i.a), "the native accuracy A per ISO 230-2 of this survey".into()),
    }
}

/// `dcc:measurementResults`.
fn results(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    x.open("dcc:measurementResults", &[])?;
    x.open("dcc:measurementResult", &[])?;
    let title = "Readout error and positioning accuracy of a rotary axis";
    match &p.cert.rehearsal {
        None => x.words("dcc:name", title)?,
        Some(_) => x.words("dcc:name", &format!("{}: {title}", capitalised(REHEARSAL)))?,
    }
    x.open("dcc:usedMethods", &[])?;
    x.open("dcc:usedMethod", &[("refType", "basic_uncertainty")])?;
    x.words("dcc:name", "Expanded uncertainty")?;
    x.words("dcc:description", rounding::COVERAGE)?;
    x.leaf("dcc:norm", "GUM")?;
    x.close("dcc:usedMethod")?;
    x.open("dcc:usedMethod", &[("refType", "survey_iso230_2")])?;
    x.words("dcc:name", "ISO 230-2:2014 and the procedure of survey")?;
    x.words("dcc:description", &method_text(&p.d.survey))?;
    x.leaf("dcc:norm", "ISO 230-2:2014")?;
    x.close("dcc:usedMethod")?;
    x.close("dcc:usedMethods")?;
    measuring_equipment(x, &p.cert)?;
    x.open("dcc:influenceConditions", &[])?;
    x.open("dcc:influenceCondition", &[("refType", "basic_temperature")])?;
    x.words("dcc:name", "Ambient air (temperature; with a tracker, pressure and relative humidity too)")?;
    let simulated = matches!(p.d.survey.setup, survey_store::survey::Setup::Simulated(_));
    x.words("dcc:description", &environment_text(&p.cert, &p.d.environment, simulated))?;
    x.open("dcc:data", &[])?;
    match (&p.cert.temperature_c, &p.d.environment) {
        (_, Environment::Tracker(m)) => {
            // Rounded as the page states them: 0.01 °C, 0.1 hPa, 0.1 % (0.001 as a fraction).
            let quantities = [
                ("basic_temperatureMin", "air temperature, least measured", m.temperature_c.min, 2, "\\degreecelsius"),
                (
                    "basic_temperatureMax",
                    "air temperature, greatest measured",
                    m.temperature_c.max,
                    2,
                    "\\degreecelsius",
                ),
                ("basic_pressureMin", "air pressure, least measured", m.pressure_hpa.min, 1, "\\hecto\\pascal"),
                ("basic_pressureMax", "air pressure, greatest measured", m.pressure_hpa.max, 1, "\\hecto\\pascal"),
                (
                    "basic_humidityRelativeMin",
                    "relative humidity, least measured",
                    m.humidity_pct.min / 100.0,
                    3,
                    "\\one",
                ),
                (
                    "basic_humidityRelativeMax",
                    "relative humidity, greatest measured",
                    m.humidity_pct.max / 100.0,
                    3,
                    "\\one",
                ),
            ];
            for (ref_type, name, value, places, unit) in quantities {
                x.open("dcc:quantity", &[("refType", ref_type)])?;
                x.words("dcc:name", name)?;
                x.open("si:real", &[])?;
                x.leaf("si:value", &format!("{value:.places$}"))?;
                x.leaf("si:unit", unit)?;
                x.close("si:real")?;
                x.close("dcc:quantity")?;
            }
        }
        (Some(t), _) => {
            x.open("dcc:quantity", &[("refType", "basic_temperatureStated")])?;
            x.words("dcc:name", "air temperature, stated")?;
            x.open("si:real", &[])?;
            x.leaf("si:value", &format!("{:.1}", t.value))?;
            x.leaf("si:unit", "\\degreecelsius")?;
            x.close("si:real")?;
            x.close("dcc:quantity")?;
        }
        (None, _) => x.words("dcc:text", "not measured")?,
    }
    x.close("dcc:data")?;
    x.close("dcc:influenceCondition")?;
    x.close("dcc:influenceConditions")?;
    x.open("dcc:results", &[])?;
    figures(x, p)?;
    motions(x, p)?;
    per_target(x, p)?;
    budget(x, p)?;
    table(x, p)?;
    x.close("dcc:results")?;
    x.close("dcc:measurementResult")?;
    x.close("dcc:measurementResults")
}

/// `dcc:measuringEquipments`: the reference instrument, its identifications
/// and the certificate of its own calibration, and its stated uncertainty
/// as a quantity.
fn measuring_equipment(x: &mut Xml, cert: &crate::certificate::Certificate) -> anyhow::Result<()> {
    x.open("dcc:measuringEquipments", &[])?;
    x.open("dcc:measuringEquipment", &[("refType", "basic_normalUsed")])?;
    x.words("dcc:name", stated(&cert.reference))?;
    let reference = cert.reference_instrument.as_ref();
    let calibration = reference.and_then(calibration_line);
    let description = [
        cert.reference_uncertainty_deg.as_ref().map(|u| format!("standard uncertainty of one angle: {} deg", u.value)),
        calibration.clone(),
    ];
    let description: Vec<String> = description.into_iter().flatten().collect();
    if !description.is_empty() {
        x.words("dcc:description", &description.join("; "))?;
    }
    // Its own calibration certificate, by its number, beside its identifications.
    let mut certificate: Vec<(&str, &str, &str)> = reference
        .and_then(|r| r.certificate.as_deref())
        .map(|c| ("calibrationLaboratory", c, "certificate of its calibration"))
        .into_iter()
        .collect();
    if let Some(said) = &cert.identified.reference {
        certificate.push(("manufacturer", said.as_str(), IDENTIFIED_AS));
    }
    x.equipment(reference, false, &certificate)?;
    if let Some(u) = &cert.reference_uncertainty_deg {
        // The same as a quantity a machine reads.
        x.open("dcc:measuringEquipmentQuantities", &[])?;
        x.open("dcc:measuringEquipmentQuantity", &[("refType", "survey_referenceStandardUncertainty")])?;
        x.words("dcc:name", "the reference's standard uncertainty of one angle (k = 1)")?;
        x.open("si:real", &[])?;
        x.leaf("si:value", &format!("{}", u.value))?;
        x.leaf("si:unit", DEGREE)?;
        x.close("si:real")?;
        x.close("dcc:measuringEquipmentQuantity")?;
        x.close("dcc:measuringEquipmentQuantities")?;
    }
    x.close("dcc:measuringEquipment")?;
    x.close("dcc:measuringEquipments")?;
    Ok(())
}

/// The axis's location (ISO 230-1) and error motions (ISO 230-7), one
/// result of their own: each figure in micrometres or microradians with its
/// expanded uncertainty, a figure below the detection limit as a
/// `dcc:noQuantity` that says so.
fn motions(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    let Some(m) = &p.d.error_motions else { return Ok(()) };
    x.open("dcc:result", &[("refType", "survey_errorMotions")])?;
    x.words("dcc:name", "Location of the axis average line (ISO 230-1) and error motions of the axis (ISO 230-7)")?;
    x.words("dcc:description", m.method)?;
    x.open("dcc:data", &[])?;
    let real =
        |x: &mut Xml, ref_type: &str, name: &str, value: f64, unit: &str, u: Option<f64>| -> anyhow::Result<()> {
            x.open("dcc:quantity", &[("refType", &format!("basic_measuredValue {ref_type}"))])?;
            x.words("dcc:name", name)?;
            x.open("si:real", &[])?;
            x.leaf("si:value", &format!("{value:.3}"))?;
            x.leaf("si:unit", unit)?;
            if let Some(u) = u {
                x.open("si:expandedUnc", &[])?;
                // One decimal for the motions (tens of um); a location's U in mm (some 0.05) to three.
                x.leaf("si:uncertainty", &if u < 1.0 { format!("{u:.3}") } else { format!("{u:.1}") })?;
                x.leaf("si:coverageFactor", K)?;
                x.leaf("si:coverageProbability", PROBABILITY)?;
                x.leaf("si:distribution", NORMAL)?;
                x.close("si:expandedUnc")?;
            }
            x.close("si:real")?;
            x.close("dcc:quantity")
        };
    let l = &m.location;
    const MM: &str = "\\milli\\metre";
    const URAD: &str = "\\micro\\radian";
    const UM: &str = "\\micro\\metre";
    let (uxy, uab) = (Some(l.u_xy_mm), Some(l.u_ab_urad));
    real(x, "survey_axisX0", "X0C, the axis average line's x in the tracker's frame", l.x0_mm, MM, uxy)?;
    real(x, "survey_axisY0", "Y0C, the axis average line's y in the tracker's frame", l.y0_mm, MM, uxy)?;
    real(x, "survey_axisA0", "A0C, the axis average line's rotation about x", l.a0_urad, URAD, uab)?;
    real(x, "survey_axisB0", "B0C, the axis average line's rotation about y", l.b0_urad, URAD, uab)?;
    if let Some(f) = &l.machine {
        let (uxy, uab) = (Some(f.u_xy_mm), Some(f.u_ab_urad));
        let at = "in the machine's frame, where it crosses the machine's z = 0";
        real(x, "survey_axisMachineX0", &format!("X0C, the axis average line's x {at}"), f.x0_mm, MM, uxy)?;
        real(x, "survey_axisMachineY0", &format!("Y0C, the axis average line's y {at}"), f.y0_mm, MM, uxy)?;
        let about = |axis: &str| format!("the axis average line's rotation about the machine's {axis}");
        real(x, "survey_axisMachineA0", &format!("A0C, {}", about("x")), f.a0_urad, URAD, uab)?;
        real(x, "survey_axisMachineB0", &format!("B0C, {}", about("y")), f.b0_urad, URAD, uab)?;
    }
    let mut blocks = vec![("Radial", "radial", &m.radial_um, UM), ("Axial", "axial", &m.axial_um, UM)];
    if let Some(a) = &m.axial_on_axis_um {
        blocks.push(("AxialOnAxis", "axial (on the axis)", a, UM));
    }
    if let Some(t) = &m.tilt_urad {
        blocks.push(("Tilt", "tilt", &t.block, URAD));
    }
    if let Some(t) = &m.tilt_across_urad {
        blocks.push(("TiltAcross", "tilt (at 90 deg to the first SMR's radial direction)", &t.block, URAD));
    }
    for (tag, name, b, unit) in blocks {
        for (kind, value, u) in [
            ("Total", b.total, b.u_total),
            ("Synchronous", b.synchronous, b.u_synchronous),
            ("Asynchronous", b.asynchronous, b.u_asynchronous),
        ] {
            let ref_type = format!("survey_motion{tag}{kind}");
            let what = format!("{} {name} error motion (ISO 230-7)", kind.to_lowercase());
            match value {
                Some(v) => real(x, &ref_type, &what, v, unit, Some(u))?,
                None => {
                    x.open("dcc:quantity", &[("refType", &ref_type)])?;
                    x.words("dcc:name", &what)?;
                    let why = format!(
                        "below the detection limit of {:.1} (the tracker's transverse error at the SMR's distance): \
                         not measurable with this reference",
                        b.detection_limit
                    );
                    x.words("dcc:noQuantity", &why)?;
                    x.close("dcc:quantity")?;
                }
            }
        }
    }
    real(
        x,
        "survey_motionDetectionLimit",
        "detection limit (the tracker's transverse MPE)",
        m.detection_limit_um,
        UM,
        None,
    )?;
    x.close("dcc:data")?;
    x.close("dcc:result")
}

/// The ISO 230-2 figures and the peaks, one result.
fn figures(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    let u = measured_u(p);
    x.open("dcc:result", &[("refType", "survey_figures")])?;
    x.words("dcc:name", "ISO 230-2 figures of the axis and the peak errors")?;
    x.words(
        "dcc:description",
        "Deviation x = actual - target (ISO 230-2); the peaks are of the error readout - actual. A, E, M and the \
         peaks carry the measurement's expanded uncertainty; R and B are given to the same decimal place.",
    )?;
    x.open("dcc:data", &[])?;
    if let Ok(iso) = &p.iso {
        let place = |v: f64| rounded(v, u).0;
        let (a, ua) = rounded(iso.a, u);
        x.angle("survey_iso230_2_A", "A, accuracy of positioning (ISO 230-2)", &a, ua.as_deref())?;
        x.angle("survey_iso230_2_R", "R, repeatability of positioning (ISO 230-2)", &place(iso.r), None)?;
        if let Some(b) = iso.b {
            x.angle("survey_iso230_2_B", "B, reversal value (ISO 230-2)", &place(b), None)?;
        }
        let (e, ue) = rounded(iso.e, u);
        x.angle("survey_iso230_2_E", "E, systematic positional deviation (ISO 230-2)", &e, ue.as_deref())?;
        if let Some(m) = iso.m {
            let (m, um) = rounded(m, u);
            x.angle("survey_iso230_2_M", "M, mean positional deviation (ISO 230-2)", &m, um.as_deref())?;
        }
        directions_and_vdi(x, iso, u)?;
    }
    if let Ok(processed) = &p.d.processed {
        let prediction = &processed.prediction;
        let (v, uv) = rounded(prediction.native_peak_deg, u);
        x.angle("survey_nativePeak", "native peak error (no correction)", &v, uv.as_deref())?;
        let table_u = p.d.uncertainty.as_ref().map(|b| b.table_u_deg);
        let (v, uv) = rounded(prediction.corrected_peak_deg, table_u);
        x.distribution = TABLE_DISTRIBUTION;
        x.angle(
            "survey_correctedPeakPredicted",
            "corrected peak error, predicted from this survey (the table's uncertainty)",
            &v,
            uv.as_deref(),
        )?;
        x.distribution = NORMAL;
    }
    if let Some(v) = &p.d.verification {
        let errors: Vec<f64> = v.corrected(&p.d.samples).iter().map(|s| s.error_deg()).collect();
        let peak = survey_tables::correction::ErrorFigures::of(&errors, None).peak_deg;
        let (value, uv) = rounded(peak, u);
        let name = format!("corrected peak error, measured by verification survey {}", v.verification_id);
        x.angle("survey_correctedPeakMeasured", &name, &value, uv.as_deref())?;
        if let Ok(iso) = iso230_2(v.corrected(&p.d.samples)) {
            let (a, ua) = rounded(iso.a, u);
            let name = format!("A, corrected, measured by verification survey {}", v.verification_id);
            x.angle("survey_correctedAMeasured", &name, &a, ua.as_deref())?;
        }
    }
    if let Some(t) = &p.cert.tolerance_deg {
        // The tolerance the accuracy A is judged against, as a quantity (its verdict is a statement).
        x.open("dcc:quantity", &[("refType", "basic_acceptanceLimitUpper survey_toleranceA")])?;
        x.words("dcc:name", "tolerance on the accuracy A (ISO 230-2), the upper acceptance limit")?;
        x.open("si:real", &[])?;
        x.leaf("si:value", &format!("{}", t.value))?;
        x.leaf("si:unit", DEGREE)?;
        x.close("si:real")?;
        x.close("dcc:quantity")?;
    }
    x.close("dcc:data")?;
    x.close("dcc:result")
}

/// ISO 230-2's figures each way (forward: increasing angle) and VDI/DGQ
/// 3441's P, Pa, Ps, U and U mean (the last two where both directions were
/// measured), each to the place of the measured figures' U (with it where
/// the figure is of the deviations themselves: A, E, P, Pa).
fn directions_and_vdi(x: &mut Xml, iso: &survey_processing::iso230::Iso230, u: Option<f64>) -> anyhow::Result<()> {
    let with_u = |v: f64| rounded(v, u);
    let figures = [
        ("survey_iso230_2_A_forward", "A, forward (ISO 230-2)", iso.a_up, true),
        ("survey_iso230_2_A_reverse", "A, reverse (ISO 230-2)", iso.a_down, true),
        ("survey_iso230_2_R_forward", "R, forward (ISO 230-2)", iso.r_up, false),
        ("survey_iso230_2_R_reverse", "R, reverse (ISO 230-2)", iso.r_down, false),
        ("survey_iso230_2_E_forward", "E, forward (ISO 230-2)", iso.e_up, true),
        ("survey_iso230_2_E_reverse", "E, reverse (ISO 230-2)", iso.e_down, true),
        ("survey_iso230_2_Bmean", "B mean, mean reversal value (ISO 230-2)", iso.b_mean, false),
    ];
    let vdi = survey_processing::vdi3441::vdi3441(iso);
    let vdi_figures = [
        ("survey_vdi3441_P", "P, positional uncertainty (VDI/DGQ 3441)", Some(vdi.p_deg), true),
        ("survey_vdi3441_Pa", "Pa, position deviation (VDI/DGQ 3441)", Some(vdi.pa_deg), true),
        ("survey_vdi3441_Ps", "Ps, largest positional scatter (VDI/DGQ 3441)", Some(vdi.ps_deg), false),
        // VDI's U is a reversal span, not an uncertainty: given to the place of the measured figures' U, without one.
        ("survey_vdi3441_U", "U, largest reversal span (VDI/DGQ 3441; not an uncertainty)", vdi.u_deg, false),
        ("survey_vdi3441_Umean", "U mean, mean reversal span (VDI/DGQ 3441)", vdi.u_mean_deg, false),
    ];
    for (ref_type, name, value, carries_u) in figures.into_iter().chain(vdi_figures) {
        let Some(v) = value else { continue };
        let (v, uv) = with_u(v);
        x.angle(ref_type, name, &v, if carries_u { uv.as_deref() } else { None })?;
    }
    Ok(())
}

/// The mean error at each target and direction (readout - actual, the
/// table's sign: the negative of ISO 230-2's mean deviation), with the
/// measured figures' U, as lists: what a consumer compares its own
/// measurements with.
fn per_target(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    let Ok(iso) = &p.iso else { return Ok(()) };
    let u = measured_u(p);
    let u_text = u.map(|u| decimal(&rounding::show_u(crate::units::Units::Deg, u)));
    x.open("dcc:result", &[("refType", "survey_perTarget")])?;
    x.words("dcc:name", "Mean error at each target, each direction")?;
    x.words(
        "dcc:description",
        "The error readout - actual averaged over the runs at each target (the negative of ISO 230-2's mean \
         positional deviation), forward (increasing angle) and reverse; a direction not measured is left out.",
    )?;
    x.open("dcc:data", &[])?;
    x.open("dcc:list", &[("refType", "survey_perTargetList")])?;
    let targets: Vec<String> = iso.targets.iter().map(|t| crate::units::angle(t.target_deg)).collect();
    x.list("basic_referenceValue survey_target", "target (the readout commanded)", &targets, DEGREE, None)?;
    type Side = fn(&survey_processing::iso230::TargetStats) -> Option<&survey_processing::iso230::DirStats>;
    let sides: [(&str, &str, Side); 2] = [
        ("basic_measurementError survey_meanErrorForward", "mean error, forward", |t| t.up.as_ref()),
        ("basic_measurementError survey_meanErrorReverse", "mean error, reverse", |t| t.down.as_ref()),
    ];
    for (ref_type, name, side) in sides {
        let means: Option<Vec<String>> =
            iso.targets.iter().map(|t| side(t).map(|d| rounding::num(crate::units::Units::Deg, -d.mean, u))).collect();
        if let Some(means) = means {
            x.list(ref_type, name, &means, DEGREE, u_text.as_deref())?;
        }
    }
    x.close("dcc:list")?;
    x.close("dcc:data")?;
    x.close("dcc:result")
}

/// The table's uncertainty budget: each contribution's standard
/// uncertainty (k = 1), the combined u and the expanded U, as the page's
/// budget states them (degrees: the contributions by significance, U to two digits).
fn budget(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    let Some(b) = &p.d.uncertainty else { return Ok(()) };
    let deg = crate::units::Units::Deg;
    x.open("dcc:result", &[("refType", "survey_uncertaintyBudget")])?;
    x.words("dcc:name", "Uncertainty budget of the correction table")?;
    x.words(
        "dcc:description",
        "Each contribution a standard uncertainty (k = 1) at an angle of the table; combined in quadrature; the \
         expanded uncertainty U the table's coverage interval (k = 2, 95.45 %).",
    )?;
    x.open("dcc:data", &[])?;
    let plain = |x: &mut Xml, ref_type: &str, name: &str, value: String| -> anyhow::Result<()> {
        x.open("dcc:quantity", &[("refType", ref_type)])?;
        x.words("dcc:name", name)?;
        x.open("si:real", &[])?;
        x.leaf("si:value", &value)?;
        x.leaf("si:unit", DEGREE)?;
        x.close("si:real")?;
        x.close("dcc:quantity")
    };
    for c in &b.budget {
        plain(x, "survey_budgetEntry", &c.source, deg.num(c.u_deg))?;
    }
    plain(x, "survey_budgetCombined", "combined standard uncertainty u", deg.num(b.combined_u_deg))?;
    plain(x, "survey_budgetExpanded", "expanded uncertainty U (k = 2)", rounding::num_u(deg, b.table_u_deg))?;
    x.close("dcc:data")?;
    x.close("dcc:result")
}

/// The correction table, one list: the readout of each row and the error of each column.
fn table(x: &mut Xml, p: &Page<'_>) -> anyhow::Result<()> {
    let Ok(processed) = &p.d.processed else { return Ok(()) };
    let t = &processed.built.table;
    let u = p.d.uncertainty.as_ref().map(|b| rounding::show_u(crate::units::Units::Deg, b.table_u_deg));
    let u = u.as_deref().map(decimal);
    let h = t.spacing_deg();
    let readouts: Vec<String> = (0..t.len()).map(|i| format!("{}", i as f64 * h)).collect();
    x.open("dcc:result", &[("refType", "survey_correctionTable")])?;
    x.words("dcc:name", "Correction table")?;
    x.words(
        "dcc:description",
        &format!(
            "{} rows every {h} deg of readout, from 0, wrapping at 360 deg; the corrected angle is readout - \
             error(readout), read with linear interpolation between rows; the uncertainty is the table's as a \
             correction of the positioner (k = 2).",
            t.len()
        ),
    )?;
    x.open("dcc:data", &[])?;
    x.open("dcc:list", &[("refType", "survey_table")])?;
    x.list("survey_readout", "readout", &readouts, DEGREE, None)?;
    let columns: &[(Direction, &str, &str)] = if t.is_directional() {
        &[
            (Direction::Forward, "survey_errorForward", "error, forward"),
            (Direction::Reverse, "survey_errorReverse", "error, reverse"),
        ]
    } else {
        &[(Direction::Forward, "survey_error", "error (both directions)")]
    };
    // Each value to the table's U's decimal place, as the page's excerpt (one rounding).
    let table_u = p.d.uncertainty.as_ref().map(|b| b.table_u_deg);
    x.distribution = TABLE_DISTRIBUTION;
    for (d, ref_type, name) in columns {
        let values: Vec<String> = (0..t.len())
            .map(|i| rounding::num(crate::units::Units::Deg, t.error_at(i as f64 * h, *d), table_u))
            .collect();
        x.list(ref_type, name, &values, DEGREE, u.as_deref())?;
    }
    x.distribution = NORMAL;
    x.close("dcc:list")?;
    x.close("dcc:data")?;
    x.close("dcc:result")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 50: a calibration (not a rehearsal) whose reference has a
    /// calibration certificate names it in the DCC, as an identification of
    /// the equipment, beside its serial number and in its description.
    #[test]
    fn a_calibrations_reference_carries_its_certificate_as_an_identification() {
        let survey = crate::certificate::tests::configured_survey();
        assert_eq!(survey.rehearsal(), None, "a configured bench's survey is a calibration");
        let cert = crate::certificate::Certificate::of(&survey, &Default::default());
        assert_eq!(cert.rehearsal, None);
        let mut x = Xml { w: Writer::new(Vec::new()), distribution: NORMAL };
        measuring_equipment(&mut x, &cert).unwrap();
        let xml = String::from_utf8(x.w.into_inner()).unwrap();
        let identification = "<dcc:identification><dcc:issuer>calibrationLaboratory</dcc:issuer>\
                              <dcc:value>5678</dcc:value><dcc:name><dcc:content lang=\"en\">certificate of its \
                              calibration</dcc:content></dcc:name></dcc:identification>";
        assert!(xml.contains(identification), "{xml}");
        assert!(xml.contains("<dcc:value>7788</dcc:value>"), "its serial number: {xml}");
        assert!(xml.contains("calibration certificate 5678 by the national metrology institute"), "{xml}");
        assert!(xml.contains("refType=\"survey_referenceStandardUncertainty\""), "{xml}");
        // A rehearsal of the same bench claims none.
        let mut x = Xml { w: Writer::new(Vec::new()), distribution: NORMAL };
        measuring_equipment(&mut x, &cert.rehearsal_of("a test".into())).unwrap();
        let xml = String::from_utf8(x.w.into_inner()).unwrap();
        assert!(!xml.contains("5678") && xml.contains("<dcc:value>7788</dcc:value>"), "{xml}");
    }

    #[test]
    fn the_performance_location_follows_the_location_stated() {
        assert_eq!(performance_location(Some("Metrology Lab North, room 2 (permanent laboratory)")), "laboratory");
        assert_eq!(performance_location(Some("at the customer's site, ACME Ltd")), "customer");
        assert_eq!(performance_location(Some("Customer branch office, Leeds")), "customerBranch");
        assert_eq!(performance_location(Some("Bay 3")), "other");
        assert_eq!(performance_location(Some("Lab North, site B")), "laboratory");
        // Stated in the configuration, it is what the configuration says.
        let mut survey = crate::certificate::tests::configured_survey();
        let words = Some("Bay 3");
        assert_eq!(performed_at(&survey, words), "other");
        if let survey_store::survey::Setup::Configured(c) = &mut survey.setup {
            c.config.certificate.as_mut().unwrap().performance_location = Some("customerBranch".into());
        }
        assert_eq!(performed_at(&survey, words), "customerBranch");
        assert_eq!(performance_location(Some("on site at ACME, hall 4")), "customer");
        assert_eq!(performance_location(Some("Site B")), "other");
        assert_eq!(performance_location(None), "other");
    }
}
