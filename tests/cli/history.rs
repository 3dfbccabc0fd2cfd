//! The history of an asset computed once (issue 40): what `survey run`,
//! `run --check`, `import` and `resume` keep (each complete survey's
//! summary, each consecutive pair's comparison) gives `survey history` and
//! the report's section exactly what computing them gives; a read-only
//! command never writes it, and reads a database without it (emptied,
//! another version's, undecodable, or one of schema 7) to the same bytes.

use super::Bench;
use rusqlite::Connection;

/// Rows of `table` in the bench's database.
fn count(bench: &Bench, table: &str) -> i64 {
    let db = Connection::open(bench.path("survey.db")).unwrap();
    db.query_row(&format!("SELECT COUNT(*) FROM {table}"), [], |r| r.get(0)).unwrap()
}

/// `sql` on the bench's database.
fn execute(bench: &Bench, sql: &str) {
    Connection::open(bench.path("survey.db")).unwrap().execute_batch(sql).unwrap();
}

/// `survey history` of `asset` as JSON and as text, and the report's history
/// section of survey `report`.
fn history(bench: &Bench, asset: &str, report: &str) -> (String, String, String) {
    let json = bench.survey(&["history", "--asset", asset, "--json"]).success().stdout;
    let text = bench.survey(&["history", "--asset", asset]).success().stdout;
    // The first report issues the certificate; a later one amends it, so that its history is computed again.
    let issued: i64 = Connection::open(bench.path("survey.db"))
        .and_then(|db| db.query_row("SELECT COUNT(*) FROM certificates", [], |r| r.get(0)))
        .unwrap_or(0);
    let mut args = vec!["report", "--survey", report, "--out", "r"];
    if issued > 0 {
        args.extend(["--amend", "the history read again"]);
    }
    bench.survey(&args).success();
    let html = bench.read("r/index.html");
    let start = html.find("<section id=\"history\"").expect("a history section");
    let end = start + html[start..].find("</section>").unwrap();
    (json, text, html[start..end].to_string())
}

