//! `survey run`, `--db`, `SURVEY_DB` and `survey stats`, from outside.

use super::*;

// ---------------------------------------------------------------------------
// run, --db, stats
// ---------------------------------------------------------------------------

#[test]
fn run_creates_the_default_database_and_prints_the_iso_summary() {
    let b = Bench::new();
    let out = b.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional"]).success();
    assert!(b.exists("survey.db"), "survey.db is the default database\n{out}");
    for word in ["survey 1", "ISO 230-2", "accuracy", "repeatability", "reversal"] {
        assert!(out.stdout.contains(word), "the summary should mention {word:?}\n{out}");
    }
    let stats = b.survey(&["stats"]).success();
    for word in ["survey 1", "ISO 230-2", "accuracy", "repeatability", "reversal"] {
        assert!(stats.stdout.contains(word), "stats should mention {word:?}\n{stats}");
    }
}

#[test]
fn a_survey_has_every_sample_in_acquisition_order() {
    let b = Bench::new();
    let id = b.small_survey(true);
    let csv = b.export(Some(id), "s.csv");
    let rows = rows(&csv);
    assert_eq!(rows.len(), 36 * 2 * 2, "36 points x 2 runs x 2 directions");
    let mut blocks: Vec<(String, String, Vec<f64>)> = Vec::new();
    for r in &rows {
        let target: f64 = r[2].parse().expect("target_deg");
        match blocks.last_mut() {
            Some((run, dir, t)) if *run == r[0] && *dir == r[1] => t.push(target),
            _ => blocks.push((r[0].clone(), r[1].clone(), vec![target])),
        }
    }
    let order: Vec<(&str, &str)> = blocks.iter().map(|(r, d, _)| (r.as_str(), d.as_str())).collect();
    assert_eq!(order, [("1", "forward"), ("1", "reverse"), ("2", "forward"), ("2", "reverse")]);
    let every_10_deg: Vec<f64> = (0..36).map(|i| f64::from(i) * 10.0).collect();
    for (run, dir, targets) in &blocks {
        let mut sorted = targets.clone();
        if dir == "reverse" {
            sorted.reverse(); // reverse is decreasing angle
        }
        assert_eq!(sorted, every_10_deg, "run {run} {dir} visits the 36 targets in its direction");
    }
    // The simulated bench records a timestamp; acquisition order means it never goes back.
    let stamps: Vec<f64> = rows.iter().map(|r| r[5].parse().expect("timestamp_s")).collect();
    assert!(stamps.windows(2).all(|w| w[0] <= w[1]), "timestamps in acquisition order");
}

#[test]
fn db_option_works_before_and_after_the_subcommand() {
    let b = Bench::new();
    b.survey(&["--db", "a.db", "run", "--points", "36", "--runs", "2", "--bidirectional"]).success();
    b.survey(&["run", "--points", "36", "--runs", "2", "--db", "b.db"]).success();
    assert!(b.exists("a.db") && b.exists("b.db"));
    assert!(!b.exists("survey.db"), "--db replaces the default database");

    let before = b.survey(&["--db", "a.db", "stats", "--json"]).success().json();
    let after = b.survey(&["stats", "--json", "--db", "a.db"]).success().json();
    assert_eq!(before, after);
    assert!(iso_figure(&before, "B").is_some(), "a.db holds the bidirectional survey");
    let other = b.survey(&["stats", "--db", "b.db", "--json"]).success().json();
    assert!(iso_figure(&other, "B").is_none(), "b.db holds the unidirectional survey");

    b.survey(&["--db", "a.db", "export", "--csv", "a1.csv"]).success();
    b.survey(&["export", "--csv", "a2.csv", "--db", "a.db"]).success();
    assert_eq!(b.read("a1.csv"), b.read("a2.csv"));

    b.write("v.csv", VALID_CSV);
    let out = b.survey(&["--db", "b.db", "import", "v.csv"]).success();
    assert_eq!(out.stdout, "2\n", "{out}");
    let out = b.survey(&["import", "v.csv", "--db", "a.db"]).success();
    assert_eq!(out.stdout, "2\n", "{out}");
    assert!(!b.exists("survey.db"));
}

