//! The controller tables from outside: `survey process --controller ...` and
//! the table options, the files beside the table, the `controllers` key of
//! `--json`, the recipe that replays them, and bad values (exit 2, naming the
//! flag, nothing written).

use super::Bench;
use serde_json::Value;

/// A small Figure 8 survey: 72 points x 2 bidirectional runs.
fn small_survey(bench: &Bench) {
    bench.survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--json"]).success();
}

fn controllers(doc: &Value) -> Vec<&str> {
    doc["controllers"]
        .as_array()
        .expect("controllers is an array")
        .iter()
        .map(|c| c["controller"].as_str().unwrap())
        .collect()
}

#[test]
fn every_controller_by_default_beside_the_table_with_the_contract_keys_kept() {
    let bench = Bench::new();
    small_survey(&bench);
    let doc = bench.survey(&["process", "--json"]).success().json();
    for k in ["survey_id", "peaks", "aliases", "table", "predicted"] {
        assert!(doc.get(k).is_some(), "{k} missing: {doc}");
    }
    assert_eq!(controllers(&doc), ["linuxcnc", "840d", "fanuc"]);
    let files = &doc["files"];
    assert_eq!(files["sinumerik_840d"], "survey-1/table-1.840d.ini");
    assert_eq!(files["fanuc"], "survey-1/table-1.fanuc.txt");
    assert_eq!(files["linuxcnc_type0"], "survey-1/table-1.comp0");
    assert_eq!(files["generic"], Value::Null);
    let c = &doc["controllers"];
    assert_eq!(c[0]["files"], serde_json::json!(["survey-1/table-1.comp0", "survey-1/table-1.comp1"]));
    assert_eq!((c[1]["points"].as_u64(), c[1]["modulo"].as_bool()), (Some(361), Some(true)));
    assert!(c[2]["parameters"].as_array().unwrap().iter().any(|p| p["number"] == "3625" && p["value"] == "360000"));
    for e in c.as_array().unwrap() {
        let peak = e["corrected_peak_deg"].as_f64().expect("a predicted peak");
        assert!(peak < doc["predicted"]["native_peak_deg"].as_f64().unwrap(), "{e}");
    }
    let ini = bench.read("survey-1/table-1.840d.ini");
    assert!(ini.starts_with("%_N_AX_EEC_INI\nCHANDATA(1)\n$AA_ENC_COMP[0,0,C1]=") && ini.ends_with("M17\n"), "{ini}");
    assert!(bench.read("survey-1/table-1.fanuc.txt").contains("3620"));
    assert!(!bench.exists("survey-1/table-1.generic.csv"));
    // The human summary names each controller file with its units.
    let text = bench.survey(&["process"]).success().stdout;
    for w in ["Siemens 840D table: 361 points", "deg every 1.000000 deg", "survey-1/table-1.fanuc.txt", "3622=360"] {
        assert!(text.contains(w), "{w:?} missing\n{text}");
    }
}

#[test]
fn chosen_controllers_and_range_are_kept_in_the_recipe_and_replayed() {
    let bench = Bench::new();
    small_survey(&bench);
    let doc = bench
        .survey(&[
            "process",
            "--json",
            "--controller",
            "840d,generic",
            "--table-start",
            "-720",
            "--table-end=720",
            "--table-interval",
            "2",
            "--sinumerik-axis",
            "A1",
            "--table-sign",
            "correction",
            "--table-values",
            "incremental",
            "--table-out",
            "c.csv",
        ])
        .success()
        .json();
    assert_eq!(controllers(&doc), ["840d", "generic"]);
    assert!(!bench.exists("c.comp0") && !bench.exists("c.fanuc.txt"));
    let ini = bench.read("c.840d.ini");
    assert_eq!(ini.lines().filter(|l| l.starts_with("$AA_ENC_COMP[0,")).count(), 721);
    for l in [
        "$AA_ENC_COMP_MIN[0,A1]=-720",
        "$AA_ENC_COMP_MAX[0,A1]=720",
        "$AA_ENC_COMP_STEP[0,A1]=2",
        "$AA_ENC_COMP_IS_MODULO[0,A1]=0",
    ] {
        assert!(ini.lines().any(|x| x == l), "{l} missing");
    }
    let generic = bench.read("c.generic.csv");
    assert!(generic.starts_with("position_deg,forward_correction_increment_deg,reverse_correction_increment_deg\n"));
    let recipe = bench.read("c.recipe.toml");
    for l in [
        "linuxcnc = false",
        "sinumerik_840d = true",
        "generic = true",
        "start_deg = -720.0",
        "interval_deg = 2.0",
        "sinumerik_axis = \"A1\"",
    ] {
        assert!(recipe.contains(l), "{l} missing from the recipe\n{recipe}");
    }
    // A recalibration replaying the recipe writes the same controller files.
    bench.survey(&["process", "--recipe", "c.recipe.toml", "--table-out", "d.csv"]).success();
    assert_eq!(bench.read("d.840d.ini"), ini);
    assert!(!bench.exists("d.comp0") && bench.exists("d.generic.csv"));
}

