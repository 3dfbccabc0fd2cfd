//! Files in and out, from outside: the CSV round trip, every defect of an
//! imported CSV and of a model file, and the database itself.

use super::*;

// ---------------------------------------------------------------------------
// export / import round trip and valid imports
// ---------------------------------------------------------------------------

#[test]
fn export_import_export_round_trip_is_byte_identical() {
    let b = Bench::new();
    let id = b.small_survey(true);
    let a = b.export(None, "a.csv");
    assert!(a.starts_with(HEADER), "{a}");
    assert_eq!(rows(&a).len(), 144);
    let new_id = b.import("a.csv");
    assert_eq!(new_id, id + 1);
    let again = b.export(Some(new_id), "b.csv");
    assert!(
        std::fs::read(b.path("a.csv")).unwrap() == std::fs::read(b.path("b.csv")).unwrap(),
        "a.csv and b.csv differ"
    );
    assert_eq!(a, again);

    let mut s1 = b.stats_json(Some(id));
    let mut s2 = b.stats_json(Some(new_id));
    assert_eq!(s1["survey_id"].as_i64(), Some(id));
    assert_eq!(s2["survey_id"].as_i64(), Some(new_id));
    assert_eq!((&s1["complete"], &s2["complete"]), (&Value::Bool(true), &Value::Bool(true)));
    // What the survey is (acquired to a plan around its refitted axis, or
    // imported) differs; the figures do not (the export writes the angles
    // around the refitted axis, those the figures are of).
    assert_eq!((&s1["axis"], &s2["axis"]), (&Value::from("refitted"), &Value::from("none")));
    for key in ["survey_id", "status", "runs_complete", "runs_planned", "axis"] {
        s1.as_object_mut().unwrap().remove(key);
        s2.as_object_mut().unwrap().remove(key);
    }
    assert_eq!(s1, s2, "a round trip keeps every figure");
    // The latest survey is now the import.
    assert_eq!(b.stats_json(None)["survey_id"].as_i64(), Some(new_id));
}

#[test]
fn import_of_a_valid_csv_without_timestamps() {
    let b = Bench::new();
    b.write("data.csv", VALID_CSV);
    assert_eq!(b.import("data.csv"), 1, "the first survey of a fresh database");
    assert!(b.exists("survey.db"), "import creates the database");
    assert_eq!(b.export(None, "out.csv"), VALID_CSV);
    let doc = b.stats_json(None);
    assert_eq!(doc["survey_id"].as_i64(), Some(1));
    for key in ISO_KEYS {
        assert!(iso_figure(&doc, key).is_some(), "iso230_2.{key} of a bidirectional import: {doc}");
    }
}

#[test]
fn import_of_a_valid_csv_with_timestamps() {
    let b = Bench::new();
    b.write("data.csv", VALID_CSV_WITH_TIMESTAMPS);
    assert_eq!(b.import("data.csv"), 1);
    assert_eq!(b.export(None, "out.csv"), VALID_CSV_WITH_TIMESTAMPS);
    // Timestamps do not change the statistics.
    b.write("plain.csv", VALID_CSV);
    assert_eq!(b.import("plain.csv"), 2);
    let mut with = b.stats_json(Some(1));
    let mut without = b.stats_json(Some(2));
    with["survey_id"] = Value::Null;
    without["survey_id"] = Value::Null;
    assert_eq!(with, without);
}

#[test]
fn import_names_the_file_as_given_in_a_subfolder() {
    let b = Bench::new();
    std::fs::create_dir(b.path("in")).unwrap();
    b.write("in/bad.csv", format!("{HEADER}\n1,forward,0,0,0\n1,forward,10,10,oops\n"));
    b.survey(&["import", "in/bad.csv"]).bad_input(&["in/bad.csv:3", "actual_deg", "oops"]);
    let abs = b.path("in/bad.csv");
    let abs = abs.to_str().expect("UTF-8 temp path");
    b.survey(&["import", abs]).bad_input(&[&format!("{abs}:3"), "actual_deg", "oops"]);
}

// ---------------------------------------------------------------------------
// import of defective CSVs: exit 2, file + line + what, nothing stored
// ---------------------------------------------------------------------------

