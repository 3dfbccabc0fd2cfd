//! `DIR/dcc.xml`, the certificate as PTB's Digital Calibration Certificate
//! 3.2.0: every DCC these tests write is validated against the schema in
//! `../shared/data/dcc` by the PyPI package `xmlschema` (an implementation
//! no one here wrote; `tests/dcc/validate.py`), and its values are those of
//! `survey stats --json` and `survey process --json`.
//!
//! Without python3, `xmlschema` or the schema the validation cannot run: in
//! CI (`CI` set; `.ci/run` installs `xmlschema`) that fails the test, elsewhere
//! the test says why and returns.

use super::Bench;
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/dcc/validate.py");

/// The schema's folder beside the repository.
fn schema_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/dcc"))
}

/// Why the validation cannot run here, if it cannot; in CI that is a failure.
pub(crate) fn validator_missing() -> Option<String> {
    let why = if !schema_dir().join("dcc_3_2_0.xsd").is_file() {
        Some(format!("the DCC schema is not at {}", schema_dir().display()))
    } else {
        match Command::new("python3").args(["-c", "import xmlschema"]).output() {
            Err(e) => Some(format!("python3 cannot be started ({e})")),
            Ok(out) if !out.status.success() => Some(format!(
                "xmlschema is not installed for python3 (`python3 -m pip install xmlschema==4.3.2`): {}",
                String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
            )),
            Ok(_) => None,
        }
    };
    if let Some(why) = &why
        && std::env::var_os("CI").is_some()
    {
        panic!("CI must validate every DCC written, but {why}");
    }
    why
}

/// Validate the DCCs `files` (paths in `bench`); panics with the schema's errors.
pub(crate) fn validate(bench: &Bench, files: &[&str]) {
    let out = Command::new("python3")
        .arg(SCRIPT)
        .arg(schema_dir())
        .args(files.iter().map(|f| bench.path(f)))
        .output()
        .expect("python3 runs the validator");
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "a DCC is not valid against DCC 3.2.0:\n{text}");
    assert_eq!(text.matches(": 0 errors").count(), files.len(), "{text}");
}

/// The text of the first `<tag>` in the quantity whose refType list (`refType="a b"`) holds `ref_type` in `xml`.
fn after(xml: &str, ref_type: &str, tag: &str) -> Option<String> {
    let rest = xml
        .split("refType=\"")
        .skip(1)
        .find(|r| r.split('"').next().is_some_and(|l| l.split(' ').any(|t| t == ref_type)))?;
    let end = rest.find("</dcc:quantity>").unwrap_or(rest.len());
    let inner = rest[..end].split(&format!("<{tag}>")).nth(1)?;
    Some(inner.split(&format!("</{tag}>")).next()?.to_string())
}

/// The DCC's figure `ref_type` equals `expected` as ILAC-P14 rounds it: to
/// the decimal place of its U (the value's own digits when it has none).
fn assert_equal(xml: &str, ref_type: &str, expected: f64) {
    let value = after(xml, ref_type, "si:value").unwrap_or_else(|| panic!("{ref_type} is in the DCC"));
    let v: f64 = value.parse().unwrap_or_else(|_| panic!("{ref_type}: {value} is a number"));
    let places = |s: &str| s.split('.').nth(1).map_or(0, |d| d.len()) as i32;
    let place = after(xml, ref_type, "si:uncertainty").map_or(places(&value), |u| places(&u));
    let half = 0.5 * 10f64.powi(-place) + 1e-12;
    assert!((v - expected).abs() <= half, "{ref_type}: the DCC's {value} against {expected} (to 1e-{place})");
}

