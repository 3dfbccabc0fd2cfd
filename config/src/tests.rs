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
    // (A survey's asset from it: the store's `the_configured_asset_is_the_surveys`.)
    let cfg = SurveyConfig::parse(&format!("{TRACKER_BENCH}[asset]\nid = \"bay-2/az\"\n"), "c.toml").unwrap();
    assert_eq!(cfg.asset.as_ref().map(|a| a.id.as_str()), Some("bay-2/az"));
    // Stored with the survey and read back.
    let text = serde_json::to_string(&cfg).unwrap();
    assert_eq!(serde_json::from_str::<SurveyConfig>(&text).unwrap(), cfg);
    assert_eq!(SurveyConfig::parse(TRACKER_BENCH, "c.toml").unwrap().asset, None);
    let e = error_of(&format!("{TRACKER_BENCH}[asset]\nid = \"bay 2\"\n"));
    assert!(e.starts_with("c.toml:8: asset.id: the asset id 'bay 2' holds ' '"), "{e}");
    let e = error_of(&format!("{TRACKER_BENCH}[asset]\nname = \"x\"\n"));
    assert!(e.starts_with("c.toml:8: asset.name: no such key in [asset]; the keys are: id"), "{e}");
}

#[test]
fn the_asset_s_interval_keys_are_checked_against_each_other() {
    let with = |keys: &str| format!("{TRACKER_BENCH}[asset]\nid = \"a\"\n{keys}");
    let cfg = SurveyConfig::parse(
        &with("interval_days = 30\ninterval_method = \"control-chart\"\ninterval_max_days = 60\n"),
        "c.toml",
    )
    .unwrap();
    let a = cfg.asset.clone().unwrap();
    assert_eq!((a.interval_days, a.interval_method.as_deref()), (Some(30.0), Some("control-chart")));
    assert_eq!((a.interval_min_days, a.interval_max_days), (None, Some(60.0)));
    let text = serde_json::to_string(&cfg).unwrap();
    assert_eq!(serde_json::from_str::<SurveyConfig>(&text).unwrap(), cfg);
    for (keys, says) in [
        (
            "interval_method = \"weekly\"\n",
            "c.toml:9: asset.interval_method: \"weekly\" is not among the choices: it takes one of \"staircase\"",
        ),
        ("interval_days = 0.5\n", "c.toml:9: asset.interval_days: 0.5 is out of range"),
        ("interval_revolutions = 0\n", "c.toml:9: asset.interval_revolutions: 0 is out of range"),
        (
            "interval_days = 400\n",
            "c.toml:9: asset.interval_days: 400 days is above asset.interval_max_days (not given: 365)",
        ),
        (
            "interval_days = 10\ninterval_min_days = 14\n",
            "c.toml:9: asset.interval_days: 10 days is below asset.interval_min_days = 14 (line 10)",
        ),
        (
            "interval_min_days = 120\n",
            "c.toml:9: asset.interval_min_days: 90 days is below asset.interval_min_days = 120",
        ),
        (
            "interval_min_days = 30\ninterval_max_days = 20\n",
            "c.toml:10: asset.interval_max_days: 20 is below asset.interval_min_days = 30 (line 9)",
        ),
    ] {
        let e = error_of(&with(keys));
        assert!(e.starts_with(says), "{keys}: {e}");
    }
}

