//! `survey model-gap` from outside: a survey acquired with `survey run --model
//! true.toml` (the simulated positioner running the true model, the
//! autocollimator as the reference), compared with a model that lacks one of
//! its effects; the contract's JSON keys; `--out` and closing the loop; bad
//! input.
//!
//! Tolerances as in the processing tests: the effect's phasor within 5 of its
//! standard errors, the noise floor within 10 % of the truth, the residual
//! after within 6 % of the noise floor.

use super::Bench;
use serde_json::Value;
use survey_processing::model::{Effect, Model};
use survey_processing::spectrum::Phasor;

/// A 20:1 gear pass and a 75-tooth gear whose second harmonic, 150
/// cycles/rev, 180 points per revolution alias to 30.
const TRUE_MODEL: &str = r#"[design]
gear_ratios = [20]
tooth_counts = [75]

[[effect]]
kind = "gear_pass"
cycles_per_rev = 20
amplitude_deg = 0.006
phase_deg = 15.0

[[effect]]
kind = "tooth_mesh"
cycles_per_rev = 75
amplitude_deg = 0.0012
phase_deg = 20.0

[[effect]]
kind = "tooth_mesh"
cycles_per_rev = 150
amplitude_deg = 0.0006
phase_deg = 200.0

[[effect]]
kind = "backlash"
amplitude_deg = 0.002

[[effect]]
kind = "noise"
sigma_deg = 0.0003
"#;

/// The true model without the 150 cycles/rev harmonic.
fn lacking() -> String {
    let m = Model::parse(TRUE_MODEL, "true.toml").unwrap();
    let keep = |e: &Effect| !matches!(e, Effect::Periodic { cycles_per_rev, .. } if *cycles_per_rev == 150.0);
    Model { design: m.design.clone(), effects: m.effects.into_iter().filter(keep).collect(), ..m }.to_toml()
}