#[test]
fn history_read_from_what_the_commands_keep_is_what_computing_it_gives_bit_for_bit() {
    let bench = Bench::new();
    let small = ["--points", "36", "--runs", "2", "--bidirectional", "--json"];
    let run = |extra: &[&str]| {
        let mut args = vec!["run"];
        args.extend(small);
        args.extend(extra);
        bench.survey(&args)
    };
    // Two calibrations of one positioner, a check, a calibration with its
    // verification (listed, not compared), and an import of one run (a pair
    // that cannot be compared: said, and kept so).
    run(&["--seed", "1"]).success();
    run(&["--seed", "2"]).success();
    // In tolerance, recalibrated, or not decided (exit 1): a check survey either way.
    let check = bench.survey(&["run", "--check", "--seed", "3", "--json"]);
    assert!(matches!(check.code, 0 | 1 | 3) && check.stdout.contains("\"check\""), "{check}");
    run(&["--seed", "4", "--verify"]).success();
    bench.write(
        "one-run.csv",
        "run,direction,target_deg,readout_deg,actual_deg\n1,forward,0,0,0.001\n1,forward,180,180,180.002\n",
    );
    bench.survey(&["import", "one-run.csv", "--asset", "sim-fig8"]).success();

    // Every complete survey's summary and every consecutive pair of the
    // native ones (calibrations, checks, the import), of one version.
    let listed = bench.survey(&["list", "--json"]).success().json();
    let surveys = listed["surveys"].as_array().unwrap();
    let complete = surveys.iter().filter(|s| matches!(s["status"].as_str(), Some("complete" | "imported"))).count();
    assert!(complete >= 6, "{listed:#}");
    assert_eq!(count(&bench, "survey_summaries"), complete as i64);
    let h = bench.survey(&["history", "--asset", "sim-fig8", "--json"]).success().json();
    let natives = h["surveys"].as_array().unwrap().iter().filter(|s| s["kind"] != "verification").count() as i64;
    assert_eq!(count(&bench, "survey_changes"), natives - 1, "{h:#}");
    assert_eq!(h["not_compared"].as_array().map(Vec::len), Some(1), "{h:#}");
    let versions =
        count(&bench, "(SELECT DISTINCT version FROM survey_summaries UNION SELECT version FROM survey_changes)");
    assert_eq!(versions, 1);

    let kinds: Vec<&str> = h["surveys"].as_array().unwrap().iter().map(|s| s["kind"].as_str().unwrap()).collect();
    assert!(kinds.contains(&"check") && kinds.contains(&"verification"), "{kinds:?}");
    let last = h["surveys"]
        .as_array()
        .unwrap()
        .iter()
        .rev()
        .find(|s| s["kind"] == "calibration" && s["samples"].as_u64() > Some(2))
        .unwrap()["id"]
        .to_string();
    let kept = history(&bench, "sim-fig8", &last);
    assert!(kept.1.contains("not compared: survey") && kept.2.contains("fig-history-a"), "{}", kept.1);

    // Nothing kept: computed on read, the same bytes, and nothing written.
    execute(&bench, "UPDATE survey_summaries SET version = 'old'; UPDATE survey_changes SET version = 'old';");
    assert_eq!(history(&bench, "sim-fig8", &last), kept, "another version's entries are not read");
    execute(&bench, "DELETE FROM survey_summaries; DELETE FROM survey_changes;");
    assert_eq!(history(&bench, "sim-fig8", &last), kept, "computed on read");
    assert_eq!((count(&bench, "survey_summaries"), count(&bench, "survey_changes")), (0, 0), "a reader writes nothing");

    // A check stored before the control chart (schema 11 and older) has no
    // figures: its point is null, and the history says so.
    let charted = h["surveys"].as_array().unwrap().iter().find(|s| s["kind"] == "check").unwrap()["check"].clone();
    assert!(charted["control"]["statistic"].as_f64().is_some(), "{charted}");
    execute(
        &bench,
        "UPDATE checks SET residual_peak_deg = NULL, stated_u_deg = NULL, cells_outside = NULL, allowed_outside = NULL;",
    );
    let kept = history(&bench, "sim-fig8", &last);
    assert!(kept.1.contains("control chart: not measured (a check stored before the chart)"), "{}", kept.1);
    let h = bench.survey(&["history", "--asset", "sim-fig8", "--json"]).success().json();

    // A database of schema 7 (before the cache) is read as it is.
    execute(
        &bench,
        "DROP TABLE certificate_numbers; DROP TABLE certificates; DROP TABLE survey_summaries; DROP TABLE survey_changes; DROP TABLE smr_readings; ALTER TABLE \
         raw_readings DROP COLUMN air_temperature_c; ALTER TABLE raw_readings DROP COLUMN air_pressure_hpa; ALTER TABLE raw_readings DROP \
         COLUMN air_humidity_pct; ALTER TABLE checks DROP COLUMN residual_peak_deg; ALTER TABLE checks DROP COLUMN \
         stated_u_deg; ALTER TABLE checks DROP COLUMN cells_outside; ALTER TABLE checks DROP COLUMN allowed_outside; \
         DELETE FROM _sqlx_migrations WHERE version >= 8;",
    );
    assert_eq!(history(&bench, "sim-fig8", &last), kept, "schema 7, read-only");
    bench.survey(&["list"]).success();
    // The next command that writes upgrades it and keeps the whole history
    // of the asset it wrote to: read from it, the same bytes again.
    run(&["--seed", "5"]).success();
    assert_eq!(count(&bench, "survey_summaries"), complete as i64 + 1);
    let grown = bench.survey(&["history", "--asset", "sim-fig8", "--json"]).success().json();
    let before = h["surveys"].as_array().unwrap();
    assert_eq!(grown["surveys"].as_array().unwrap()[..before.len()], before[..]);
    let kept_again = history(&bench, "sim-fig8", &last);
    assert_eq!(kept_again.2, kept.2, "the report's history up to its survey");

    // Entries that do not decode are measured again, never trusted.
    execute(&bench, "UPDATE survey_summaries SET data = x'00'; UPDATE survey_changes SET data = x'0000';");
    assert_eq!(history(&bench, "sim-fig8", &last), kept_again, "undecodable entries");
}