#[test]
fn every_number_is_finite_and_within_its_stated_range() {
    assert!(SurveyConfig::parse(TRACKER_BENCH, "c.toml").is_ok());
    for (extra, says) in [
        (
            "[timing]\ncall_timeout_s = 1e19\n",
            "8: timing.call_timeout_s: 1e19 is out of range: it takes a number above 0",
        ),
        ("[timing]\nretry_backoff_s = 2e19\n", "8: timing.retry_backoff_s: 2e19 is out of range"),
        ("[timing]\ndwell_s = 1e19\n", "8: timing.dwell_s: 1e19 is out of range: it takes a number from 0 to 3600 s"),
        ("[timing]\npoll_interval_s = 0\n", "8: timing.poll_interval_s: 0 is out of range: it takes a number above 0"),
        ("[timing]\nmax_retries = 4000000000\n", "8: timing.max_retries: 4000000000 is out of range"),
        ("[timing]\nlocate_points = 2\n", "8: timing.locate_points: 2 is out of range: it takes a whole number from 3"),
        ("[timing]\ntime_scale = 0\n", "8: timing.time_scale: 0 is out of range: it takes a number above 0"),
        ("[timing]\ntime_scale = 20000\n", "8: timing.time_scale: 20000 is out of range"),
        ("[survey]\noverrun_deg = 45.0\n", "8: survey.overrun_deg: 45.0 is out of range"),
        ("[survey]\ntravel_deg = [-1e9, 90.0]\n", "8: survey.travel_deg[0]: -1e9 is out of range"),
        ("[survey]\ntravel_deg = [90.0, -10]\n", "8: survey.travel_deg: [90.0, -10] is not an increasing pair"),
        ("[arm]\nradius_mm = 500.0\nradius_tolerance_mm = 600.0\n", "9: arm.radius_tolerance_mm: 600.0 mm is more"),
        ("[certificate]\ntemperature_c = 293.15\n", "8: certificate.temperature_c: 293.15 is out of range"),
        ("[certificate]\nreference_uncertainty_deg = 0\n", "8: certificate.reference_uncertainty_deg: 0 is out"),
        ("[certificate]\ntolerance_deg = -0.01\n", "8: certificate.tolerance_deg: -0.01 is out of range"),
        ("[survey]\npoints = 1\n", "8: survey.points: 1 is out of range: it takes a whole number from 2 to"),
        ("[survey]\nruns = 1\n", "8: survey.runs: 1 is out of range: it takes a whole number from 2 to"),
        (
            "[certificate]\nreceived = \"2026-02-30\"\n",
            "8: certificate.received: \"2026-02-30\" is not a date (no such day",
        ),
        ("[certificate]\nreceived = \"1 May 2026\"\n", "8: certificate.received: \"1 May 2026\" is not a date"),
        ("[certificate]\ncountry = \"de\"\n", "8: certificate.country: \"de\" is not an ISO 3166-1"),
        ("[certificate]\ncountry = \"XX\"\n", "8: certificate.country: \"XX\" is not an ISO 3166-1"),
    ] {
        let e = error_of(&format!("{TRACKER_BENCH}{extra}"));
        assert!(e.starts_with(&format!("c.toml:{says}")), "{extra}: {e}");
    }
    // nan and inf anywhere, with the key and the line.
    for (extra, want) in [
        ("[survey]\noverrun_deg = nan\n", "c.toml:8: survey.overrun_deg: nan is not a finite number"),
        ("[timing]\ndwell_s = inf\n", "c.toml:8: timing.dwell_s: inf is not a finite number"),
        ("[timing]\ndwell_s = -inf\n", "c.toml:8: timing.dwell_s: -inf is not a finite number"),
        ("[arm]\nradius_mm = nan\n", "c.toml:8: arm.radius_mm: nan is not a finite number"),
    ] {
        let e = error_of(&format!("{TRACKER_BENCH}{extra}"));
        assert!(e.starts_with(want), "{extra}: {e}");
    }
    let e =
        error_of(&TRACKER_BENCH.replace("address = \"h:700\"\n", "address = \"h:700\"\napprox_distance_mm = nan\n"));
    assert!(e.starts_with("c.toml:7: tracker.approx_distance_mm: nan is not a finite number"), "{e}");
}

#[test]
fn defects_are_named_with_the_file_and_line() {
    let e = error_of("[positioner]\ndriver = \"warp-drive\"\naddress = \"x\"\n");
    assert!(
        e.starts_with("c.toml:2: positioner.driver: \"warp-drive\" is not among the choices: it takes one of"),
        "{e}"
    );
    let e = error_of("[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\nadress = \"x\"\n\n[tracker]\n");
    assert!(
        e.starts_with(
            "c.toml:4: positioner.adress: no such key in [positioner] with driver = \"scpi-tcp\"; did you mean address?"
        ),
        "{e}"
    );
    let e = error_of("[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n");
    assert!(e.starts_with("c.toml:1: survey: not given, so the reference is the tracker") && e.contains("no"), "{e}");
    let e = error_of(
        "[survey]\nreference = \"autocollimator\"\n[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"/dev/ttyS0\"\n[polygon]\nfaces = 4\ncertificate_arcsec = [0.1]\n",
    );
    assert!(e.starts_with("c.toml:11: polygon.certificate_arcsec: 1 values for polygon.faces = 4 (line 10)"), "{e}");
    let e = error_of(
        "[survey]\nreference = \"autocollimator\"\n[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"/dev/ttyS0\"\n[polygon]\nfaces = 4\n[timing]\ndwell_s = -1\n",
    );
    assert!(e.starts_with("c.toml:12: timing.dwell_s: -1 is out of range"), "{e}");
}