/// Imports `content` as `bad.csv` into a database that already holds a
/// simulated survey and an imported one; expects exit 2 with every one of
/// `words` on stderr, and the database unchanged.
#[track_caller]
fn assert_import_rejected(content: impl AsRef<[u8]>, words: &[&str]) {
    let b = Bench::new();
    b.small_survey(true);
    b.write("first.csv", VALID_CSV);
    b.import("first.csv");
    let before = b.stored();
    assert_eq!(before.len(), 2);
    b.write("bad.csv", content);
    let out = b.survey(&["import", "bad.csv"]).bad_input(words);
    assert!(out.stdout.is_empty(), "a failed import prints no id\n{out}");
    b.assert_unchanged(&before, &out);
}

#[test]
fn import_rejects_a_missing_column() {
    assert_import_rejected(
        "run,direction,target_deg,readout_deg\n1,forward,0,0\n2,forward,0,0\n",
        &["bad.csv:1", "missing", "actual_deg"],
    );
}

#[test]
fn import_rejects_an_unexpected_column() {
    assert_import_rejected(
        format!("{HEADER},temperature\n1,forward,0,0,0,20\n2,forward,0,0,0,20\n"),
        &["bad.csv:1", "temperature"],
    );
}

#[test]
fn import_rejects_a_non_number() {
    assert_import_rejected(
        format!("{HEADER}\n1,forward,0,0,0\n1,forward,10,abc,10\n2,forward,0,0,0\n2,forward,10,10,10\n"),
        &["bad.csv:3", "readout_deg", "abc", "not a number"],
    );
}

#[test]
fn import_rejects_an_unknown_direction() {
    assert_import_rejected(
        format!("{HEADER}\n1,forward,0,0,0\n1,fwd,10,10,10\n2,forward,0,0,0\n"),
        &["bad.csv:3", "direction", "fwd"],
    );
}

#[test]
fn import_rejects_bad_run_numbers() {
    for bad in ["0", "-1", "1.5"] {
        assert_import_rejected(
            format!("{HEADER}\n1,forward,0,0,0\n2,forward,0,0,0\n{bad},forward,10,10,10\n"),
            &["bad.csv:4", "run", &format!("'{bad}'")],
        );
    }
}

#[test]
fn import_rejects_an_empty_file() {
    assert_import_rejected("", &["bad.csv", "empty"]);
}

#[test]
fn import_rejects_a_header_without_rows() {
    assert_import_rejected(format!("{HEADER}\n"), &["bad.csv", "no samples"]);
}

#[test]
fn import_rejects_a_wrong_field_count() {
    assert_import_rejected(
        format!("{HEADER}\n1,forward,0,0,0\n1,forward,10,10\n2,forward,0,0,0\n"),
        &["bad.csv:3", "4 fields", "5"],
    );
}

#[test]
fn import_rejects_nan_and_infinite_values() {
    assert_import_rejected(
        format!("{HEADER}\n1,forward,0,0,0\n2,forward,0,0,0\n1,forward,10,NaN,10\n"),
        &["bad.csv:4", "readout_deg", "NaN", "finite"],
    );
    assert_import_rejected(
        format!("{HEADER},timestamp_s\n1,forward,0,0,0,1\n2,forward,0,0,inf,2\n"),
        &["bad.csv:3", "actual_deg", "inf", "finite"],
    );
}

/// Contract: "A bad input file gets a message that names the file, the line
/// (or key) and what was wrong". FAILS today: `survey import` reads the file
/// with `std::fs::read_to_string` (orchestrator/src/commands.rs:32) and reports
/// `cannot read bad.csv: stream did not contain valid UTF-8`, with no line,
/// instead of going through `csvio::read_survey_csv`, which names the line.
#[test]
fn import_rejects_text_that_is_not_utf8_naming_the_line() {
    assert_import_rejected(
        [format!("{HEADER}\n1,forward,0,0,0\n").as_bytes(), b"2,forward,\xff,0,0\n"].concat(),
        &["bad.csv:3", "UTF-8"],
    );
}

#[test]
fn rejected_import_into_a_fresh_folder_creates_no_database() {
    let b = Bench::new();
    b.write("bad.csv", format!("{HEADER}\n1,fwd,0,0,0\n"));
    b.survey(&["import", "bad.csv"]).bad_input(&["bad.csv:2", "fwd"]);
    assert!(!b.exists("survey.db"));
}

