//! The configuration file: parsing, ranges, defects named with their file and line, timing overrides.

use super::*;

#[test]
fn the_example_files_parse() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/config");
    let mut seen = 0;
    for entry in std::fs::read_dir(dir).expect("examples/config exists") {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            SurveyConfig::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
            seen += 1;
        }
    }
    assert!(seen >= 5, "at least one example per driver");
}

fn error_of(text: &str) -> String {
    SurveyConfig::parse(text, "c.toml").unwrap_err().to_string()
}

const TRACKER_BENCH: &str = "[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n\
    [tracker]\ndriver = \"emscon\"\naddress = \"h:700\"\n";

#[test]
fn the_asset_section_names_the_surveys_asset_and_is_checked() {
    use crate::survey::{ConfiguredSetup, Setup};
    let plan = survey_plan::SurveyPlan::full_circle(36, 2, true).unwrap();
    let setup = |config| Setup::Configured(ConfiguredSetup { config, plan: plan.clone() });
    let cfg = SurveyConfig::parse(&format!("{TRACKER_BENCH}[asset]\nid = \"bay-2/az\"\n"), "c.toml").unwrap();
    assert_eq!(setup(cfg.clone()).default_asset(), "bay-2/az");
    // Stored with the survey and read back.
    let text = serde_json::to_string(&cfg).unwrap();
    assert_eq!(serde_json::from_str::<SurveyConfig>(&text).unwrap(), cfg);
    let without = SurveyConfig::parse(TRACKER_BENCH, "c.toml").unwrap();
    assert_eq!(setup(without).default_asset(), crate::asset::UNASSIGNED);
    let e = error_of(&format!("{TRACKER_BENCH}[asset]\nid = \"bay 2\"\n"));
    assert!(e.starts_with("c.toml: [asset] id: the asset id 'bay 2' holds ' '"), "{e}");
    assert!(error_of(&format!("{TRACKER_BENCH}[asset]\nname = \"x\"\n")).contains("unknown field `name`"));
}

#[test]
fn every_number_is_finite_and_within_its_stated_range() {
    assert!(SurveyConfig::parse(TRACKER_BENCH, "c.toml").is_ok());
    for (extra, key) in [
        ("[timing]\ncall_timeout_s = 1e19\n", "timing.call_timeout_s = 1e19 is outside"),
        ("[timing]\nretry_backoff_s = 2e19\n", "timing.retry_backoff_s"),
        ("[timing]\ndwell_s = 1e19\n", "timing.dwell_s"),
        ("[timing]\npoll_interval_s = 0\n", "timing.poll_interval_s = 0 is outside its range (above 0"),
        ("[timing]\nmax_retries = 4000000000\n", "timing.max_retries"),
        ("[timing]\nlocate_points = 2\n", "timing.locate_points"),
        ("[timing]\ntime_scale = 0\n", "timing.time_scale = 0 is outside its range (above 0"),
        ("[timing]\ntime_scale = 20000\n", "timing.time_scale = 20000 is outside"),
        ("[survey]\noverrun_deg = 45.0\n", "survey.overrun_deg = 45 is outside"),
        ("[survey]\ntravel_deg = [-1e9, 90.0]\n", "survey.travel_deg[0]"),
        ("[arm]\nradius_mm = 500.0\nradius_tolerance_mm = 600.0\n", "arm.radius_tolerance_mm"),
        ("[certificate]\ntemperature_c = 293.15\n", "certificate.temperature_c = 293.15 is outside"),
        ("[certificate]\nreference_uncertainty_deg = 0\n", "certificate.reference_uncertainty_deg = 0 is outside"),
        ("[certificate]\ntolerance_deg = -0.01\n", "certificate.tolerance_deg = -0.01 is outside"),
        ("[certificate]\nreceived = \"2026-02-30\"\n", "certificate.received = \"2026-02-30\": not a date"),
        ("[certificate]\nreceived = \"1 May 2026\"\n", "certificate.received = \"1 May 2026\": not a date"),
        ("[certificate]\ncountry = \"de\"\n", "certificate.country = \"de\": not an ISO 3166-1"),
        ("[certificate]\ncountry = \"XX\"\n", "certificate.country = \"XX\": not an ISO 3166-1"),
    ] {
        let e = error_of(&format!("{TRACKER_BENCH}{extra}"));
        assert!(e.starts_with("c.toml: ") && e.contains(key), "{extra}: {e}");
    }
    // nan and inf anywhere, with the key and the line.
    for (extra, want) in [
        ("[survey]\noverrun_deg = nan\n", "line 8: survey.overrun_deg is not a finite number"),
        ("[timing]\ndwell_s = inf\n", "line 8: timing.dwell_s is not a finite number"),
        ("[timing]\ndwell_s = -inf\n", "timing.dwell_s is not a finite number"),
        ("[arm]\nradius_mm = nan\n", "arm.radius_mm is not a finite number"),
    ] {
        let e = error_of(&format!("{TRACKER_BENCH}{extra}"));
        assert!(e.contains(want), "{extra}: {e}");
    }
    let e =
        error_of(&TRACKER_BENCH.replace("address = \"h:700\"\n", "address = \"h:700\"\napprox_distance_mm = nan\n"));
    assert!(e.contains("tracker.approx_distance_mm is not a finite number"), "{e}");
}

#[test]
fn defects_are_named_with_the_file_and_line() {
    let e = error_of("[positioner]\ndriver = \"warp-drive\"\naddress = \"x\"\n");
    assert!(e.starts_with("c.toml: line 2") && e.contains("warp-drive"), "{e}");
    let e = error_of("[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\nadress = \"x\"\n\n[tracker]\n");
    assert!(e.contains("adress"), "{e}");
    let e = error_of("[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n");
    assert!(e.contains("no [tracker] section"), "{e}");
    let e = error_of(
        "[survey]\nreference = \"autocollimator\"\n[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"/dev/ttyS0\"\n[polygon]\nfaces = 4\ncertificate_arcsec = [0.1]\n",
    );
    assert!(e.contains("1 values for 4 faces"), "{e}");
    let e = error_of(
        "[survey]\nreference = \"autocollimator\"\n[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"/dev/ttyS0\"\n[polygon]\nfaces = 4\n[timing]\ndwell_s = -1\n",
    );
    assert!(e.contains("timing.dwell_s"), "{e}");
}

#[test]
fn timing_overrides_the_defaults() {
    let cfg = SurveyConfig::parse(
        "[survey]\nreference = \"autocollimator\"\n[positioner]\ndriver = \"scpi-serial\"\nport = \"/dev/ttyUSB0\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"/dev/ttyS0\"\n[polygon]\nfaces = 24\n[timing]\ndwell_s = 2.0\nmax_retries = 5\n",
        "c.toml",
    )
    .unwrap();
    let t = cfg.timing();
    assert_eq!(t.dwell, Duration::from_secs(2));
    assert_eq!(t.max_retries, 5);
    assert_eq!(t.call_timeout, Timing::default().call_timeout);
    assert_eq!(
        cfg.positioner,
        PositionerConfig::ScpiSerial {
            port: "/dev/ttyUSB0".into(),
            baud: 9600,
            controller: 1,
            axis: 1,
            in_position_window_deg: 0.01,
            error_query: ErrorQueryForm::All,
            unverified_commands: false,
        },
        "the defaults: only the publicly recorded commands, SYST:ERR:ALL?"
    );
}
