//! A stale `running` survey is `interrupted` for every reader (contract, "the
//! pages' truth"): a survey stored as `running` whose acquisition lock no
//! process holds reads as `interrupted` in `list`, `show`, `history`, on `/`
//! and is not on `/api/live`; one whose lock a live process holds still
//! reads `running`. The stored row is left as it is: readers never write.

use super::Bench;
use super::serve::{Server, get};
use serde_json::Value;

/// The status of survey `id` as `list --json`, `show --json` and `history
/// --json` show it, in that order.
fn statuses(bench: &Bench, id: i64) -> [String; 3] {
    let list = bench.survey(&["list", "--json"]).success().json();
    let listed = list["surveys"].as_array().unwrap().iter().find(|s| s["id"] == id).expect("listed").clone();
    let show = bench.survey(&["show", &id.to_string(), "--json"]).success().json();
    let asset = listed["asset"].as_str().unwrap().to_string();
    let history = bench.survey(&["history", "--asset", &asset, "--json"]).success().json();
    let in_history = history["surveys"].as_array().unwrap().iter().find(|s| s["id"] == id).expect("in the history");
    let status = |v: &Value| v["status"].as_str().unwrap_or_else(|| panic!("a status in {v}")).to_string();
    [status(&listed), status(&show), status(in_history)]
}

/// The stored status column of survey `id`, read past the program.
fn stored(bench: &Bench, id: i64) -> String {
    let conn = rusqlite::Connection::open(bench.path("survey.db")).unwrap();
    conn.query_row("SELECT status FROM surveys WHERE id = ?1", [id], |r| r.get(0)).unwrap()
}

#[test]
fn a_survey_left_running_by_a_killed_process_reads_as_interrupted_everywhere() {
    let bench = Bench::new();
    let killed = bench.command(&["run", "--points", "36", "--runs", "2", "--sim-crash-after", "10"]).output().unwrap();
    assert!(!killed.status.success(), "the crash hook aborts the process");
    assert_eq!(stored(&bench, 1), "running", "what a killed acquirer leaves");
    assert_eq!(statuses(&bench, 1), ["interrupted", "interrupted", "interrupted"]);
    let server = Server::on(&bench, "survey.db", &[]);
    assert_eq!(get(&server.url, "/api/live").json(), serde_json::json!({"surveys": []}));
    let uid = bench.survey(&["show", "--json"]).success().json()["uid"].as_str().unwrap().to_string();
    let home = get(&server.url, "/");
    assert_eq!(home.status, 200, "{}", home.body);
    assert!(!home.body.contains(&format!("live-{uid}")), "not listed as being acquired:\n{}", home.body);
    assert_eq!(server.stop(), Some(0));
    assert_eq!(stored(&bench, 1), "running", "readers write nothing");
    // The survey is what it reads as: resumable, and then complete.
    bench.survey(&["resume"]).success();
    assert_eq!(statuses(&bench, 1), ["complete", "complete", "complete"]);
}

#[test]
fn a_running_survey_whose_lock_is_held_reads_as_running_and_is_live() {
    let bench = Bench::new();
    let id = bench.small_survey(false);
    // A row set to `running` (as a kill after the status write would leave it).
    let conn = rusqlite::Connection::open(bench.path("survey.db")).unwrap();
    conn.execute("UPDATE surveys SET status = 'running' WHERE id = ?1", [id]).unwrap();
    drop(conn);
    assert_eq!(statuses(&bench, id), ["interrupted", "interrupted", "interrupted"], "no process holds it");
    // A live acquirer: this test process, through the store's lock.
    let lock = survey_store::AcquirerLock::acquire(&bench.path("survey.db"), id).unwrap();
    assert_eq!(statuses(&bench, id), ["running", "running", "running"], "its lock is held");
    let server = Server::on(&bench, "survey.db", &[]);
    let live = get(&server.url, "/api/live").json();
    let listed: Vec<i64> = live["surveys"].as_array().unwrap().iter().map(|s| s["id"].as_i64().unwrap()).collect();
    assert_eq!(listed, [id], "{live}");
    // The acquirer is gone: at once interrupted, on the pages too.
    drop(lock);
    assert_eq!(get(&server.url, "/api/live").json(), serde_json::json!({"surveys": []}));
    assert_eq!(statuses(&bench, id), ["interrupted", "interrupted", "interrupted"]);
    assert_eq!(server.stop(), Some(0));
}

/// A folder on the small file system of `SURVEY_TEST_SMALL_FS`, removed when dropped.
struct SmallFs(std::path::PathBuf);

impl Drop for SmallFs {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The disk fills up during `survey run` (issue 42 item 3, as reported: a
/// 2 MiB file system, 3600 points x 3 runs both ways): the survey is stored
/// `interrupted`, not left `running`; once space is freed, `resume` stores
/// more, each sample once, and stops `interrupted` again when the disk is
/// full again. Skipped, saying so, without `SURVEY_TEST_SMALL_FS` (a folder
/// on a small file system: `.ci/run` mounts one).
#[test]
fn a_full_disk_stores_the_survey_interrupted_and_resume_goes_on_once_space_is_freed() {
    let Some(small) = std::env::var_os("SURVEY_TEST_SMALL_FS") else {
        eprintln!("skipped: SURVEY_TEST_SMALL_FS names no folder on a small file system");
        return;
    };
    let dir = SmallFs(std::path::Path::new(&small).join(format!("cli-{}", std::process::id())));
    std::fs::create_dir_all(&dir.0).unwrap();
    let db = dir.0.join("full.db");
    let db_text = db.to_str().unwrap();
    let ballast = dir.0.join("ballast");
    std::fs::write(&ballast, vec![1u8; 1024 * 1024]).unwrap();
    let bench = Bench::new();
    let stored = || -> (String, i64) {
        let conn = rusqlite::Connection::open_with_flags(&db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY).unwrap();
        conn.query_row("SELECT status, (SELECT COUNT(*) FROM samples) FROM surveys WHERE id = 1", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
        .unwrap()
    };
    let run = bench.survey(&["--db", db_text, "run", "--points", "3600", "--runs", "3", "--bidirectional"]);
    assert_eq!(run.code, 1, "a full disk is a run-time failure\n{run}");
    assert!(run.stderr.contains("full") && !run.stderr.contains("could not be stored"), "{run}");
    let (status, first) = stored();
    assert_eq!(status, "interrupted", "the status on disk\n{run}");
    assert!(first > 0 && first < 21_600, "{first} samples");
    let listed = bench.survey(&["--db", db_text, "list", "--json"]).success().json();
    assert_eq!(listed["surveys"][0]["status"], "interrupted");

    std::fs::remove_file(&ballast).unwrap();
    let resumed = bench.survey(&["--db", db_text, "resume"]);
    assert_eq!(resumed.code, 1, "the 2 MiB fill up again before 21600 samples\n{resumed}");
    let (status, second) = stored();
    assert_eq!(status, "interrupted", "{resumed}");
    assert!(second > first, "the resume stored more: {first} then {second}\n{resumed}");
    let conn = rusqlite::Connection::open_with_flags(&db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY).unwrap();
    let (distinct, last): (i64, i64) = conn
        .query_row("SELECT COUNT(DISTINCT seq), MAX(seq) FROM samples", [], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap();
    assert_eq!((distinct, last + 1), (second, second), "each sample once, none missing");
}
