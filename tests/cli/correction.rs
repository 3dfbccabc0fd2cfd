//! The correction in force (issue 37, `../shared/contract.md`: "The
//! correction in force"), against `survey sim`'s Modbus drive, whose status
//! register has the `correction_enabled` bit: after `--verify` leaves its
//! table applied, a calibration is refused (exit 2, naming it, nothing
//! stored) unless `--correction off` (switched off through the driver,
//! recorded) or `--correction keep` (the corrected axis measured on purpose:
//! no calibration); a check reads the state and says which axis it judged,
//! and leaves the correction as it found it.

use crate::Bench;
use crate::serve::slow_bench;
use serde_json::Value;

/// `survey show --json` of survey `id`.
fn show(bench: &Bench, id: i64) -> Value {
    bench.survey(&["show", &id.to_string(), "--json"]).success().json()
}

#[test]
fn a_calibration_refuses_a_corrected_axis_unless_told_and_a_check_says_which_axis_it_judged() {
    let bench = Bench::new();
    let mut sim = slow_bench(&bench, 200.0);
    let run = |extra: &[&str]| {
        let mut args = vec!["run", "--config", "run.toml", "--asset", "bay/az", "--json"];
        args.extend(extra);
        bench.survey(&args)
    };
    // A calibration and its verification: the table is left applied.
    let first = run(&["--verify"]);
    assert!(first.code == 0 || first.code == 1, "{first}");
    let doc = first.json();
    assert_eq!(doc["correction"], "off", "read through the driver before the calibration: {doc:#}");

    // The next calibration finds it on: refused, nothing stored.
    let before = bench.stored();
    let refused = run(&[]).bad_input(&["applies a correction table", "--correction off", "--correction keep"]);
    bench.assert_unchanged(&before, &refused);

    // Kept on purpose: measured, marked, and no calibration.
    let kept = run(&["--correction", "keep"]).success().json();
    assert_eq!(kept["correction"], "kept on", "{kept:#}");
    let id = kept["survey_id"].as_i64().unwrap();
    let h = bench.survey(&["history", "--asset", "bay/az", "--json"]).success().json();
    let kinds: Vec<&str> = h["surveys"].as_array().unwrap().iter().map(|s| s["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["calibration", "verification", "corrected"], "{h:#}");
    let out = bench.survey(&["compare", "1", &id.to_string()]).bad_input(&["corrected axis", "--correction keep"]);
    assert!(!out.stderr.contains("panicked"), "{out}");

    // A check finds the correction on, says so, and judges the corrected
    // axis. In tolerance, it leaves it on; a recalibration switches it off
    // first (the table is replaced).
    let check = bench.survey(&["run", "--check", "--config", "run.toml", "--asset", "bay/az", "--json"]);
    let doc = check.json();
    assert_eq!(doc["check"]["correction"], "on", "{check}");
    assert_eq!(show(&bench, doc["check"]["survey_id"].as_i64().unwrap())["status"], "complete", "{check}");
    let still_on = match doc["outcome"].as_str() {
        Some("in tolerance") | Some("changed, the table holds") => true,
        Some("recalibrated") => {
            assert_eq!(doc["recalibration"]["correction"], "switched off", "{doc:#}");
            false
        }
        other => panic!("{other:?}: {check}"),
    };
    if still_on {
        // Switched off through the driver, and recorded.
        let off = run(&["--correction", "off"]).success().json();
        assert_eq!(off["correction"], "switched off", "{off:#}");
        let id = off["survey_id"].as_i64().unwrap();
        let events = show(&bench, id)["events"].clone();
        assert!(events.to_string().contains("switched off before the survey"), "{events:#}");
    }
    // Off now: a plain calibration goes ahead.
    let plain = run(&[]).success().json();
    assert_eq!(plain["correction"], "off", "{plain:#}");
    sim.kill().unwrap();
    sim.wait().unwrap();
}

/// An MI-4190-style controller on the network and an emScon tracker, 24
/// targets both ways, 2 runs; `unverified` sends the `CORR:` subsystem.
fn scpi_config(positioner: &str, tracker: &str, unverified: bool) -> String {
    format!(
        "[survey]\nreference = \"tracker\"\npoints = 24\nruns = 2\nbidirectional = true\n\
         [positioner]\ndriver = \"scpi-tcp\"\naddress = \"{positioner}\"\nunverified_commands = {unverified}\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"{tracker}\"\n\
         [timing]\ndwell_s = 0.01\npoll_interval_s = 0.02\n"
    )
}

/// Where the driver cannot tell (an MI-4190 without the unverified
/// commands), the survey says the state is unknown; when a table was left
/// applied (here by a verification through the unverified commands, as a
/// controller's own loading would) the calibration's error is far below the
/// asset's last one, and the survey says the axis may be corrected.
#[test]
fn an_unknown_correction_is_said_and_a_calibration_far_below_the_last_says_the_axis_may_be_corrected() {
    use std::io::{BufRead as _, BufReader};
    use std::process::Stdio;
    let bench = Bench::new();
    bench.write("sim.toml", scpi_config("127.0.0.1:0", "127.0.0.1:0", true));
    let mut sim = bench
        .command(&["sim", "--config", "sim.toml", "--time-scale", "200", "--seed", "3"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(sim.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
    let ready: Value = serde_json::from_str(&line).expect("the simulator's ready line");
    let at = |k: &str| ready["instruments"][k].as_str().unwrap().to_string();
    bench.write("loads.toml", scpi_config(&at("positioner"), &at("tracker"), true));
    bench.write("reads.toml", scpi_config(&at("positioner"), &at("tracker"), false));
    let run = |config: &str, extra: &[&str]| {
        let mut args = vec!["run", "--config", config, "--asset", "mi/az", "--json"];
        args.extend(extra);
        bench.survey(&args)
    };
    // A calibration and its verification through the unverified commands: the table stays applied.
    let loaded = run("loads.toml", &["--verify"]);
    assert!(loaded.code == 0 || loaded.code == 1, "{loaded}");
    // The next calibration cannot read the state, and measures a corrected axis.
    let blind = run("reads.toml", &[]);
    assert!(blind.stdout.contains("correction at the positioner: unknown") || blind.code == 0, "{blind}");
    let blind = blind.success().json();
    assert_eq!(blind["correction"], "unknown", "{blind:#}");
    let note = blind["correction_note"].as_str().unwrap_or_else(|| panic!("no note: {blind:#}"));
    assert!(note.starts_with("the axis may be corrected") && note.contains("far below"), "{note}");
    sim.kill().unwrap();
    sim.wait().unwrap();
}