#[test]
fn every_dcc_written_validates_against_the_dcc_3_2_0_schema() {
    let bench = Bench::new();
    // A verified survey: the corrected figures measured are in the DCC too.
    bench.survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--verify", "--json"]).success();
    // Every field stated, a tolerance and its verdict, another unit on the page.
    bench
        .survey(&[
            "report",
            "--survey",
            "1",
            "--out",
            "full",
            "--units",
            "arcsec",
            "--certificate-number",
            "CAL-2026-0042 <&>",
            "--laboratory",
            "Metrology Lab \"North\", 1 Bay Road",
            "--customer",
            "ACME Ltd, 2 Dock St",
            "--signatory",
            "A. Jones, head of the laboratory",
            "--operator",
            "J. Smith",
            "--location",
            "Bay 3",
            "--item-condition",
            "as received, no damage",
            "--received",
            "2026-11-20",
            "--country",
            "GB",
            "--temperature",
            "20.3",
            "--tolerance",
            "0.05",
        ])
        .success();
    // Nothing stated but what the bench knows; the verification survey itself.
    // (Survey 1's certificate is issued: a second is an amendment.)
    bench.survey(&["report", "--survey", "1", "--out", "bare", "--amend", "nothing stated"]).success();
    bench.survey(&["report", "--survey", "2", "--out", "verification"]).success();
    // An autocollimator survey measured one way: no reversal, no M.
    bench.survey(&["run", "--points", "24", "--runs", "2", "--reference", "autocollimator"]).success();
    bench.survey(&["report", "--out", "one-way"]).success();
    let full = bench.read("full/dcc.xml");
    assert!(full.contains("<dcc:uniqueIdentifier>CAL-2026-0042 &lt;&amp;&gt;</dcc:uniqueIdentifier>"), "escaped");
    for words in [
        "<dcc:receiptDate>2026-11-20</dcc:receiptDate>",
        "<dcc:countryCodeISO3166_1>GB</dcc:countryCodeISO3166_1>",
        ">A. Jones, head of the laboratory</dcc:content>",
        "<dcc:mainSigner>true</dcc:mainSigner>",
        ">ACME Ltd, 2 Dock St</dcc:content>",
        "<dcc:norm>ISO 230-2:2014</dcc:norm>",
        "<dcc:norm>ILAC-G8:09/2019</dcc:norm>",
        "<si:unit>\\degreecelsius</si:unit>",
        "<si:unit>\\degree</si:unit>",
        "<si:coverageFactor>2</si:coverageFactor>",
        "<si:coverageProbability>0.9545</si:coverageProbability>",
        "<si:distribution>normal</si:distribution>",
        "<si:distribution>other: a normal part plus the sinusoids the table may leave",
        " survey_correctedAMeasured\"",
        // PTB's refTypes beside ours: the measured values, the tolerance as the upper acceptance limit.
        "refType=\"basic_measuredValue survey_iso230_2_A\"",
        "refType=\"basic_acceptanceLimitUpper survey_toleranceA\"",
        "<si:realListXMLList>",
    ] {
        assert!(full.contains(words), "the DCC should hold {words}");
    }
    // No address stated: the customer is named once, its location says so (never the name again).
    assert_eq!(full.matches(">ACME Ltd, 2 Dock St</dcc:content>").count(), 1, "the customer named once");
    let customer = full.split("<dcc:customer>").nth(1).and_then(|c| c.split("</dcc:customer>").next()).unwrap();
    assert!(customer.contains(">postal address not stated</dcc:content>"), "{customer}");
    let bare = bench.read("bare/dcc.xml");
    assert!(!bare.contains("mainSigner"), "no main signer when none is stated");
    // The reference's uncertainty as a quantity; the location "Bay 3" says neither laboratory nor customer.
    assert!(after(&full, "survey_referenceStandardUncertainty", "si:value").is_some());
    assert!(full.contains("<dcc:performanceLocation>other</dcc:performanceLocation>"));
    assert_eq!(after(&full, "basic_acceptanceLimitUpper", "si:value").as_deref(), Some("0.05"));
    assert!(bare.contains("<dcc:countryCodeISO3166_1>ZZ</dcc:countryCodeISO3166_1>"));
    assert!(bare.contains("refType=\"basic_temperatureMax\"") && bare.contains("<si:unit>\\hecto\\pascal</si:unit>"));
    let one_way = bench.read("one-way/dcc.xml");
    assert!(!one_way.contains("survey_iso230_2_M"), "no M measured one way");
    assert!(one_way.contains(">not measured</dcc:content>"), "an autocollimator measures no air");
    if let Some(why) = validator_missing() {
        println!("skipped the validation: {why}");
        return;
    }
    validate(&bench, &["full/dcc.xml", "bare/dcc.xml", "verification/dcc.xml", "one-way/dcc.xml"]);
}

