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
fn validator_missing() -> Option<String> {
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
fn validate(bench: &Bench, files: &[&str]) {
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

/// The text of the first `<tag>` after `refType="ref"` in `xml`.
fn after(xml: &str, ref_type: &str, tag: &str) -> Option<String> {
    let rest = xml.split(&format!("refType=\"{ref_type}\"")).nth(1)?;
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
    bench.survey(&["report", "--survey", "1", "--out", "bare"]).success();
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
        "<si:coverageProbability>0.95</si:coverageProbability>",
        "refType=\"survey_correctedAMeasured\"",
        "<si:realListXMLList>",
    ] {
        assert!(full.contains(words), "the DCC should hold {words}");
    }
    let bare = bench.read("bare/dcc.xml");
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
    // The table's values are the CSV's, row by row.
    let path = process["table"]["path"].as_str().unwrap();
    let csv = std::fs::read_to_string(bench.path(path)).unwrap();
    let forward = after(&xml, "survey_errorForward", "si:valueXMLList")
        .or_else(|| after(&xml, "survey_error", "si:valueXMLList"))
        .expect("the table's errors");
    for (line, value) in csv.lines().skip(1).zip(forward.split_whitespace()) {
        let in_csv: f64 = line.split(',').nth(1).unwrap().parse().unwrap();
        let in_dcc: f64 = value.parse().unwrap();
        assert!((in_csv - in_dcc).abs() <= 1e-9, "{line} against {value}");
    }
}