fn run(bench: &Bench, model: &str, seed: &str) -> i64 {
    let out = bench
        .survey(&[
            "run",
            "--model",
            model,
            "--points",
            "180",
            "--runs",
            "3",
            "--bidirectional",
            "--reference",
            "autocollimator",
            "--seed",
            seed,
            "--json",
        ])
        .success();
    out.json()["survey_id"].as_i64().expect("survey_id")
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[track_caller]
fn assert_at_noise_floor(doc: &Value, which: &str) {
    let (rms, floor) = (num(&doc[which]), num(&doc["noise_floor_deg"]));
    assert!((rms / floor - 1.0).abs() < 0.06, "{which} {rms} vs noise floor {floor}\n{doc:#}");
}

#[test]
fn model_gap_names_the_missing_harmonic_writes_the_improved_model_and_closes_the_loop() {
    let bench = Bench::new();
    bench.write("true.toml", TRUE_MODEL);
    bench.write("lacking.toml", lacking());
    let id = run(&bench, "true.toml", "1");

    let out = bench.survey(&["model-gap", "--model", "lacking.toml", "--json", "--out", "improved.toml"]).success();
    let doc = out.json();
    assert_eq!(doc["survey_id"], id);
    for key in ["effects_added", "steps", "rms_before_deg", "rms_after_deg", "noise_floor_deg"] {
        assert!(doc.get(key).is_some(), "{key} missing\n{out}");
    }
    // The noise: the positioner's 0.0003 deg (the autocollimator adds 0.1 arcsec).
    assert!((num(&doc["noise_floor_deg"]) / 0.0003 - 1.0).abs() < 0.1, "{out}");
    let added = doc["effects_added"].as_array().expect("effects_added is an array");
    assert_eq!(added.len(), 1, "{out}");
    let e = &added[0];
    assert_eq!((e["kind"].as_str(), num(&e["cycles_per_rev"])), (Some("tooth_mesh"), 150.0), "{out}");
    let got = Phasor::from_polar(num(&e["amplitude_deg"]), num(&e["phase_deg"]));
    let se = num(&e["standard_error_deg"]);
    assert!((got - Phasor::from_polar(0.0006, 200.0)).amplitude_deg() < 5.0 * se, "{out}");
    let explanation = e["explanation"].as_str().unwrap();
    assert!(
        explanation.starts_with(
            "150 cycles/rev: 75-tooth gear, harmonic 2 at 150 cycles/rev, aliased to 30 by 180 points/rev"
        ),
        "{explanation}"
    );
    let steps = doc["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 1, "{out}");
    assert_eq!(steps[0]["added"], "tooth_mesh 150 cycles/rev");
    assert!(num(&steps[0]["rms_deg"]) < num(&doc["rms_before_deg"]));
    assert_eq!(num(&steps[0]["rms_deg"]), num(&doc["rms_after_deg"]));
    assert_at_noise_floor(&doc, "rms_after_deg");
    assert!(out.stderr.contains("improved.toml"), "{out}");

    // The improved model file: the model given plus the harmonic, readable.
    let text = bench.read("improved.toml");
    assert!(text.starts_with("# Improved by `survey model-gap` from lacking.toml on survey 1"), "{text}");
    let improved = Model::parse(&text, "improved.toml").unwrap();
    assert_eq!(improved.effects.len(), 5);
    assert!(
        improved
            .effects
            .iter()
            .any(|e| matches!(e, Effect::Periodic { cycles_per_rev, .. } if *cycles_per_rev == 150.0))
    );

    // It explains the measured survey: nothing named, the gap at the noise floor.
    let again = bench.survey(&["model-gap", "--model", "improved.toml", "--json"]).success().json();
    assert_eq!(again["effects_added"].as_array().unwrap().len(), 0, "{again:#}");
    assert_eq!(again["steps"].as_array().unwrap().len(), 0);
    assert_at_noise_floor(&again, "rms_before_deg");
    // The verdict (issue 14): explained by the stated tests, nothing of the reference named.
    assert_eq!(again["verdict"]["explained"], true, "{again:#}");
    assert!(again["verdict"]["reference"].as_array().unwrap().is_empty(), "{again:#}");
    assert_eq!(doc["verdict"]["explained"].as_bool(), Some(true), "{out}");

    // The simulator running the improved model reproduces the measured survey
    // to the noise floor: a new survey of it (another seed) is explained by
    // the true model, and the improved model explains it too.
    let id2 = run(&bench, "improved.toml", "7");
    let id2_text = id2.to_string();
    for model in ["true.toml", "improved.toml"] {
        let doc = bench.survey(&["model-gap", "--model", model, "--survey", &id2_text, "--json"]).success().json();
        assert_eq!(doc["effects_added"].as_array().unwrap().len(), 0, "{model}: {doc:#}");
        assert_eq!(doc["effects_adjusted"].as_array().unwrap().len(), 0, "{model}: {doc:#}");
        assert_at_noise_floor(&doc, "rms_before_deg");
    }

    // Without --json: the report, with the steps as a table.
    let text = bench.survey(&["model-gap", "--model", "lacking.toml", "--survey", "1"]).success().stdout;
    for want in [
        "survey 1, model lacking.toml",
        "the gap with the model given:",
        "     0  the model as given",
        "     1  tooth_mesh 150 cycles/rev",
        "150 (seen at 30) cycles/rev",
        "the gap with the improved model:",
        "in angle:",
        "by direction:",
        "in time:",
    ] {
        assert!(text.contains(want), "{want:?} not in\n{text}");
    }
}

#[test]
fn model_gap_bad_input_exits_2_and_changes_nothing() {
    let bench = Bench::new();
    let help = bench.survey(&["model-gap", "--help"]).success();
    for flag in ["--model", "--survey", "--out", "--json", "--db"] {
        assert!(help.stdout.contains(flag), "model-gap --help should mention {flag}\n{help}");
    }
    bench.write("lacking.toml", lacking());
    // No database yet.
    bench.survey(&["model-gap", "--model", "lacking.toml"]).bad_input(&["survey.db"]);
    assert!(!bench.exists("survey.db"));
    run(&bench, "lacking.toml", "3");
    let before = bench.stored();
    // A model file with a defect: the file and the line are named, no --out written.
    bench.write("bad.toml", "[design]\ngear_ratios = [20]\n\n[[effect]]\nkind = \"wobble\"\namplitude_deg = 1\n");
    let out =
        bench.survey(&["model-gap", "--model", "bad.toml", "--out", "never.toml"]).bad_input(&["bad.toml:5", "wobble"]);
    assert!(!bench.exists("never.toml"), "{out}");
    bench.survey(&["model-gap", "--model", "missing.toml"]).bad_input(&["missing.toml"]);
    bench.survey(&["model-gap", "--model", "lacking.toml", "--survey", "99"]).bad_input(&["99"]);
    let out = bench
        .survey(&["model-gap", "--model", "lacking.toml", "--out", "no/such/dir/m.toml"])
        .bad_input(&["no/such/dir/m.toml"]);
    bench.survey(&["model-gap"]).bad_input(&["--model"]);
    bench.assert_unchanged(&before, &out);
}

/// The Figure 1 case of issue 14: an elevation axis over -10..90 deg with a
/// tracker, compared with its own preset model. Compared around the axis
/// located before the runs (`--located-axis`), the located axis is off by
/// 0.06 mm on seed 1 (a once-per-revolution error of 3.5e-3 deg, three times
/// the noise floor): model-gap names "the reference: axis location" with its
/// size and never says the model explains the data down to the noise floor.
/// Around the axis fitted again from every SMR position (the default), the
/// same survey is explained, and the JSON says how well the axis is known.
#[test]
fn model_gap_on_a_partial_arc_names_the_axis_location_and_is_never_falsely_content() {
    let bench = Bench::new();
    let preset = concat!(env!("CARGO_MANIFEST_DIR"), "/sims/presets/fig1.toml");
    let run = ["run", "--preset", "fig1", "--points", "720", "--bidirectional", "--seed", "1"];
    bench.survey(&run).success();
    // Every controller's table of the partial range, Fanuc's on whole degrees
    // inside the measured arc (its spacing counts whole detection units).
    let fanuc = bench.read("survey-1/table-1.fanuc.txt");
    let interval = fanuc.lines().find(|l| l.split_whitespace().collect::<Vec<_>>().starts_with(&["3624", "1000"]));
    assert!(interval.is_some(), "parameter 3624 = 1000 units of 0.001 deg\n{fanuc}");
    let out = bench.survey(&["model-gap", "--model", preset, "--located-axis", "--json"]).success();
    let doc = out.json();
    let found = &doc["verdict"]["reference"][0];
    assert_eq!(found["source"], "the reference: axis location", "{out}");
    // The located centre's shift, as the refit measures it: 0.0641 mm, 3.67e-3 deg.
    // The finding is within 5 of its standard errors of that.
    let refit = bench.survey(&["model-gap", "--model", preset, "--json"]).success().json();
    let shift = num(&refit["axis_refit"]["located_once_per_rev_deg"]);
    assert!((num(&found["amplitude_deg"]) - shift).abs() < 5.0 * num(&found["standard_error_deg"]) + 2e-4, "{out}");
    assert!(doc["axis_refit"].is_null(), "{out}");
    let text = bench.survey(&["model-gap", "--model", preset, "--located-axis"]).success().stdout;
    assert!(!text.contains("explains the data down to the noise floor"), "{text}");
    assert!(text.contains("verdict: the model explains the positioner, and the rest is the reference's"), "{text}");
    assert!(text.contains("the reference: axis location, a once-per-revolution error of"), "{text}");
    // Around the refitted axis: explained, and the arc and its cost stated.
    assert_eq!(refit["verdict"]["explained"], true, "{refit:#}");
    assert!((num(&refit["axis_refit"]["arc_deg"]) - 100.0).abs() < 0.5, "{refit:#}");
    assert!(num(&refit["axis_refit"]["over_arc_se_deg"]) > 0.0, "{refit:#}");
}
