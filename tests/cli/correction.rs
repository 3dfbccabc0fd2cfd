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

    // Switched off through the driver, and recorded.
    let off = run(&["--correction", "off"]).success().json();
    assert_eq!(off["correction"], "switched off", "{off:#}");
    let id = off["survey_id"].as_i64().unwrap();
    let events = show(&bench, id)["events"].clone();
    assert!(events.to_string().contains("switched off before the survey"), "{events:#}");
    // Now it is off: a plain calibration goes ahead, then a verification applies its table.
    let plain = run(&["--verify"]).json();
    assert_eq!(plain["correction"], "off", "{plain:#}");

    // A check finds the correction on and says so. In tolerance, it leaves
    // it on; a recalibration switches it off first (the table is replaced).
    let check = bench.survey(&["run", "--check", "--config", "run.toml", "--asset", "bay/az", "--json"]);
    let doc = check.json();
    assert_eq!(doc["check"]["correction"], "on", "{check}");
    assert!(check.stdout.contains("\"correction\":\"on\"") || doc["check"]["correction"] == "on");
    assert_eq!(show(&bench, doc["check"]["survey_id"].as_i64().unwrap())["status"], "complete", "{check}");
    match doc["outcome"].as_str() {
        Some("in tolerance") => {
            run(&[]).bad_input(&["applies a correction table"]);
        }
        Some("recalibrated") => {
            assert_eq!(doc["recalibration"]["correction"], "switched off", "{doc:#}");
            assert_eq!(run(&[]).success().json()["correction"], "off");
        }
        other => panic!("{other:?}: {check}"),
    }
    sim.kill().unwrap();
    sim.wait().unwrap();
}