#[test]
fn import_of_an_unreadable_path_exits_2() {
    let b = Bench::new();
    b.small_survey(false);
    let before = b.stored();
    let out = b.survey(&["import", "missing.csv"]).bad_input(&["missing.csv"]);
    assert!(out.stdout.is_empty());
    std::fs::create_dir(b.path("folder.csv")).unwrap();
    b.survey(&["import", "folder.csv"]).bad_input(&["folder.csv"]);
    b.assert_unchanged(&before, &out);
}

// ---------------------------------------------------------------------------
// run --model with model files
// ---------------------------------------------------------------------------

/// Runs `survey run --model bad.toml` twice: in a fresh folder (no database
/// may appear) and over a database holding a survey (it must stay as it was).
#[track_caller]
fn assert_model_rejected(model: &str, words: &[&str]) {
    let fresh = Bench::new();
    fresh.write("bad.toml", model);
    let out = fresh
        .survey(&["run", "--points", "36", "--runs", "2", "--model", "bad.toml"])
        .bad_input(&[&["bad.toml"][..], words].concat());
    assert!(out.stdout.is_empty(), "{out}");
    assert!(!fresh.exists("survey.db"), "a rejected model file creates no database\n{out}");

    let b = Bench::new();
    b.small_survey(true);
    let before = b.stored();
    b.write("bad.toml", model);
    let out =
        b.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--model", "bad.toml"]).bad_input(words);
    b.assert_unchanged(&before, &out);
}

#[test]
fn model_with_an_unknown_kind_is_rejected() {
    assert_model_rejected("[[effect]]\nkind = \"wobble\"\namplitude_deg = 0.001\n", &["bad.toml:2", "kind", "wobble"]);
}

#[test]
fn model_with_a_missing_key_is_rejected() {
    assert_model_rejected(
        "[design]\ngear_ratios = [12]\n\n[[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = 12\nphase_deg = 30.0\n",
        &["bad.toml:4", "missing", "amplitude_deg"],
    );
}

#[test]
fn model_with_a_negative_sigma_is_rejected() {
    assert_model_rejected(
        "[[effect]]\nkind = \"noise\"\nsigma_deg = -0.1\n",
        &["bad.toml:3", "sigma_deg", "negative", "-0.1"],
    );
}

#[test]
fn model_with_an_unknown_key_is_rejected() {
    assert_model_rejected(
        "[[effect]]\nkind = \"noise\"\nsigma_deg = 0.001\nsigma = 0.1\n",
        &["bad.toml:4", "unknown key", "sigma"],
    );
    assert_model_rejected("[desgin]\ngear_ratios = [12]\n", &["bad.toml:1", "desgin"]);
}

#[test]
fn model_that_is_not_toml_is_rejected() {
    assert_model_rejected("[design]\ngear_ratios = [12]\nthis is not toml\n", &["bad.toml:3", "TOML"]);
}

#[test]
fn missing_model_file_is_rejected() {
    let b = Bench::new();
    b.survey(&["run", "--points", "36", "--runs", "2", "--model", "nowhere.toml"]).bad_input(&["nowhere.toml"]);
    assert!(!b.exists("survey.db"));
}

#[test]
fn valid_model_files_run() {
    let b = Bench::new();
    b.write("contract.toml", CONTRACT_MODEL);
    b.write("design-only.toml", "[design]\ngear_ratios = [12]\ntooth_counts = [216]\n");
    b.write("no-effects.toml", "");
    for (i, file) in ["contract.toml", "design-only.toml", "no-effects.toml"].iter().enumerate() {
        let out = b.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--model", file, "--json"]);
        let doc = out.success().json();
        assert_eq!(doc["survey_id"].as_i64(), Some(i as i64 + 1));
        assert_bidirectional_relations(&doc);
    }
}

/// The model file drives the simulated positioner: with `backlash` of 0.004 deg
/// (forward reads +0.002, reverse -0.002, error = readout - actual), the
/// deviation `x = actual - target` is -0.002 forward and +0.002 reverse, so the
/// mean reversal `B_mean` (x_up - x_down) is about -0.004; without it, about 0.
#[test]
fn model_file_backlash_shows_in_the_mean_reversal() {
    let b = Bench::new();
    b.write("backlash.toml", "[[effect]]\nkind = \"backlash\"\namplitude_deg = 0.004\n");
    b.write("none.toml", "[design]\n");
    let run = |file| {
        b.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--model", file, "--json"])
            .success()
            .json()
    };
    let with = number(&run("backlash.toml"), "B_mean");
    let without = number(&run("none.toml"), "B_mean");
    assert!((with + 0.004).abs() < 0.0015, "B_mean with 0.004 deg of backlash = {with}");
    assert!(without.abs() < 0.0015, "B_mean without backlash = {without}");
}