#[test]
fn the_dccs_values_are_survey_stats_and_process() {
    let bench = Bench::new();
    bench.survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--verify", "--json"]).success();
    bench.survey(&["report", "--survey", "1", "--out", "r", "--certificate-number", "CAL-7"]).success();
    let xml = bench.read("r/dcc.xml");
    assert!(xml.contains("<dcc:uniqueIdentifier>CAL-7</dcc:uniqueIdentifier>"));
    let stats = bench.stats_json(Some(1));
    let iso = &stats["iso230_2"];
    for (key, ref_type) in [
        ("A", "survey_iso230_2_A"),
        ("R", "survey_iso230_2_R"),
        ("B", "survey_iso230_2_B"),
        ("E", "survey_iso230_2_E"),
        ("M", "survey_iso230_2_M"),
    ] {
        assert_equal(&xml, ref_type, iso[key].as_f64().unwrap_or_else(|| panic!("stats' {key}")));
    }
    // One rounding (ILAC-P14): the page states each figure as the DCC does, to the place of the U beside it.
    let page = bench.read("r/index.html");
    for (row, ref_type) in [
        ("A, accuracy", "survey_iso230_2_A"),
        ("R, repeatability", "survey_iso230_2_R"),
        ("E, systematic positional deviation", "survey_iso230_2_E"),
        ("M, mean positional deviation", "survey_iso230_2_M"),
        ("B, reversal value", "survey_iso230_2_B"),
    ] {
        let shown = page.split(&format!("{row}</td><td>")).nth(1).and_then(|s| s.split('<').next()).unwrap();
        assert_eq!(Some(shown.to_string()), after(&xml, ref_type, "si:value"), "{row}: the page and the DCC");
    }
    // VDI/DGQ 3441's figures too (its U and Ū, reversal spans, to the same place: issue 50).
    for (row, ref_type) in [
        ("P, positional uncertainty", "survey_vdi3441_P"),
        ("Pa, position deviation", "survey_vdi3441_Pa"),
        ("Ps, largest positional scatter", "survey_vdi3441_Ps"),
        ("U, largest reversal span", "survey_vdi3441_U"),
        ("Ū, mean reversal span", "survey_vdi3441_Umean"),
    ] {
        let shown = page.split(&format!("{row}</td><td>")).nth(1).and_then(|s| s.split('<').next()).unwrap();
        assert_eq!(Some(shown.to_string()), after(&xml, ref_type, "si:value"), "{row}: the page and the DCC");
    }
    // The table's hysteresis is B, rounded as B is; the air as the page states it.
    let b = after(&xml, "survey_iso230_2_B", "si:value").unwrap();
    assert!(page.contains(&format!("ysteresis max {b} deg ")), "the hysteresis as B, {b}");
    let (t_min, t_max) = (
        after(&xml, "basic_temperatureMin", "si:value").expect("the air measured"),
        after(&xml, "basic_temperatureMax", "si:value").unwrap(),
    );
    assert!(page.contains(&format!("air temperature {t_min} to {t_max} °C")), "{t_min} to {t_max} on the page");
    for (ref_type, places) in [("basic_temperatureMin", 2), ("basic_pressureMax", 1), ("basic_humidityRelativeMin", 3)]
    {
        let v = after(&xml, ref_type, "si:value").unwrap();
        assert_eq!(v.split('.').nth(1).map_or(0, str::len), places, "{ref_type} {v}: as the page rounds it");
    }
    for ref_type in ["survey_nativePeak", "survey_correctedPeakPredicted"] {
        let (v, u) = (after(&xml, ref_type, "si:value").unwrap(), after(&xml, ref_type, "si:uncertainty").unwrap());
        assert!(page.contains(&format!("<td>{v} deg</td><td>{u} deg")), "{ref_type} {v} ± {u} on the page");
    }
    // Each way, as stats says; the mean error at every target and direction, found by PTB's refTypes.
    for (key, ref_type) in [
        ("A_up", "survey_iso230_2_A_forward"),
        ("A_down", "survey_iso230_2_A_reverse"),
        ("R_up", "survey_iso230_2_R_forward"),
        ("E_down", "survey_iso230_2_E_reverse"),
    ] {
        assert_equal(&xml, ref_type, iso[key].as_f64().unwrap_or_else(|| panic!("stats' {key}")));
    }
    assert!(after(&xml, "survey_vdi3441_P", "si:uncertainty").is_some(), "VDI/DGQ 3441's P with U");
    let targets = after(&xml, "basic_referenceValue", "si:valueXMLList").expect("the targets");
    assert_eq!(targets.split_whitespace().count(), 72, "one a target");
    let errors = xml.matches("refType=\"basic_measurementError survey_meanError").count();
    assert_eq!(errors, 2, "forward and reverse");
    let forward = after(&xml, "survey_meanErrorForward", "si:valueXMLList").unwrap();
    assert_eq!(forward.split_whitespace().count(), 72);
    // The budget as process --json gives it: each contribution, by its source.
    let entries = xml.matches("refType=\"survey_budgetEntry\"").count();
    assert_eq!(entries, process_budget_len(&bench), "one quantity a contribution");
    // A, E and M carry the measurement's U; the corrected A is the verification survey's.
    assert!(after(&xml, "survey_iso230_2_A", "si:uncertainty").is_some());
    assert_equal(&xml, "survey_correctedAMeasured", bench.stats_json(Some(2))["iso230_2"]["A"].as_f64().unwrap());
    // The predictions and the table are `survey process`'s.
    let process: Value = bench.survey(&["process", "--survey", "1", "--json"]).success().json();
    let predicted = &process["predicted"];
    assert_equal(&xml, "survey_nativePeak", predicted["native_peak_deg"].as_f64().unwrap());
    assert_equal(&xml, "survey_correctedPeakPredicted", predicted["corrected_peak_deg"].as_f64().unwrap());
    let table_u = process["uncertainty"]["table_u_deg"].as_f64().unwrap();
    let stated_u: f64 = after(&xml, "survey_correctedPeakPredicted", "si:uncertainty").unwrap().parse().unwrap();
    assert!(stated_u >= table_u && stated_u < 1.1 * table_u + 1e-9, "U rounded up: {stated_u} against {table_u}");
    let readouts = after(&xml, "survey_readout", "si:valueXMLList").expect("the table's readouts");
    let rows = process["table"]["points"].as_u64().unwrap() as usize;
    assert_eq!(readouts.split_whitespace().count(), rows, "one readout a row of the table");
    // The table's values are the CSV's, row by row, each rounded to the decimal place of the table's U.
    let path = process["table"]["path"].as_str().unwrap();
    let csv = std::fs::read_to_string(bench.path(path)).unwrap();
    let (column, list) = ["survey_errorForward", "survey_error"]
        .iter()
        .find_map(|r| Some((*r, after(&xml, r, "si:valueXMLList")?)))
        .expect("the table's errors");
    let u = after(&xml, column, "si:uncertaintyXMLList").expect("the table's U");
    let half = 0.5 * 10f64.powi(-(u.split('.').nth(1).map_or(0, str::len) as i32)) + 1e-12;
    for (line, value) in csv.lines().skip(1).zip(list.split_whitespace()) {
        let in_csv: f64 = line.split(',').nth(1).unwrap().parse().unwrap();
        let in_dcc: f64 = value.parse().unwrap();
        assert!((in_csv - in_dcc).abs() <= half, "{line} against {value} (U {u})");
        assert!(value == "0" || value.split('.').nth(1).map_or(0, str::len) == u.split('.').nth(1).map_or(0, str::len));
    }
}