#[test]
fn the_840d_table_is_zero_at_the_reference_unless_the_recipe_keeps_it_absolute() {
    let bench = Bench::new();
    small_survey(&bench);
    // The default (K3): zero at the reference point 0 deg, said in the file.
    let ini = bench.read("survey-1/table-1.840d.ini");
    assert!(ini.lines().any(|l| l == "$AA_ENC_COMP[0,0,C1]=0"), "{ini}");
    assert!(ini.contains("\n; zero at the reference point 0 deg (K3)"), "{ini}");
    let doc = bench.survey(&["process", "--json", "--sinumerik-absolute", "--table-out", "a.csv"]).success().json();
    assert_eq!(doc["controllers"][1]["zero_at_reference"], false, "{doc}");
    let absolute = bench.read("a.840d.ini");
    assert!(!absolute.lines().any(|l| l == "$AA_ENC_COMP[0,0,C1]=0"), "{absolute}");
    assert!(absolute.contains("\n; absolute values, not zero at the reference point"), "{absolute}");
    let recipe = bench.read("a.recipe.toml");
    assert!(recipe.contains("sinumerik_absolute = true"), "{recipe}");
    // Replaying the recipe keeps the values absolute.
    bench.survey(&["process", "--recipe", "a.recipe.toml", "--table-out", "b.csv"]).success();
    assert_eq!(bench.read("b.840d.ini"), absolute);
}

#[test]
fn bad_table_choices_exit_2_naming_the_flag_and_write_nothing() {
    let bench = Bench::new();
    small_survey(&bench);
    // `run` wrote survey-1/table-1.* already: a failed process must leave them as they are.
    let snapshot = || {
        let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(bench.path("survey-1"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with("table-1"))
            .map(|p| (p.display().to_string(), std::fs::read(&p).unwrap()))
            .collect();
        files.sort();
        files
    };
    let before = snapshot();
    assert!(before.len() >= 6, "{:?}", before.iter().map(|f| &f.0).collect::<Vec<_>>());
    bench.survey(&["process", "--controller", "linuxcnc,heidenhain"]).bad_input(&[
        "--controller",
        "heidenhain",
        "840d",
    ]);
    bench.survey(&["process", "--table-interval", "7"]).bad_input(&["--table-interval", "whole number"]);
    bench.survey(&["process", "--table-interval", "1"]).bad_input(&["--table-interval", "256"]);
    bench.survey(&["process", "--sinumerik-axis", "1C"]).bad_input(&["--sinumerik-axis", "1C"]);
    bench.survey(&["process", "--table-start", "10", "--table-end", "5"]).bad_input(&["--table-end"]);
    bench
        .survey(&["process", "--controller", "fanuc", "--table-reference", "0.5"])
        .bad_input(&["--table-reference", "0.5"]);
    bench.survey(&["process", "--table-interval", "2", "--table-points", "9"]).bad_input(&["--table-points"]);
    assert!(snapshot() == before, "a failed command changes no file");
}