// ---------------------------------------------------------------------------
// Missing database, unknown survey, not a database
// ---------------------------------------------------------------------------

#[test]
fn stats_and_export_without_a_database_exit_2_and_create_none() {
    let b = Bench::new();
    for args in
        [vec!["stats"], vec!["stats", "--json"], vec!["export", "--csv", "out.csv"], vec!["stats", "--survey", "1"]]
    {
        let out = b.survey(&args).bad_input(&["no survey database", "survey.db"]);
        assert!(out.stdout.is_empty(), "{out}");
        assert!(!b.exists("survey.db"), "a read command creates no database\n{out}");
        assert!(!b.exists("out.csv"), "{out}");
    }
    b.survey(&["--db", "elsewhere.db", "stats"]).bad_input(&["no survey database", "elsewhere.db"]);
    assert!(!b.exists("elsewhere.db"));
}

#[test]
fn unknown_survey_id_exits_2_naming_it() {
    let b = Bench::new();
    b.small_survey(false);
    let out = b.survey(&["stats", "--survey", "999"]).bad_input(&["999"]);
    assert!(out.stdout.is_empty(), "{out}");
    let out = b.survey(&["stats", "--json", "--survey", "999"]).bad_input(&["999"]);
    assert!(out.stdout.is_empty(), "{out}");
    b.survey(&["export", "--csv", "out.csv", "--survey", "999"]).bad_input(&["999"]);
    assert!(!b.exists("out.csv"), "no file for a survey that does not exist");
}

/// Runs `args` (after `--db junk.db`) with `junk.db` a text file: expects exit
/// 2 naming the file and saying it is not a survey database, and the file left
/// alone.
#[track_caller]
fn assert_not_a_database_is_bad_input(args: &[&str]) {
    let b = Bench::new();
    let junk = "this is not a database\n";
    b.write("junk.db", junk);
    b.write("v.csv", VALID_CSV);
    let out = b.survey(&[&["--db", "junk.db"][..], args].concat());
    assert_eq!(b.read("junk.db"), junk, "the file is left alone\n{out}");
    let out = out.bad_input(&["junk.db", "not a survey database"]);
    assert!(out.stdout.is_empty(), "{out}");
    assert!(!b.exists("out.csv"), "{out}");
}

/// A `--db` file that is not a SQLite database is bad input (exit 2).
#[test]
fn stats_and_export_of_a_file_that_is_not_a_database_exit_2() {
    assert_not_a_database_is_bad_input(&["stats"]);
    assert_not_a_database_is_bad_input(&["stats", "--json"]);
    assert_not_a_database_is_bad_input(&["export", "--csv", "out.csv"]);
}

/// FAILS today (exit 1): `run` opens the store with
/// `Store::open(db).await.map_err(Failure::runtime)` (orchestrator/src/run.rs:104),
/// so the store's "is not a survey database" user error (a `store::NotFound`)
/// is reported as a run-time failure; `stats` and `export` go through
/// `commands::classify` and exit 2.
#[test]
fn run_over_a_file_that_is_not_a_database_exits_2() {
    assert_not_a_database_is_bad_input(&["run", "--points", "36", "--runs", "2"]);
}

/// FAILS today (exit 1), same cause as for `run`:
/// orchestrator/src/commands.rs:40 maps every `Store::open` error to `Failure::runtime`.
#[test]
fn import_into_a_file_that_is_not_a_database_exits_2() {
    assert_not_a_database_is_bad_input(&["import", "v.csv"]);
}

#[test]
fn stats_of_a_survey_too_small_for_iso230_2_exits_2() {
    let b = Bench::new();
    b.write("one-run.csv", format!("{HEADER}\n1,forward,0,0,0.001\n1,forward,90,90,90.001\n"));
    let id = b.import("one-run.csv");
    let out = b.survey(&["stats", "--json"]).bad_input(&["ISO 230-2", &id.to_string()]);
    assert!(out.stdout.is_empty(), "{out}");
}