#[test]
fn survey_db_environment_variable_selects_the_database() {
    let b = Bench::new();
    b.survey_with_env(&["run", "--points", "36", "--runs", "2"], "SURVEY_DB", "env.db").success();
    assert!(b.exists("env.db") && !b.exists("survey.db"));
    b.survey_with_env(&["stats", "--json"], "SURVEY_DB", "env.db").success().json();
    // --db on the command line wins over the environment.
    b.survey_with_env(&["--db", "cli.db", "run", "--points", "36", "--runs", "2"], "SURVEY_DB", "env.db").success();
    assert!(b.exists("cli.db"));
    let out = b.survey_with_env(&["stats", "--survey", "2"], "SURVEY_DB", "env.db").bad_input(&["2", "env.db"]);
    assert!(out.stdout.is_empty());
}

#[test]
fn stats_json_of_a_bidirectional_survey_has_every_figure() {
    let b = Bench::new();
    let id = b.small_survey(true);
    let out = b.survey(&["stats", "--json"]).success();
    let doc = out.json();
    assert_eq!(doc["survey_id"].as_i64(), Some(id), "{out}");
    assert_bidirectional_relations(&doc);
    // --survey picks the same survey.
    assert_eq!(b.stats_json(Some(id)), doc);
}

#[test]
fn stats_json_of_a_unidirectional_survey_has_the_keys_with_null_reverse_figures() {
    let b = Bench::new();
    let id = b.small_survey(false);
    let doc = b.stats_json(None);
    assert_eq!(doc["survey_id"].as_i64(), Some(id));
    for key in ["A", "A_up", "R", "R_up", "E", "E_up"] {
        let v = number(&doc, key);
        assert!(v.is_finite() && v > 0.0, "iso230_2.{key} = {v}");
    }
    for key in ["A_down", "R_down", "E_down", "B", "B_mean", "M"] {
        assert_eq!(iso_figure(&doc, key), None, "iso230_2.{key} should be null for a forward-only survey: {doc}");
    }
    // With one direction, the axis figures are that direction's.
    assert_eq!(number(&doc, "A"), number(&doc, "A_up"));
    assert_eq!(number(&doc, "R"), number(&doc, "R_up"));
    assert_eq!(number(&doc, "E"), number(&doc, "E_up"));
}

#[test]
fn stats_figures_are_iso230_2_of_the_exported_samples() {
    let b = Bench::new();
    let bi = b.small_survey(true);
    let uni = b.small_survey(false);
    for id in [bi, uni] {
        let csv = b.export(Some(id), &format!("s{id}.csv"));
        assert_iso_matches_csv(&b.stats_json(Some(id)), &csv);
    }
    b.write("v.csv", VALID_CSV);
    let hand = b.import("v.csv");
    assert_iso_matches_csv(&b.stats_json(Some(hand)), VALID_CSV);
}

#[test]
fn run_json_prints_one_document_with_the_statistics() {
    let b = Bench::new();
    let out = b.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--json"]).success();
    let doc = out.json();
    assert_eq!(doc["survey_id"].as_i64(), Some(1), "{out}");
    assert_bidirectional_relations(&doc);
    let stats = b.stats_json(Some(1));
    assert_eq!(doc["iso230_2"], stats["iso230_2"], "run --json reports the same figures as stats --json");

    let out = b.survey(&["run", "--points", "36", "--runs", "2", "--json"]).success();
    let doc = out.json();
    assert_eq!(doc["survey_id"].as_i64(), Some(2), "{out}");
    for key in ISO_KEYS {
        iso_figure(&doc, key);
    }
    // The contract's run keys beside the statistics.
    assert_eq!(doc["status"], "complete", "{out}");
    assert_eq!(doc["samples"].as_u64(), Some(72), "{out}");
    assert!(doc["instrument_time_s"].as_f64().is_some_and(|t| t > 0.0), "{out}");
    let faults = &doc["faults"];
    assert!(faults.get("injected").is_some() && faults["recovered"].as_u64() == Some(0), "{out}");
    for kind in ["timeout", "disconnected", "garbled", "device", "usage"] {
        assert_eq!(faults["by_kind"][kind].as_u64(), Some(0), "{kind}: {out}");
    }
}

