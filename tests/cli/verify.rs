//! The closed loop of the paper, end to end through the binary: survey the
//! Figure 8 positioner, process, load the table into the simulated
//! positioner's feedback path through the driver trait, survey again between
//! the calibration targets (where the table interpolates).

use super::Bench;
use serde_json::Value;

#[test]
fn the_fig8_correction_measured_in_the_loop_beats_native_and_the_hysteresis_floor() {
    let bench = Bench::new();
    let out = bench.survey(&["run", "--points", "360", "--runs", "5", "--bidirectional", "--verify", "--json"]);
    assert_eq!(out.code, 0, "{out}");
    let doc: Value = serde_json::from_str(&out.stdout).expect("one JSON document");
    let v = &doc["verify"];
    let num = |k: &str| v[k].as_f64().unwrap_or_else(|| panic!("verify.{k} missing: {v}"));
    assert_eq!(v["survey_id"], 2);
    // Measured half a step (0.5 deg) from every calibration target.
    assert_eq!((v["targets"].as_u64(), v["between_targets"].as_bool()), (Some(360), Some(true)), "{v}");
    assert!((num("offset_deg") - 0.5).abs() < 1e-9, "{v}");
    bench.survey(&["export", "--csv", "v.csv", "--survey", "2"]).success();
    let targets = targets_of(&bench.read("v.csv"));
    assert_eq!(targets.len(), 360);
    assert!(targets.iter().enumerate().all(|(k, t)| (t - (k as f64 + 0.5)).abs() < 1e-9), "{targets:?}");
    // Its own plan is stored with it, so a resume measures the same targets.
    let shown = bench.survey(&["show", "2", "--json"]).success().json();
    assert_eq!(shown["plan"]["targets_deg"][0].as_f64(), Some(0.5), "{shown}");
    assert_eq!(shown["points"].as_u64(), Some(360), "{shown}");
    assert_eq!(v["directional"], true, "fig8's 0.008 deg backlash makes the table direction-aware");
    // The paper: +/-0.015 -> +/-0.005, a factor of 3, limited by hysteresis.
    // Here every sample also carries the tracker's ~0.0009 deg and the
    // positioner's 0.0004 deg of noise, which no table removes.
    assert!(num("improvement") >= 3.0, "measured improvement {}", num("improvement"));
    // The hysteresis floor of a one-column table is +/- backlash/2 = 0.004 deg.
    // The systematic part (per-target means over 5 runs: noise sd about
    // 0.001/sqrt(5) = 0.00045, so a peak of about 4 sd = 0.0018) is well below it.
    let floor = 0.008 / 2.0;
    assert!(num("corrected_systematic_peak_deg") < floor, "{v}");
    assert!(num("native_systematic_peak_deg") > 3.0 * num("corrected_systematic_peak_deg"), "{v}");
    // And the reversal is gone: B_mean was -backlash, now within 5 of its sd
    // (sqrt(2 * 0.001^2 / 5 / 360) = 3.3e-5).
    let b_mean = v["iso230_2"]["B_mean"].as_f64().unwrap();
    let native_b = doc["iso230_2"]["B_mean"].as_f64().unwrap();
    assert!((native_b + 0.008).abs() < 5e-4, "native B_mean {native_b}");
    assert!(b_mean.abs() < 5.0 * 3.3e-5 + 2e-4, "corrected B_mean {b_mean}");
    // The prediction made before the table was applied (on the samples at the
    // table's own points) is borne out between them: the table's
    // interpolation adds nothing the noise does not hide.
    assert!((num("corrected_peak_deg") - num("predicted_corrected_peak_deg")).abs() < 0.002, "{v}");
    assert!(bench.exists("survey-1/table-1.csv") && bench.exists("survey-1/table-1.recipe.toml"));
}

#[test]
fn run_replays_a_recipe_and_refuses_a_bad_one_before_measuring() {
    let bench = Bench::new();
    let first = bench.survey(&["run", "--points", "120", "--runs", "2", "--bidirectional", "--json"]);
    assert_eq!(first.code, 0, "{first}");
    let again = bench.survey(&[
        "run",
        "--points",
        "120",
        "--runs",
        "2",
        "--bidirectional",
        "--json",
        "--seed",
        "2",
        "--recipe",
        "survey-1/table-1.recipe.toml",
    ]);
    assert_eq!(again.code, 0, "{again}");
    let doc: Value = serde_json::from_str(&again.stdout).unwrap();
    assert_eq!(doc["process"]["survey_id"], 2, "{doc}");
    assert!(bench.exists("survey-2/table-2.csv"));
    bench.write("bad.toml", "[table]\nrows = 1\n");
    let bad = bench.survey(&["--db", "other.db", "run", "--points", "120", "--runs", "2", "--recipe", "bad.toml"]);
    assert_eq!(bad.code, 2, "{bad}");
    assert!(bad.stderr.contains("bad.toml") && bad.stderr.contains("rows"), "{bad}");
    assert!(!bench.exists("other.db"), "nothing measured, nothing stored");
}

/// The distinct targets of an exported survey CSV, ascending.
fn targets_of(csv: &str) -> Vec<f64> {
    let mut t: Vec<f64> = csv.lines().skip(1).map(|l| l.split(',').nth(2).unwrap().parse::<f64>().unwrap()).collect();
    t.sort_by(f64::total_cmp);
    t.dedup();
    t
}

#[test]
fn verify_points_measures_a_denser_set_between_the_targets_and_refuses_one_on_them() {
    let bench = Bench::new();
    let run = |extra: &[&str]| {
        let mut args = vec!["run", "--points", "36", "--runs", "2", "--bidirectional", "--verify", "--json"];
        args.extend_from_slice(extra);
        bench.survey(&args)
    };
    // 72 targets every 5 deg from 2.5: the calibration targets are every 10 deg.
    let out = run(&["--verify-points", "72"]).success();
    let v = &out.json()["verify"];
    assert_eq!((v["targets"].as_u64(), v["between_targets"].as_bool()), (Some(72), Some(true)), "{v}");
    assert!((v["offset_deg"].as_f64().unwrap() - 2.5).abs() < 1e-9, "{v}");
    bench.survey(&["export", "--csv", "v.csv", "--survey", "2"]).success();
    let targets = targets_of(&bench.read("v.csv"));
    assert_eq!(targets, (0..72).map(|k| 2.5 + 5.0 * k as f64).collect::<Vec<_>>());
    // 18 targets every 20 deg from 10 deg fall on the calibration targets:
    // refused before anything is measured or stored.
    let before = bench.stored();
    run(&["--verify-points", "18"]).bad_input(&["--verify-points 18", "calibration target"]);
    assert_eq!(bench.stored(), before, "nothing stored");
    // With an autocollimator the faces are all there is to measure.
    run(&["--reference", "autocollimator", "--verify-points", "72"]).bad_input(&["autocollimator", "faces"]);
    assert_eq!(bench.stored(), before, "nothing stored");
    bench.survey(&["run", "--points", "36", "--runs", "2", "--verify-points", "72"]).bad_input(&["--verify"]);
}

#[test]
fn with_an_autocollimator_the_verification_stays_at_the_faces_and_says_so() {
    let bench = Bench::new();
    let out = bench
        .survey(&[
            "run",
            "--points",
            "24",
            "--runs",
            "2",
            "--bidirectional",
            "--reference",
            "autocollimator",
            "--verify",
        ])
        .success();
    assert!(out.stdout.contains("at the 24 calibration targets (the polygon's faces"), "{out}");
}