/// What serde said (issue 42): Rust's types, the wrong key, floats spelt
/// out in full. Each is now the key, its line, the value as written and
/// what the key takes, in words.
#[test]
fn a_wrong_value_is_named_as_written_with_what_its_key_takes_in_words() {
    let modbus = "[positioner]\ndriver = \"modbus-tcp\"\naddress = \"h:502\"\n";
    let tracker = "[tracker]\ndriver = \"emscon\"\naddress = \"h:700\"\n";
    for (text, want) in [
        (
            format!("[survey]\npoints = 4.5\n{TRACKER_BENCH}"),
            "c.toml:2: survey.points: 4.5 is not a whole number: it takes a whole number from 2 to 4294967295",
        ),
        (
            format!("{modbus}timeouts = 5\n{tracker}"),
            "c.toml:4: positioner.timeouts: 5 is a whole number: it takes a table [positioner.timeouts] with the keys connect_ms, request_ms",
        ),
        (
            format!("{modbus}timeouts = {{ request_ms = -1 }}\n{tracker}"),
            "c.toml:4: positioner.timeouts.request_ms: -1 is out of range: it takes a whole number, 0 or more",
        ),
        (
            format!("{TRACKER_BENCH}[timing]\ndwell_s = 1e400\n"),
            "c.toml:8: timing.dwell_s: 1e400 is too large in size to be a number: it takes a number from 0 to 3600 s",
        ),
        (
            format!("{TRACKER_BENCH}[timing]\nmax_retries = 123456789012345678901234567890\n"),
            "c.toml:8: timing.max_retries: 123456789012345678901234567890 is out of range: it takes a whole number from 0 to 1000",
        ),
        (
            format!("{TRACKER_BENCH}[survey]\nreference = 7\n"),
            "c.toml:8: survey.reference: 7 is a whole number: it takes one of \"tracker\" or \"autocollimator\"",
        ),
        (
            format!("{TRACKER_BENCH}[timing]\ndwell_s = \"1 s\"\n"),
            "c.toml:8: timing.dwell_s: \"1 s\" is text: it takes a number from 0 to 3600 s",
        ),
        (
            format!("{TRACKER_BENCH}[survey]\nbidirectional = 1\n"),
            "c.toml:8: survey.bidirectional: 1 is a whole number: it takes true or false",
        ),
        (
            format!(
                "{modbus}map = {{ position_encoding = {{ kind = \"counts\", counts_per_degree = 123456789012345678901234567890 }} }}\n{tracker}"
            ),
            "c.toml:4: positioner.map.position_encoding.counts_per_degree: 123456789012345678901234567890 is too large for a whole number (write it with an exponent): it takes a finite number",
        ),
        (
            format!("{TRACKER_BENCH}[timing]\ndwell_s = -123456789012345678901234567890\n"),
            "c.toml:8: timing.dwell_s: -123456789012345678901234567890 is out of range: it takes a number from 0 to 3600 s",
        ),
        // The radius made smaller than its default tolerance: the radius is named.
        (
            format!("{TRACKER_BENCH}[arm]\nradius_mm = 4.5\n"),
            "c.toml:8: arm.radius_mm: 4.5 mm is less than its tolerance, arm.radius_tolerance_mm (not given: 5 mm)",
        ),
        (
            format!("{TRACKER_BENCH}[arm]\nradius_mm = 4.5\nradius_tolerance_mm = 5.0\n"),
            "c.toml:8: arm.radius_mm: 4.5 mm is less than its tolerance, arm.radius_tolerance_mm = 5.0 (line 9)",
        ),
        (
            format!("{modbus}{tracker}[timing]\ncall_timeout_s = 1\n"),
            "c.toml:8: timing.call_timeout_s: 1 s is not longer than the positioner's own deadline, positioner.timeouts.request_ms (not given: 1000 ms)",
        ),
        (
            format!("{modbus}timeouts = {{ request_ms = 5000 }}\n{tracker}"),
            "c.toml:4: positioner.timeouts.request_ms: 5000 ms is not shorter than the engine's deadline of a call, timing.call_timeout_s (not given: 2 s)",
        ),
        (
            format!("survey = 1\n{TRACKER_BENCH}"),
            "c.toml:1: survey: 1 is a whole number: it takes a table [survey] with the keys points, runs,",
        ),
        (
            format!("{TRACKER_BENCH}[timing]\ndwell_s = 1\ndwell_s = 2\n"),
            "c.toml:9: timing.dwell_s: written twice (first on line 8)",
        ),
        (
            format!("{modbus}[positioner.map]\nposition_encoding = {{ kind = \"counts\" }}\n{tracker}"),
            "c.toml:5: positioner.map.position_encoding.counts_per_degree: missing: [positioner.map.position_encoding] with kind = \"counts\" needs counts_per_degree, a finite number",
        ),
    ] {
        let e = error_of(&text);
        assert!(e.starts_with(want), "{text}\n-> {e}\nwanted {want}");
    }
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

#[test]
fn the_machine_frame_is_stored_with_the_survey_and_checked() {
    let frame = "[machine_frame]\norigin_mm = [2500, 800.5, -300]\nrotation_deg = [0.1, -0.2, 90]\n";
    let cfg = SurveyConfig::parse(&format!("{TRACKER_BENCH}{frame}"), "c.toml").unwrap();
    let f = cfg.machine_frame.expect("stated");
    assert_eq!((f.origin_mm, f.rotation_deg), ([2500.0, 800.5, -300.0], [0.1, -0.2, 90.0]));
    let text = serde_json::to_string(&cfg).unwrap();
    assert_eq!(serde_json::from_str::<SurveyConfig>(&text).unwrap(), cfg);
    let only = SurveyConfig::parse(&format!("{TRACKER_BENCH}[machine_frame]\norigin_mm = [0, 0, 0]\n"), "c.toml");
    assert_eq!(only.unwrap().machine_frame.unwrap().rotation_deg, [0.0; 3]);
    // The alignment's uncertainty, stated (optional): read and stored.
    let stated = format!("{TRACKER_BENCH}{frame}origin_u_mm = 0.05\nrotation_u_deg = 0.01\n");
    let cfg = SurveyConfig::parse(&stated, "c.toml").unwrap();
    let f = cfg.machine_frame.unwrap();
    assert_eq!((f.origin_u_mm, f.rotation_u_deg), (Some(0.05), Some(0.01)));
    assert_eq!(serde_json::from_str::<SurveyConfig>(&serde_json::to_string(&cfg).unwrap()).unwrap(), cfg);
    for (bad, says) in [
        ("origin_mm = [1, 2, 3]\norigin_u_mm = -1\n", "c.toml:9: machine_frame.origin_u_mm: -1 is out of range"),
        ("origin_mm = [1, 2, 3]\nrotation_u_deg = \"x\"\n", "c.toml:9: machine_frame.rotation_u_deg"),
        ("origin_mm = [1, 2, 3]\nrotation_u_deg = 20\n", "c.toml:9: machine_frame.rotation_u_deg: 20 is out of range"),
        ("origin_mm = [1, 2]\n", "c.toml:8: machine_frame.origin_mm: a list of 2 is not three values"),
        (
            "origin_mm = [1, 2, 3]\nrotation_deg = [0, 0, 400]\n",
            "c.toml:9: machine_frame.rotation_deg[2]: 400 is out of range",
        ),
        ("rotation_deg = [0, 0, 0]\n", "machine_frame.origin_mm"),
        ("origin_mm = [1, 2, 3]\nrotate = 1\n", "c.toml:9: machine_frame.rotate: no such key in [machine_frame]"),
        ("origin_mm = [1, 2, 1e6]\n", "c.toml:8: machine_frame.origin_mm[2]: 1e6 is out of range"),
    ] {
        let e = error_of(&format!("{TRACKER_BENCH}[machine_frame]\n{bad}"));
        assert!(e.contains(says), "{bad}: {e}");
    }
    // The frame says where the tracker measures the axis: an autocollimator survey has no use for it.
    let e = error_of(
        "[survey]\nreference = \"autocollimator\"\n[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"/dev/ttyS0\"\n[polygon]\nfaces = 4\n\
         [machine_frame]\norigin_mm = [0, 0, 0]\n",
    );
    assert!(e.starts_with("c.toml:12: machine_frame.origin_mm: ") && e.contains("needs the tracker"), "{e}");
}