#[test]
fn simulated_survey_is_reproducible() {
    let b = Bench::new();
    let first = b.small_survey(true);
    let second = b.small_survey(true);
    assert_eq!(b.export(Some(first), "1.csv"), b.export(Some(second), "2.csv"));
}

#[test]
fn autocollimator_reference_runs() {
    let b = Bench::new();
    let out = b.survey(&["run", "--reference", "autocollimator", "--points", "24", "--runs", "2", "--json"]).success();
    let id = out.json()["survey_id"].as_i64().expect("survey_id");
    let csv = b.export(Some(id), "ac.csv");
    assert_eq!(rows(&csv).len(), 24 * 2, "24 faces x 2 runs, forward only");
    let doc = b.stats_json(Some(id));
    assert!(number(&doc, "R") > 0.0);
}

#[test]
fn run_json_counts_the_faults_the_simulators_injected_by_kind() {
    let b = Bench::new();
    let clean = b.survey(&["run", "--points", "12", "--runs", "2", "--json"]).success().json();
    assert_eq!(clean["faults"]["injected"], 0, "the in-process simulators' count, not null: {clean}");
    let args = [
        "--db",
        "faulty.db",
        "run",
        "--points",
        "12",
        "--runs",
        "2",
        "--bidirectional",
        "--fault-rates",
        "timeout=0.0005,garbled=0.0005,disconnect=0.0005,move=0.05,beam=0.05,beam_hold_s=20",
        "--json",
    ];
    let doc = b.survey(&args).success().json();
    assert_eq!(doc["status"], "complete", "{doc}");
    let f = &doc["faults"];
    let injected = f["injected"].as_u64().unwrap_or_else(|| panic!("injected is a count: {doc}"));
    let by_kind = &f["injected_by_kind"];
    let sum: u64 = ["timeout", "garbled", "disconnect", "stall", "device", "move", "beam"]
        .iter()
        .map(|k| by_kind[*k].as_u64().unwrap_or_else(|| panic!("{k} counted: {doc}")))
        .sum();
    assert_eq!(sum, injected, "{doc}");
    assert!(by_kind["move"].as_u64().unwrap() >= 1 && by_kind["beam"].as_u64().unwrap() >= 1, "{doc}");
    // Every injected fault was met and recovered (the survey completed).
    assert!(f["recovered"].as_u64().unwrap() >= 1, "{doc}");
    // The events say so.
    let show = b.survey(&["--db", "faulty.db", "show", "--json"]).success().json();
    let events = show["events"].as_array().unwrap();
    assert!(events.iter().any(|e| e["message"].as_str().unwrap().contains("survey suspended")), "{show}");
}

#[test]
fn a_bad_fault_rate_spec_exits_2_naming_the_item() {
    let b = Bench::new();
    b.survey(&["run", "--points", "12", "--fault-rates", "lightning=0.1"]).bad_input(&["--fault-rates", "lightning"]);
    assert!(!b.exists("survey.db"), "nothing stored");
    b.write(
        "c.toml",
        "[positioner]\ndriver = \"modbus-tcp\"\naddress = \"127.0.0.1:0\"\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n",
    );
    b.survey(&["sim", "--config", "c.toml", "--fault-rates", "stall=0.9"]).bad_input(&["stall=0.9", "0 to 0.5"]);
}