/// A background task that spins without yielding (as sqlx-core 0.9.0's pool
/// reaper can, sqlx issue 3645) holds a worker thread for good: the command
/// still ends once its work and writes are done, with its usual status and
/// everything stored. Without the bounded shutdown the process never exits
/// and the deadline below fails the test.
#[test]
fn a_command_exits_while_a_spawned_task_spins() {
    use std::time::{Duration, Instant};
    let bench = Bench::new();
    let args = ["run", "--points", "36", "--runs", "2", "--bidirectional", "--json"];
    let mut cmd = bench.command(&args);
    cmd.env("SURVEY_TEST_WEDGE_AT_EXIT", "1").stdout(std::process::Stdio::null()).stderr(std::process::Stdio::null());
    let mut child = cmd.spawn().expect("start the survey binary");
    // A liveness bound, not a timing claim: the survey takes well under a
    // second; two minutes only separates "exits" from "never exits".
    let deadline = Instant::now() + Duration::from_secs(120);
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for the binary") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("`survey run` did not exit while a spawned task spun");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!(status.code(), Some(0), "{status:?}");
    let stats = bench.stats_json(Some(1));
    assert!(stats["iso230_2"]["A"].as_f64().is_some_and(|a| a > 0.0), "{stats}");
}

// ---------------------------------------------------------------------------
// Messages: each thing said once, numbers in a readable form
// ---------------------------------------------------------------------------

#[test]
fn import_refuses_a_second_sample_of_a_run_direction_and_target_naming_both_lines() {
    let b = Bench::new();
    // Line 4 repeats run 1, forward, target 90 of line 3: stats would refuse
    // the survey, so import does, and stores nothing.
    b.write("dup.csv", format!("{HEADER}\n1,forward,0,0,0.001\n1,forward,90,90,90.001\n1,forward,90,90,90.002\n"));
    let out = b.survey(&["import", "dup.csv"]).bad_input(&["dup.csv:4:", "run 1, forward, target 90 deg", "line 3"]);
    assert!(out.stdout.is_empty(), "{out}");
    assert!(!b.exists("survey.db"), "nothing stored\n{out}");
}

/// The text after `error: ` on stderr.
fn error_line(out: &Output) -> String {
    out.stderr.lines().find_map(|l| l.strip_prefix("error: ")).unwrap_or_default().to_string()
}

#[test]
fn an_error_says_each_thing_once() {
    let b = Bench::new();
    // Two targets make no spectrum: the reason once, not once per layer.
    let out = b.survey(&["run", "--points", "2", "--runs", "2"]);
    let line = error_line(&out);
    assert_eq!(line.matches("at least 3 are needed").count(), 1, "{out}");
}

#[test]
fn large_and_tiny_numbers_in_messages_read_as_written_and_never_panic() {
    let b = Bench::new();
    b.small_survey(false);
    b.write("m.toml", "[[effect]]\nkind = \"noise\"\nsigma_deg = 1e308\n");
    b.write("d.toml", "[design]\ngear_ratios = [1e308]\n");
    b.write(
        "c.toml",
        "[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n[tracker]\ndriver = \"emscon\"\naddress = \"h:700\"\n\
         [timing]\ndwell_s = 1e308\n",
    );
    b.write("r.toml", "[lines]\nmin_amplitude_deg = -1e308\n");
    for (args, shown) in [
        (vec!["model-gap", "--model", "m.toml"], "sigma_deg = 1e308"),
        (vec!["process", "--design", "d.toml"], "1e308 is not a gear ratio"),
        (vec!["run", "--config", "c.toml", "--points", "36"], "c.toml:8: timing.dwell_s: 1e308"),
        (vec!["process", "--recipe", "r.toml"], "got -1e308"),
        (vec!["process", "--table-interval", "1e-300"], "1e-300 deg intervals"),
        (vec!["process", "--table-start", "1e308"], "got 1e308"),
        (vec!["process", "--table-end", "1e308"], "got 1e308"),
        (vec!["process", "--table-reference", "1e308"], "got 1e308"),
        (vec!["process", "--fanuc-unit", "1e-300"], "got 1e-300"),
        (vec!["report", "--out", "r", "--tolerance", "1e308"], "--tolerance 1e308"),
        (vec!["report", "--out", "r", "--temperature", "-1e308"], "--temperature -1e308"),
    ] {
        let out = b.survey(&args).bad_input(&[shown]);
        let line = error_line(&out);
        assert!(line.len() < 300 && !line.contains("00000000000"), "{}: {out}", args.join(" "));
        assert!(!out.stderr.contains("panicked"), "{out}");
    }
}
