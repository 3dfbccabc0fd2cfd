//! Integrity of an acquisition (issue 9): one acquirer per survey, and a stop
//! signal at any moment commits what was measured, marks the survey
//! `interrupted` with the reason, exits 1, and `survey resume` continues it.

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use survey_store::survey::SurveyStatus;
use survey_store::{AcquirerLock, Store, lock_path};

const BIN: &str = env!("CARGO_BIN_EXE_survey");

pub(crate) fn survey(db: &Path, args: &[&str]) -> Output {
    Command::new(BIN)
        .current_dir(db.parent().unwrap())
        .env_remove("RUST_LOG")
        .arg("--db")
        .arg(db)
        .args(args)
        .output()
        .expect("the binary starts")
}

/// The exit status, stdout (its first 2000 characters) and stderr, for messages.
pub(crate) fn text(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stdout: String = stdout.chars().take(2000).collect();
    format!(
        "exit {:?}\n--- stdout ---\n{stdout}\n--- stderr ---\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Every stored sample of survey 1 is step `seq` of the plan, each once, from 0.
pub(crate) async fn dense_prefix(db: &Path) -> (SurveyStatus, usize, Vec<String>) {
    let store = Store::open_existing(db).await.unwrap();
    let record = store.survey(1).await.unwrap();
    let samples = store.recorded_samples(1).await.unwrap();
    assert!(samples.iter().enumerate().all(|(i, r)| r.seq == i as u64), "every step once, in order");
    let events = store.events(1).await.unwrap().into_iter().map(|e| e.message).collect();
    store.close().await;
    (record.status, samples.len(), events)
}

#[tokio::test]
async fn a_stop_signal_during_acquisition_keeps_what_was_measured_and_resume_finishes() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    // 360 targets x 2 runs x 2 directions = 1440 steps; SIGTERM after step
    // 1000 (not a batch boundary: 256 a batch), through the real signal path.
    let out = survey(&db, &["run", "--points", "360", "--runs", "2", "--bidirectional", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let db2 = dir.path().join("t.db");
    let args = ["run", "--points", "360", "--runs", "2", "--bidirectional", "--json", "--sim-signal-after", "1000"];
    let out = survey(&db2, &args);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "a stop is a run-time end: {all}");
    assert!(all.contains("stopped by signal (SIGTERM)") && !all.contains("UNIQUE"), "{all}");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(doc["status"], "interrupted", "{all}");
    let (status, kept, events) = dense_prefix(&db2).await;
    assert_eq!(status, SurveyStatus::Interrupted);
    // The signal is raised after step 1000's progress; the engine sees it
    // when the signal listener (another task, on a loaded machine maybe some
    // milliseconds later) has run: before or during one of the next steps.
    // The step it was measuring is dropped, never half-stored.
    assert!((1000..1440).contains(&kept), "{kept} samples kept");
    assert_eq!(doc["samples"], kept as u64, "the document says what is stored");
    assert!(events.iter().any(|e| e == "stopped by signal (SIGTERM)"), "{events:?}");
    assert!(!lock_path(&db2, 1).exists(), "the lock is released");

    let out = survey(&db2, &["resume", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let (status, n, _) = dense_prefix(&db2).await;
    assert_eq!((status, n), (SurveyStatus::Complete, 1440));
    // Resumed, it is the same survey as one never stopped, up to noise.
    let whole: serde_json::Value =
        serde_json::from_slice(&survey(&db, &["stats", "--json"]).stdout).expect("stats of the whole survey");
    let resumed: serde_json::Value =
        serde_json::from_slice(&survey(&db2, &["stats", "--json"]).stdout).expect("stats of the resumed survey");
    let (a, b) = (whole["iso230_2"]["A"].as_f64().unwrap(), resumed["iso230_2"]["A"].as_f64().unwrap());
    assert!((a - b).abs() < 0.1 * a, "accuracy A {a} against {b} (10%: new noise draws after the resume)");
}

#[tokio::test]
async fn a_stop_signal_while_processing_leaves_the_survey_for_resume_to_finish() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    // SIGTERM after the last of 720 steps: acquisition is over, processing is next.
    let args = ["run", "--points", "180", "--runs", "2", "--bidirectional", "--json", "--sim-signal-after", "720"];
    let out = survey(&db, &args);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(doc["status"], "interrupted", "{}", text(&out));
    let (status, n, events) = dense_prefix(&db).await;
    assert_eq!((status, n), (SurveyStatus::Interrupted, 720));
    assert!(events.iter().any(|e| e.contains("stopped by signal (SIGTERM) while processing")), "{events:?}");

    let out = survey(&db, &["resume", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(doc["status"], "complete");
    assert!(doc["process"]["table"]["path"].is_string(), "processed: {doc}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("all 720 samples are stored: finishing"));
    let (status, n, _) = dense_prefix(&db).await;
    assert_eq!((status, n), (SurveyStatus::Complete, 720));
}

/// The names in `folder` of our temporary files (`.<name>.tmp-<pid>`).
fn temporary_files(folder: &Path) -> Vec<String> {
    std::fs::read_dir(folder)
        .map(|d| {
            d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).filter(|n| n.contains(".tmp-")).collect()
        })
        .unwrap_or_default()
}

#[tokio::test]
async fn a_kill_while_the_outputs_are_written_leaves_the_survey_processing_and_resume_writes_them() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    let folder = dir.path().join("s.db.survey-1");
    // The process aborts (a power loss, as SIGKILL) with every output written
    // to its temporary name and none renamed into place.
    let args = ["run", "--points", "36", "--runs", "2", "--bidirectional", "--json", "--sim-crash-in-outputs"];
    let out = survey(&db, &args);
    assert_eq!(out.status.code(), None, "killed by a signal: {}", text(&out));
    assert!(!temporary_files(&folder).is_empty(), "the kill left the staged files");
    assert!(!folder.join("table-1.csv").exists(), "no table yet");
    let (status, n, _) = dense_prefix(&db).await;
    assert_eq!((status, n), (SurveyStatus::Processing, 144), "acquired whole, not complete without its table");
    let list = survey(&db, &["list"]);
    assert!(text(&list).contains("processing"), "{}", text(&list));

    let out = survey(&db, &["resume", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(String::from_utf8_lossy(&out.stderr).contains("all 144 samples are stored: finishing"), "{}", text(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(doc["status"], "complete");
    assert_eq!(doc["process"]["table"]["path"], folder.join("table-1.csv").display().to_string());
    assert!(std::fs::read_to_string(folder.join("table-1.csv")).unwrap().starts_with("readout_deg,"));
    assert_eq!(temporary_files(&folder), Vec::<String>::new(), "the stale temporary files are removed");
    assert_eq!(dense_prefix(&db).await.0, SurveyStatus::Complete);
    let again = survey(&db, &["resume"]);
    assert_eq!(again.status.code(), Some(2), "{}", text(&again));
    assert!(text(&again).contains("nothing to resume"), "{}", text(&again));
}

/// Runs `survey --db DB args` in a mount namespace of its own where `folder`
/// is a 64 KiB tmpfs: a really full disk for what is written there. Prints
/// what the folder holds when the command ends (`left: ...` on stderr).
/// `None` when this machine does not let an unprivileged user namespace
/// mount one (the reason printed).
fn on_a_full_folder(folder: &Path, db: &Path, args: &[&str]) -> Option<Output> {
    const SCRIPT: &str = r#"f=$1; shift; mount -t tmpfs -o size=64k survey-test "$f" || exit 99; "$@"; rc=$?; echo "left: $(ls -A "$f" | tr '\n' ' ')" >&2; exit $rc"#;
    let probe = Command::new("unshare")
        .args(["--user", "--map-root-user", "--mount", "sh", "-c", SCRIPT, "sh"])
        .arg(folder)
        .arg("true")
        .output();
    match probe {
        Ok(p) if p.status.success() => {}
        other => {
            eprintln!("skipped: no tmpfs in a user namespace here ({other:?})");
            return None;
        }
    }
    let out = Command::new("unshare")
        .args(["--user", "--map-root-user", "--mount", "sh", "-c", SCRIPT, "sh"])
        .arg(folder)
        .arg(BIN)
        .current_dir(db.parent().unwrap())
        .env_remove("RUST_LOG")
        .arg("--db")
        .arg(db)
        .args(args)
        .output()
        .unwrap();
    Some(out)
}

#[tokio::test]
async fn a_full_disk_while_the_outputs_are_written_leaves_no_temporary_file_and_resume_writes_them() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    let folder = dir.path().join("s.db.survey-1");
    std::fs::create_dir(&folder).unwrap();
    let args = ["run", "--points", "36", "--runs", "2", "--bidirectional", "--json"];
    let Some(out) = on_a_full_folder(&folder, &db, &args) else { return };
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "a full disk is a run-time failure: {all}");
    assert!(all.contains("No space left on device") && all.contains("table-1"), "{all}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let left = stderr.lines().find_map(|l| l.strip_prefix("left:")).expect("the folder listed");
    assert_eq!(left.trim(), "", "no temporary file stays on the full disk: {all}");
    assert!(all.contains("`survey resume` writes them"), "{all}");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(doc["status"], "interrupted", "{all}");
    let (status, n, events) = dense_prefix(&db).await;
    assert_eq!((status, n), (SurveyStatus::Interrupted, 144));
    assert!(events.iter().any(|e| e.contains("its outputs could not be written")), "{events:?}");

    // Space freed (the namespace and its tmpfs are gone): resume writes them.
    let out = survey(&db, &["resume", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(std::fs::read_to_string(folder.join("table-1.csv")).unwrap().starts_with("readout_deg,"));
    assert_eq!(dense_prefix(&db).await.0, SurveyStatus::Complete);
}

#[tokio::test]
async fn resume_is_refused_while_another_process_holds_the_survey_and_takes_over_a_dead_ones_lock() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    let out = survey(&db, &["run", "--points", "90", "--runs", "2", "--sim-crash-after", "100"]);
    assert_ne!(out.status.code(), Some(0), "the run was to crash");
    assert!(lock_path(&db, 1).exists(), "a crashed acquirer leaves its lock file (the kernel freed the lock)");

    let stale = dense_prefix(&db).await;
    // Stored `running`, its lock free: read as interrupted.
    assert_eq!((stale.0, stale.1), (SurveyStatus::Interrupted, 90), "the first pass was committed before the crash");
    // This test process holds the survey: resume is refused, naming it.
    let held = AcquirerLock::acquire(&db, 1).unwrap();
    assert!(held.took_over.is_some(), "the crashed run's lock was recognised as dead and taken over");
    let before = dense_prefix(&db).await;
    assert_eq!(before.0, SurveyStatus::Running, "a live process holds it");
    let out = survey(&db, &["resume"]);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "{all}");
    assert!(all.contains(&format!("survey 1 is being acquired by process {} on", std::process::id())), "{all}");
    assert_eq!(dense_prefix(&db).await, before, "the refused resume changed nothing");
    drop(held);

    let out = survey(&db, &["resume"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert_eq!(dense_prefix(&db).await.1, 180, "90 targets x 2 runs, one direction");
}

#[tokio::test]
async fn a_live_run_keeps_its_survey_from_resume_and_a_sigterm_from_outside_stops_it_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    // A long survey (720000 steps): it is stopped long before its end.
    let run = Command::new(BIN)
        .current_dir(dir.path())
        .env_remove("RUST_LOG")
        .arg("--db")
        .arg(&db)
        .args(["run", "--points", "36000", "--runs", "10", "--bidirectional", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait (bounded) until the run has stored samples: its lock is taken
    // before its survey is visible, so from then on it is held.
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        // Until the run has set the new file up, it holds no survey table
        // and is refused (nothing is written to it).
        if let Ok(store) = Store::open_existing(&db).await {
            let n = store.sample_count(1).await.unwrap_or(0);
            store.close().await;
            if n >= 512 {
                break;
            }
        }
        assert!(Instant::now() < deadline, "the run stored nothing in 120 s");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let out = survey(&db, &["resume"]);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "{all}");
    assert!(all.contains(&format!("being acquired by process {} on", run.id())), "{all}");

    kill(Pid::from_raw(run.id() as i32), Signal::SIGTERM).unwrap();
    let out = run.wait_with_output().unwrap();
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "{all}");
    assert!(all.contains("stopped by signal (SIGTERM)") && !all.contains("UNIQUE"), "{all}");
    let (status, n, events) = dense_prefix(&db).await;
    assert_eq!(status, SurveyStatus::Interrupted, "{all}");
    assert!((512..720_000).contains(&n), "{n}");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(doc["samples"], n as u64, "what it says is stored is what is stored");
    assert!(events.iter().any(|e| e == "stopped by signal (SIGTERM)"), "{events:?}");
}

#[tokio::test]
async fn stats_says_how_much_of_an_incomplete_survey_is_there() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    // 36 targets x 4 runs x 2 directions; stopped after 200 steps: runs 1 and 2
    // (144 steps) are complete, run 3 is cut short.
    let args = ["run", "--points", "36", "--runs", "4", "--bidirectional", "--sim-signal-after", "200"];
    assert_eq!(survey(&db, &args).status.code(), Some(1));
    let out = survey(&db, &["stats", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(doc["complete"], false);
    assert_eq!((doc["runs_complete"].as_u64(), doc["runs_planned"].as_u64()), (Some(2), Some(4)));
    assert_eq!(doc["status"], "interrupted");
    let out = survey(&db, &["stats"]);
    let all = text(&out);
    assert!(all.contains("2 of 4 runs complete") && all.contains("36 targets x 2 runs"), "{all}");

    assert_eq!(survey(&db, &["resume"]).status.code(), Some(0));
    let doc: serde_json::Value = serde_json::from_slice(&survey(&db, &["stats", "--json"]).stdout).unwrap();
    assert_eq!((doc["complete"].as_bool(), doc["runs_complete"].as_u64()), (Some(true), Some(4)));
}

#[tokio::test]
async fn a_full_disk_stops_the_survey_claims_only_what_is_stored_and_resume_remeasures_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    // The database may hold 44 pages (SQLite's max_page_count: the same
    // SQLITE_FULL as a full disk): the survey (360 x 2 x 2 = 1440 steps) fills it.
    // (40 until migration 11's certificates took 3 pages of an empty file.)
    let args = ["run", "--points", "360", "--runs", "2", "--bidirectional", "--json", "--sim-db-max-pages", "44"];
    let out = survey(&db, &args);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "a failed commit stops the acquisition: {all}");
    // Said in words, naming the file (issue 51 item 5), on the stop line and in the stored event.
    let stop = all.lines().find(|l| l.starts_with("survey 1 stopped: ")).unwrap_or_else(|| panic!("{all}"));
    assert!(stop.contains(&db.display().to_string()) && stop.contains("the disk is full"), "{stop}");
    assert!(!stop.contains("code: 13") && !stop.contains("error returned from database"), "{stop}");
    let (status, kept, _) = dense_prefix(&db).await;
    assert!(kept > 0 && kept < 1440, "{kept}");
    // What is claimed stored is what is on disk.
    assert!(all.contains(&format!("{kept} samples are stored")), "{all}");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(doc["samples"], kept as u64, "{all}");
    // The status could not be written on a full database either, or was: both resume.
    assert!(matches!(status, SurveyStatus::Running | SurveyStatus::Interrupted), "{status:?}");

    let out = survey(&db, &["resume", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(String::from_utf8_lossy(&out.stderr).contains(&format!("resumed at step {kept}")));
    let (status, n, _) = dense_prefix(&db).await;
    assert_eq!((status, n), (SurveyStatus::Complete, 1440), "exactly what was lost was measured again");
    // The stop's event, where the full file still took it: in the same words.
    let conn = rusqlite::Connection::open(&db).unwrap();
    let mut q = conn.prepare("SELECT message FROM events").unwrap();
    let events: Vec<String> = q.query_map([], |r| r.get(0)).unwrap().map(Result::unwrap).collect();
    assert!(events.iter().all(|e| !e.contains("code: 13")), "{events:#?}");
}

fn sha(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()))
}

#[tokio::test]
async fn read_only_commands_never_write_and_refuse_foreign_damaged_or_newer_files_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    assert_eq!(survey(&db, &["run", "--points", "36", "--runs", "2", "--bidirectional"]).status.code(), Some(0));
    let mut before = sha(&db);
    let model = dir.path().join("m.toml");
    std::fs::write(&model, "[[effect]]\nkind = \"noise\"\nsigma_deg = 0.001\n").unwrap();
    let out_dir = dir.path().join("report");
    let (csv, table) = (dir.path().join("e.csv"), dir.path().join("t.csv"));
    let m = model.to_str().unwrap();
    let commands: [Vec<&str>; 5] = [
        vec!["stats", "--json"],
        vec!["export", "--csv", csv.to_str().unwrap()],
        vec!["process", "--table-out", table.to_str().unwrap()],
        vec!["report", "--out", out_dir.to_str().unwrap()],
        vec!["model-gap", "--model", m],
    ];
    for args in &commands {
        let out = survey(&db, args);
        assert_eq!(out.status.code(), Some(0), "{}", text(&out));
        if args[0] == "report" {
            // The one write of a report: the certificate it issues (issue 50), kept in the file.
            before = sha(&db);
            continue;
        }
        assert!(sha(&db) == before, "`survey {}` changed the database file", args.join(" "));
    }

    // Another application's SQLite file: refused, and not touched.
    let foreign = dir.path().join("app.sqlite");
    make_foreign(&foreign);
    let foreign_before = sha(&foreign);
    for args in &commands {
        let out = survey(&foreign, args);
        let all = text(&out);
        assert_eq!(out.status.code(), Some(2), "{all}");
        assert!(all.contains("app.sqlite is not a survey database"), "{all}");
        assert!(sha(&foreign) == foreign_before, "`survey {}` changed another application's file", args.join(" "));
        assert!(!dir.path().join("app.sqlite-wal").exists(), "no WAL was made beside it");
    }

    // A damaged database (pages overwritten) and one from a newer version.
    let damaged = dir.path().join("damaged.db");
    let mut bytes = before.clone();
    for b in bytes.iter_mut().skip(4096).take(4096 * 3) {
        *b = 0xff;
    }
    std::fs::write(&damaged, &bytes).unwrap();
    let out = survey(&damaged, &["stats"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("damaged.db is damaged"), "{}", text(&out));

    let newer = dir.path().join("newer.db");
    std::fs::copy(&db, &newer).unwrap();
    let store = Store::open(&newer).await.unwrap();
    store.close().await;
    bump_schema(&newer);
    let out = survey(&newer, &["stats"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("newer.db was written by a newer version of survey"), "{}", text(&out));
}

#[tokio::test]
async fn every_command_refuses_a_foreign_database_a_folder_or_a_device_with_exit_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    assert_eq!(survey(&db, &["run", "--points", "36", "--runs", "2"]).status.code(), Some(0));
    let csv = dir.path().join("in.csv");
    assert_eq!(survey(&db, &["export", "--csv", csv.to_str().unwrap()]).status.code(), Some(0));
    let model = dir.path().join("m.toml");
    std::fs::write(&model, "[[effect]]\nkind = \"noise\"\nsigma_deg = 0.001\n").unwrap();
    let (out_csv, table, report) = (dir.path().join("e.csv"), dir.path().join("t.csv"), dir.path().join("report"));
    let commands: Vec<Vec<&str>> = vec![
        vec!["run", "--points", "36", "--runs", "2"],
        vec!["import", csv.to_str().unwrap()],
        vec!["resume"],
        vec!["stats"],
        vec!["list"],
        vec!["show"],
        vec!["export", "--csv", out_csv.to_str().unwrap()],
        vec!["process", "--table-out", table.to_str().unwrap()],
        vec!["report", "--out", report.to_str().unwrap()],
        vec!["model-gap", "--model", model.to_str().unwrap()],
    ];
    // Another application's SQLite file (in WAL mode or not): refused, its
    // bytes unchanged, no WAL or shared-memory file made beside it.
    for wal in [false, true] {
        let foreign = dir.path().join(format!("app{wal}.sqlite"));
        make_foreign(&foreign);
        if wal {
            rusqlite::Connection::open(&foreign).unwrap().pragma_update(None, "journal_mode", "wal").unwrap();
        }
        let before = sha(&foreign);
        for args in &commands {
            let out = survey(&foreign, args);
            let all = text(&out);
            assert_eq!(out.status.code(), Some(2), "survey {}: {all}", args.join(" "));
            assert!(all.contains(&format!("app{wal}.sqlite is not a survey database")), "{all}");
            assert!(sha(&foreign) == before, "`survey {}` changed another application's file", args.join(" "));
            for suffix in ["-wal", "-shm", "-journal"] {
                assert!(!dir.path().join(format!("app{wal}.sqlite{suffix}")).exists(), "{suffix} made: {all}");
            }
        }
    }
    // A folder and a device: a clear message, exit 2, nothing made.
    let folder = dir.path().join("a-folder");
    std::fs::create_dir(&folder).unwrap();
    for (path, says) in [(folder.as_path(), "is a folder"), (Path::new("/dev/null"), "is not a regular file")] {
        for args in &commands {
            let out = survey(path, args);
            let all = text(&out);
            assert_eq!(out.status.code(), Some(2), "survey --db {} {}: {all}", path.display(), args.join(" "));
            assert!(all.contains(&format!("{} {says}", path.display())) && !all.contains("SQLite"), "{all}");
        }
    }
    assert_eq!(std::fs::read_dir(&folder).unwrap().count(), 0, "nothing made in the folder");
    use std::os::unix::fs::FileTypeExt as _;
    assert!(std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());
    // A database in a folder that does not exist: said so, not created.
    let nowhere = dir.path().join("no/such/folder/x.db");
    let out = Command::new(BIN)
        .current_dir(dir.path())
        .arg("--db")
        .arg(&nowhere)
        .args(["run", "--points", "36", "--runs", "2"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("the folder") && text(&out).contains("does not exist"), "{}", text(&out));
    // A new file is made where none exists, and an empty one is set up.
    let empty = dir.path().join("empty.db");
    std::fs::write(&empty, b"").unwrap();
    assert_eq!(survey(&empty, &["import", csv.to_str().unwrap()]).status.code(), Some(0));
    assert_eq!(survey(&empty, &["stats"]).status.code(), Some(0));
}

/// An SQLite file of another application: one table of its own.
fn make_foreign(path: &Path) {
    let c = rusqlite::Connection::open(path).unwrap();
    c.execute_batch("CREATE TABLE notes (x); INSERT INTO notes VALUES (1);").unwrap();
}

/// Record a schema version this build does not know.
fn bump_schema(path: &Path) {
    let c = rusqlite::Connection::open(path).unwrap();
    c.execute_batch(
        "INSERT INTO _sqlx_migrations (version, description, installed_on, success, checksum, execution_time) \
         VALUES (99, 'future', 0, 1, x'00', 0)",
    )
    .unwrap();
}

#[test]
fn default_table_names_never_collide_across_databases() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["a.db", "b.db", "survey.db"] {
        let out = survey(&dir.path().join(name), &["run", "--points", "36", "--runs", "2", "--json"]);
        assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    }
    // Each survey's files go in its own folder: `<db>.survey-<id>/` beside
    // any database but the default.
    let a = std::fs::read_to_string(dir.path().join("a.db.survey-1/table-1.csv")).expect("a's table");
    let b = std::fs::read_to_string(dir.path().join("b.db.survey-1/table-1.csv")).expect("b's table");
    assert!(a.starts_with("readout_deg,") && b.starts_with("readout_deg,"));
    assert!(dir.path().join("a.db.survey-1/table-1.recipe.toml").exists());
    assert!(dir.path().join("b.db.survey-1/table-1.bin").exists());
    // survey() passes --db as an absolute path: that is another database than
    // the default `survey.db` of the current folder, so it is named too.
    assert!(dir.path().join(format!("{}.survey-1/table-1.csv", dir.path().join("survey.db").display())).exists());

    // The default database keeps `survey-<id>/` in the current folder, named
    // in the summary and in `--json`'s table path; nothing else lands there.
    let here = tempfile::tempdir().unwrap();
    for expected in ["survey-1/table-1.csv", "survey-2/table-2.csv"] {
        let out = Command::new(BIN)
            .current_dir(here.path())
            .env_remove("RUST_LOG")
            .args(["run", "--points", "36", "--runs", "2", "--json"])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", text(&out));
        let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(doc["process"]["table"]["path"], expected, "{}", text(&out));
        assert!(here.path().join(expected).exists(), "{expected}");
    }
    let mut names: Vec<String> = std::fs::read_dir(here.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["survey-1", "survey-2", "survey.db"], "one folder per survey and the database, nothing else");
    let out =
        Command::new(BIN).current_dir(here.path()).args(["run", "--points", "36", "--runs", "2"]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("survey-3/table-3.csv"), "{}", text(&out));
}

#[test]
fn table_out_follows_links_writes_into_devices_and_pipes_and_never_replaces_them() {
    use std::os::unix::fs::FileTypeExt as _;
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    assert_eq!(survey(&db, &["run", "--points", "36", "--runs", "2"]).status.code(), Some(0));

    // A full device: the write fails, exit status 1, the device stays a device.
    let out = survey(&db, &["process", "--table-out", "/dev/full"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("cannot write /dev/full"), "{}", text(&out));
    assert!(std::fs::metadata("/dev/full").unwrap().file_type().is_char_device());

    // A symbolic link is followed: the file it names gets the table.
    let real = dir.path().join("real.csv");
    let link = dir.path().join("link.csv");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let out = survey(&db, &["process", "--table-out", link.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link is still a link");
    assert!(std::fs::read_to_string(&real).unwrap().starts_with("readout_deg,"));

    // A named pipe is written into (a reader takes the table), and stays a pipe.
    let fifo = dir.path().join("table.fifo");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::from_bits_truncate(0o600)).unwrap();
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    let out = survey(&db, &["process", "--table-out", fifo.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(reader.join().unwrap().starts_with("readout_deg,"), "the reader got the table");
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    assert!(!dir.path().join("table.fifo.recipe.toml").exists(), "no side files beside a pipe");

    // A folder is not a file: bad usage.
    let out = survey(&db, &["process", "--table-out", dir.path().to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("is a folder"), "{}", text(&out));
}