#[test]
fn a_survey_that_cannot_give_iso_statistics_is_bad_input_from_resume_as_from_stats() {
    // Stopped once every step is stored (acquisition over, statistics next):
    // `resume` only concludes it.
    let b = Bench::new();
    let out = b.survey(&["run", "--points", "4", "--runs", "2", "--bidirectional", "--sim-signal-after", "16"]);
    assert_eq!(out.code, 1, "a stop is a run-time end\n{out}");
    // A stored sample moved to the other run: run 1 twice at one target.
    let db = rusqlite::Connection::open(b.path("survey.db")).expect("the database opens");
    let moved = db
        .execute("UPDATE samples SET run = 1 WHERE seq = (SELECT MIN(seq) FROM samples WHERE run = 2)", [])
        .expect("a sample is moved");
    assert_eq!(moved, 1);
    drop(db);
    // The same typed error (ISO 230-2's, a run appearing twice), the same
    // exit status from both commands.
    b.survey(&["resume"]).bad_input(&["ISO 230-2 statistics", "run 1 appears 2 times"]);
    b.survey(&["stats"]).bad_input(&["survey 1 cannot give ISO 230-2 statistics", "run 1 appears 2 times"]);
}

/// Issue 42: a log pipe that goes away must not stop a survey. With stderr
/// a pipe whose reader is gone before the first line (`survey -v run ...
/// 2>&1 >/dev/null | head -c1`), every note and log line meets a broken pipe:
/// the survey goes on, every sample is stored, the command exits 0 (it
/// exited 101, "failed printing to stderr", leaving the survey `running`).
#[test]
fn a_closed_stderr_loses_the_lines_and_never_the_survey() {
    use std::process::Stdio;
    let b = Bench::new();
    let mut child = b
        .command(&["-v", "run", "--points", "360", "--runs", "2", "--bidirectional", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stdout));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((doc["status"].as_str(), doc["samples"].as_u64()), (Some("complete"), Some(360 * 2 * 2)), "{doc}");
    let shown = b.survey(&["show", "1", "--json"]).success().json();
    assert_eq!(shown["status"], "complete", "{shown}");
}

/// Issue 42: `survey sim` counts the replies it served, faults or none (it
/// said `"replies": 0` after serving a whole survey without faults).
#[test]
fn survey_sim_counts_the_replies_it_served_without_faults() {
    use std::io::Read as _;
    let b = Bench::new();
    let mut sim = crate::serve::slow_bench(&b, 200.0);
    b.survey(&["run", "--config", "run.toml", "--json"]).success();
    nix::sys::signal::kill(nix::unistd::Pid::from_raw(sim.id() as i32), nix::sys::signal::Signal::SIGTERM).unwrap();
    let mut rest = String::new();
    sim.stdout.take().unwrap().read_to_string(&mut rest).unwrap();
    assert!(sim.wait().unwrap().success(), "{rest}");
    let stopped: serde_json::Value = serde_json::from_str(rest.lines().last().unwrap()).unwrap();
    let replies = stopped["faults"]["replies"].as_u64().unwrap();
    // 12 targets x 2 runs both ways: at least a reply a sample from each instrument.
    assert!(replies >= 2 * 48, "{stopped}");
    assert_eq!(stopped["faults"]["injected"].as_u64(), Some(0), "{stopped}");
}

/// Issue 49: a survey of a model file's positioner is named by the file,
/// never by the preset whose instruments it borrows.
#[test]
fn a_model_files_survey_is_named_by_its_file() {
    let b = Bench::new();
    b.write("mine.toml", include_str!("../../sims/presets/fig4.toml"));
    let out = b.survey(&["run", "--points", "36", "--runs", "2", "--model", "mine.toml"]).success();
    assert!(out.stderr.contains("simulated mine.toml positioner, simulated tracker reference"), "{out}");
    assert!(!out.stderr.contains("fig8"), "{out}");
    // The certificate's title too.
    let dir = b.path("out");
    b.survey(&["report", "--out", dir.to_str().unwrap()]).success();
    let page = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(page.contains("simulated mine.toml positioner") && !page.contains("fig8 positioner"), "the title");
}