/// A verification survey's own `U` carries the tracker's systematic part
/// (issue 48): it measures around its calibration's axis with the same
/// tracker, whose error repeats at each place; before, with no axis of its
/// own, its budget had no such row and its `U` was the random part alone
/// (2 x 2.27e-4 deg). `process --survey 2`'s budget names the part, as the
/// calibration's does through the same axis over the same circle (equal
/// to 1 %); its `reference_error` says it was not separated; the report's
/// `A` and the DCC's state a `U` of at least twice that part (`U = 2 sqrt(
/// random^2 + systematic^2 + axis^2)`), and the report's budget shows the row.
#[test]
fn a_verification_survey_s_own_u_carries_the_tracker_s_systematic_part() {
    let bench = Bench::new();
    // Evenly spaced verification targets (72, between the 36), so that
    // `process` can make a table of the verification too; whether the
    // verification confirms (exit 0) or not (exit 1) is not this test's.
    let out = bench.survey(&["run", "--points", "36", "--runs", "2", "--verify", "--verify-points", "72", "--json"]);
    assert!(out.code == 0 || out.code == 1, "{out}");
    let systematic_of = |id: &str| -> f64 {
        let p: Value = bench.survey(&["process", "--survey", id, "--json"]).success().json();
        p["uncertainty"]["budget"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["source"] == "reference instrument, systematic")
            .unwrap_or_else(|| panic!("survey {id}: no systematic part in {}", p["uncertainty"]))["u_deg"]
            .as_f64()
            .unwrap()
    };
    let (calibration, verification) = (systematic_of("1"), systematic_of("2"));
    assert!(verification > 1e-4, "the tracker's MPE through the default arm: {verification}");
    assert!((verification / calibration - 1.0).abs() < 0.01, "{verification} against {calibration}");
    let p: Value = bench.survey(&["process", "--survey", "2", "--json"]).success().json();
    let r = &p["reference_error"];
    assert_eq!((&r["separated"], &r["method"]), (&Value::Bool(false), &Value::from("none")), "{r}");
    assert!((r["u_deg"].as_f64().unwrap() / verification - 1.0).abs() < 1e-9, "{r}");
    bench.survey(&["report", "--out", "v"]).success();
    let xml = bench.read("v/dcc.xml");
    let u: f64 = after(&xml, "survey_iso230_2_A", "si:uncertainty").expect("A's U").parse().unwrap();
    assert!(u >= 2.0 * verification, "the verification's U {u} against its systematic part {verification}");
    let page = bench.read("v/index.html");
    assert!(page.contains("reference instrument, systematic"), "the budget's row on the verification's report");
}

/// Every element's text of `xml`, as a parser reads it back (quick-xml,
/// end names checked); panics if it is not well-formed or holds a character
/// a certificate cannot print.
fn texts(xml: &str) -> Vec<String> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(xml);
    reader.config_mut().check_end_names = true;
    let (mut out, mut text, mut depth) = (Vec::new(), String::new(), 0usize);
    loop {
        match reader.read_event().unwrap_or_else(|e| panic!("the DCC is not well-formed: {e}")) {
            Event::Eof => break,
            Event::Start(_) => {
                depth += 1;
                text.clear();
            }
            Event::End(_) => {
                depth -= 1;
                out.push(std::mem::take(&mut text));
            }
            Event::Text(t) => text += &t.xml10_content(),
            Event::GeneralRef(r) => {
                let entity = format!("&{};", r.xml10_content());
                text += &quick_xml::escape::unescape(&entity).unwrap_or_else(|e| panic!("{entity}: {e}"));
            }
            _ => {}
        }
    }
    assert_eq!(depth, 0, "every element closed");
    for t in &out {
        assert!(!t.chars().any(|c| c.is_control() && c != '\n' && c != '\t'), "a control character in {t:?}");
    }
    out
}

#[test]
fn hostile_fields_are_refused_or_written_as_they_read() {
    let bench = Bench::new();
    bench.survey(&["run", "--points", "24", "--runs", "2", "--reference", "autocollimator"]).success();
    // What XML must escape, what looks like markup, right-to-left and astral characters, a field at the limit.
    let long = "x".repeat(400);
    let fields = [
        ("--customer", "ACME <Ltd> & \"Sons\" 'n' ]]> --> <!-- &amp;"),
        ("--operator", "J. Smith \u{202E}evil\u{202C} \u{1F600}"),
        ("--laboratory", "<?xml version=\"1.0\"?><dcc:x/>"),
        ("--signatory", "A. Jones &#0; &lt; head"),
        ("--location", long.as_str()),
        ("--certificate-number", "CAL <1> & 2"),
    ];
    for (i, (flag, value)) in fields.iter().enumerate() {
        let (out, reason) = (format!("h{i}"), format!("field {i} stated"));
        // The first issues the certificate, each other amends it.
        let amend: &[&str] = if i == 0 { &[] } else { &["--amend", &reason] };
        bench.survey(&[&["report", "--out", &out, flag, value][..], amend].concat()).success();
        let read = texts(&bench.read(&format!("{out}/dcc.xml")));
        assert!(read.iter().any(|t| t.contains(value)), "{flag} {value:?} read back as written");
        let html = bench.read(&format!("{out}/index.html"));
        assert!(!html.contains(value) || !value.contains('<'), "{flag}: HTML escaped");
    }
    // What cannot be printed: refused, exit 2, nothing written.
    let too_long = "y".repeat(401);
    for (flag, value, words) in [
        ("--operator", "J. Smith\u{7}", "U+0007"),
        // (A NUL cannot be an argument: the configuration's case below.)
        ("--customer", "a\u{1b}[31mb", "U+001B"),
        ("--laboratory", "Lab\nNorth", "U+000A"),
        ("--location", "Bay\t3", "U+0009"),
        ("--traceability", too_long.as_str(), "401 characters long: a certificate's field holds at most 400"),
        ("--signatory", "   ", "is empty"),
        ("--certificate-number", &"9".repeat(65), "at most 64"),
    ] {
        bench.survey(&["report", "--out", "refused", flag, value]).bad_input(&[flag, words]);
        assert!(!bench.exists("refused"), "{flag} wrote something");
    }
    // The same in a configuration's [certificate]: its file, line and key, before anything is stored.
    let example = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/config/modbus-emscon.toml"))
        .expect("the example configuration");
    for (line, words) in [
        (
            "operator = \"J. Smith\\u0007\"",
            "c.toml:37: certificate.operator: \"J. Smith\\u0007\" holds the control character U+0007",
        ),
        ("operator = \"\"", "c.toml:37: certificate.operator: \"\" is empty"),
        (
            "operator = \"a\\u0000b\"",
            "c.toml:37: certificate.operator: \"a\\u0000b\" holds the control character U+0000",
        ),
        (&format!("operator = \"{too_long}\""), "c.toml:37: certificate.operator: \"yyyy"),
    ] {
        bench.write("c.toml", example.replace("operator = \"J. Smith\"", line));
        let out = bench.survey(&["run", "--config", "c.toml"]).bad_input(&[words]);
        if line.len() > 400 {
            out.bad_input(&["is 401 characters long"]);
        }
        assert!(!bench.exists("survey.db") || bench.stored().len() == 1, "nothing stored");
    }
    bench.write("c.toml", example.replace("signatory = \"A. Jones", "signatory = \"\" # \"A. Jones"));
    bench.survey(&["run", "--config", "c.toml"]).bad_input(&["c.toml:41: certificate.signatory: \"\" is empty"]);
    bench.write("c.toml", example.replace("192.168.1.40:502", "192.168.1.40:502\\u001b"));
    bench.survey(&["run", "--config", "c.toml"]).bad_input(&["positioner.address", "U+001B"]);
}

/// How many contributions `survey process --survey 1 --json`'s budget has.
fn process_budget_len(bench: &Bench) -> usize {
    let process: Value = bench.survey(&["process", "--survey", "1", "--json"]).success().json();
    process["uncertainty"]["budget"].as_array().map_or(0, Vec::len)
}

/// The DCC's `uniqueIdentifier`.
fn number_of(xml: &str) -> String {
    xml.split("<dcc:uniqueIdentifier>").nth(1).and_then(|s| s.split('<').next()).expect("a number").to_string()
}

#[test]
fn a_certificate_is_issued_once_and_amended_by_a_new_one() {
    let bench = Bench::new();
    bench.small_survey(true);
    let first = bench.survey(&["report", "--out", "a"]).success();
    assert!(first.stderr.contains(" issued "), "{first}");
    let (page, dcc) = (bench.read("a/index.html"), bench.read("a/dcc.xml"));
    // Unique across databases and stations: the survey's date and the first 12 digits of its uid.
    let uid = bench.survey(&["show", "--json"]).success().json()["uid"].as_str().unwrap().replace('-', "");
    let number = number_of(&dcc);
    assert!(number.len() == 21 && number.ends_with(&uid[..12]), "{number} of the uid {uid}");
    assert!(page.contains(&format!("certificate <b>{number}</b>")));
    // Later reports reproduce it byte for byte (the issue date included).
    std::thread::sleep(std::time::Duration::from_millis(1100));
    let again = bench.survey(&["report", "--out", "b"]).success();
    assert!(again.stderr.contains("as issued"), "{again}");
    assert!(bench.read("b/index.html") == page && bench.read("b/dcc.xml") == dcc, "reproduced byte for byte");
    // Asking for what it was issued with is no change; another unit would be.
    bench.survey(&["report", "--out", "b", "--units", "deg"]).success();
    bench
        .survey_with_env(&["report", "--out", "c"], "SURVEY_UNITS", "arcsec")
        .bad_input(&["--units (or SURVEY_UNITS)"]);
    // What would change it is refused: exit 2, nothing written.
    bench
        .survey(&["report", "--out", "c", "--operator", "K. Lee"])
        .bad_input(&["--operator would change it", "--amend"]);
    assert!(!bench.exists("c"));
    // An amendment: a new number naming the one it replaces, when it was issued and why.
    let amended = bench
        .survey(&["report", "--out", "d", "--operator", "K. Lee", "--amend", "the operator was not stated"])
        .success();
    assert!(amended.stderr.contains("an amendment"), "{amended}");
    let (page_d, dcc_d) = (bench.read("d/index.html"), bench.read("d/dcc.xml"));
    assert_eq!(number_of(&dcc_d), format!("{number}-A1"));
    assert!(page_d.contains(&format!("This certificate replaces certificate <b>{number}</b> issued 20")), "{page_d}");
    assert!(page_d.contains("Reason: the operator was not stated") && page_d.contains("K. Lee"));
    let previous = texts(&dcc_d);
    assert!(previous.contains(&number), "previousReport's referralID");
    assert!(previous.iter().any(|t| t.len() == 64 && t.chars().all(|c| c.is_ascii_hexdigit())), "its SHA-256");
    assert!(dcc_d.contains("refType=\"survey_amendment\"") && dcc_d.contains("<dcc:reference>7.8.8</dcc:reference>"));
    bench.survey(&["report", "--out", "e"]).success();
    assert!(bench.read("e/dcc.xml") == dcc_d, "the current certificate is the amendment");
    // A folder the files cannot go to: refused before the certificate is issued.
    bench.small_survey(true);
    bench.write("file", "not a folder");
    bench.survey(&["report", "--survey", "2", "--out", "file/r"]).bad_input(&["--out file/r", "is not a folder"]);
    // Nothing to amend before a certificate is issued (survey 2's was not); a number is issued once in a store.
    bench.survey(&["report", "--survey", "2", "--out", "f", "--amend", "x"]).bad_input(&["no certificate issued"]);
    bench
        .survey(&["report", "--survey", "2", "--out", "f", "--certificate-number", &number])
        .bad_input(&[&format!("certificate number {number} is issued already (to survey 1)")]);
    assert!(!bench.exists("f"));
    // The same survey in another database (the same seed, the same samples): another uid, another number.
    let other = Bench::new();
    other.small_survey(true);
    other.survey(&["report", "--out", "a"]).success();
    assert_ne!(number_of(&other.read("a/dcc.xml")), number, "two databases, two numbers");
    if validator_missing().is_none() {
        validate(&bench, &["a/dcc.xml", "d/dcc.xml"]);
    }
}
