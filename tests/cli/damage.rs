//! A damaged survey database is refused (issue 42, item 4): a copy of a good
//! file with a table dropped, or with 4 KiB of a page overwritten. Every
//! command exits 2 saying the file is damaged and what is wrong, writes
//! nothing into it (its bytes stay as they were), and a read-only command
//! leaves no `-wal` or `-shm` file beside it; `survey serve` answers 503 with
//! a page that says so in words.

use super::serve::{Server, get};
use super::{Bench, Output, VALID_CSV};

/// A good database (one small bidirectional survey) copied to `name`,
/// damaged by `damage` (an SQL statement run on the copy), left with no
/// `-wal` or `-shm` beside it.
fn damaged_copy(bench: &Bench, name: &str, damage: impl FnOnce(&rusqlite::Connection)) -> Vec<u8> {
    if !bench.exists("survey.db") {
        bench.small_survey(true);
    }
    std::fs::copy(bench.path("survey.db"), bench.path(name)).unwrap();
    let conn = rusqlite::Connection::open(bench.path(name)).unwrap();
    damage(&conn);
    drop(conn);
    assert_no_sidecars(bench, name, "the damaged copy as made");
    std::fs::read(bench.path(name)).unwrap()
}

#[track_caller]
fn assert_no_sidecars(bench: &Bench, name: &str, when: &str) {
    for suffix in ["-wal", "-shm", "-journal"] {
        assert!(!bench.exists(&format!("{name}{suffix}")), "{when}: {name}{suffix} is there");
    }
}

/// `survey --db DB args...`, which must be refused as damaged naming `what`,
/// leaving the file's bytes as `before` and no `-wal`/`-shm` beside it.
#[track_caller]
fn refused(bench: &Bench, db: &str, before: &[u8], args: &[&str], what: &str) -> Output {
    let mut all = vec!["--db", db];
    all.extend(args);
    let out = bench.survey(&all).bad_input(&[db, "is damaged", what]);
    assert!(!out.stderr.contains("(code:"), "said in words, not SQLite's code\n{out}");
    assert!(std::fs::read(bench.path(db)).unwrap() == before, "nothing was written into it\n{out}");
    assert_no_sidecars(bench, db, &format!("after `survey {}`", args.join(" ")));
    out
}

fn drop_table(table: &'static str) -> impl FnOnce(&rusqlite::Connection) {
    move |c| c.execute_batch(&format!("DROP TABLE {table}")).unwrap()
}

#[test]
fn a_dropped_table_is_refused_by_every_command_which_names_it() {
    let bench = Bench::new();
    bench.write("valid.csv", VALID_CSV);
    for table in ["locate_points", "events", "sample_packs"] {
        let db = format!("no-{table}.db");
        let before = damaged_copy(&bench, &db, drop_table(table));
        let missing = format!("the table `{table}` is missing");
        refused(&bench, &db, &before, &["stats"], &missing);
        refused(&bench, &db, &before, &["export", "--csv", "out.csv"], &missing);
        assert!(!bench.exists("out.csv"), "no export written from a damaged file");
        refused(&bench, &db, &before, &["import", "valid.csv"], &missing);
        refused(&bench, &db, &before, &["run", "--points", "36", "--runs", "2"], &missing);
        refused(&bench, &db, &before, &["list"], &missing);
    }
    // A column gone (a table rebuilt without it) is named too.
    let before = damaged_copy(&bench, "no-column.db", |c| {
        c.execute_batch("ALTER TABLE events DROP COLUMN level").unwrap();
    });
    refused(&bench, "no-column.db", &before, &["stats"], "the table `events` has no column `level`");
    // The good file is still read.
    bench.survey(&["stats", "--json"]).success();
}

/// The root page of the table or index `name`, as a file offset.
fn root_page_offset(conn: &rusqlite::Connection, name: &str) -> u64 {
    let page: i64 = conn.query_row("SELECT rootpage FROM sqlite_master WHERE name = ?1", [name], |r| r.get(0)).unwrap();
    let size: i64 = conn.query_row("PRAGMA page_size", [], |r| r.get(0)).unwrap();
    ((page - 1) * size) as u64
}

#[test]
fn an_overwritten_page_is_refused_by_the_readers() {
    use std::io::{Seek as _, SeekFrom, Write as _};
    let bench = Bench::new();
    for table in [
        "samples",
        "sample_packs",
        "surveys",
        "_sqlx_migrations",
        "sqlite_autoindex__sqlx_migrations_1",
        "events_by_survey",
    ] {
        let db = format!("page-{table}.db");
        damaged_copy(&bench, &db, |_| {});
        let at = root_page_offset(&rusqlite::Connection::open(bench.path(&db)).unwrap(), table);
        assert_no_sidecars(&bench, &db, "read to find the page");
        let mut file = std::fs::OpenOptions::new().write(true).open(bench.path(&db)).unwrap();
        file.seek(SeekFrom::Start(at)).unwrap();
        // 4 KiB of what a bad sector or a stray write leaves: not zeros.
        let noise: Vec<u8> = (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        file.write_all(&noise).unwrap();
        drop(file);
        let before = std::fs::read(bench.path(&db)).unwrap();
        let out = refused(&bench, &db, &before, &["stats"], "is damaged");
        refused(&bench, &db, &before, &["export", "--csv", "out.csv"], "is damaged");
        assert!(!bench.exists("out.csv"));
        refused(&bench, &db, &before, &["run", "--points", "36", "--runs", "2"], "is damaged");
        assert!(out.stderr.contains("restore it from a backup"), "{out}");
    }
}

#[test]
fn serve_answers_503_saying_the_file_is_damaged_in_words() {
    let bench = Bench::new();
    let before = damaged_copy(&bench, "no-events.db", drop_table("events"));
    let server = Server::on(&bench, "no-events.db", &[]);
    for path in ["/", "/api/live", "/api/surveys"] {
        let page = get(&server.url, path);
        assert_eq!(page.status, 503, "{path}: {}", page.body);
        assert!(
            page.body.contains("is damaged") && page.body.contains("the table `events` is missing"),
            "{path}: {}",
            page.body
        );
        assert!(!page.body.contains("(code:"), "{path}: {}", page.body);
    }
    assert_eq!(server.stop(), Some(0));
    assert!(std::fs::read(bench.path("no-events.db")).unwrap() == before);
    assert_no_sidecars(&bench, "no-events.db", "after serve");
}

/// The commands of issue 51's attack set, each refused on a damaged file.
const EVERY_COMMAND: [&[&str]; 7] = [
    &["list"],
    &["stats"],
    &["export", "--csv", "out.csv"],
    &["run", "--points", "36", "--runs", "2"],
    &["import", "valid.csv"],
    &["push", "--to", "postgres://survey@127.0.0.1:9/none"],
    &["resume"],
];

/// A file cut short by less than a page (1, 100, 4095 bytes) or by one
/// whole page: SQLite reads the missing tail as zeros or a short read, so
/// every command looked at it as sound (`list` exited 1 with `(code: 522)`,
/// `stats` and `export` 0, `run` and `import` wrote into it). Now each is
/// refused, exit 2, naming what the file lacks, its bytes unchanged.
#[test]
fn a_file_cut_short_by_less_than_a_page_is_refused_by_every_command() {
    let bench = Bench::new();
    bench.write("valid.csv", VALID_CSV);
    bench.small_survey(true);
    let whole = std::fs::read(bench.path("survey.db")).unwrap();
    assert_eq!(whole.len() % 4096, 0);
    for cut in [1usize, 100, 4095, 4096] {
        let db = format!("cut-{cut}.db");
        let before = whole[..whole.len() - cut].to_vec();
        bench.write(&db, &before);
        for args in EVERY_COMMAND {
            let out = refused(&bench, &db, &before, args, "its header counts");
            assert!(out.stderr.contains("cut short") && out.stderr.contains("are whole"), "{out}");
        }
        assert!(!bench.exists("out.csv"), "no export written from a damaged file");
    }
    bench.survey(&["list"]).success();
}

/// The write-ahead log of `db` as it stands after `change` on a connection
/// that never checkpoints (what a killed writer leaves), copied to `to`; the
/// connection then closes, checkpointing it into `db` (the log goes).
fn log_of(bench: &Bench, db: &str, to: &str, change: &str) {
    let conn = rusqlite::Connection::open(bench.path(db)).unwrap();
    conn.execute_batch("PRAGMA journal_mode = WAL; PRAGMA wal_autocheckpoint = 0").unwrap();
    conn.execute_batch(change).unwrap();
    std::fs::copy(bench.path(&format!("{db}-wal")), bench.path(to)).unwrap();
    drop(conn);
}

/// Rows enough to add pages to the file (page 1 changes with the count).
fn grow(tag: &str) -> String {
    format!(
        "WITH RECURSIVE n(v) AS (SELECT 1 UNION ALL SELECT v + 1 FROM n WHERE v < 8) \
         INSERT INTO events (survey_id, at_s, level, message) SELECT 1, v, 'info', '{tag}' || printf('%.3000c', 'x') FROM n"
    )
}

/// A `-wal` beside the file that is not its own: an old log of the file
/// itself, and another copy's log that changed no page 1 while this file
/// grew (another copy's log whose page 1 shares the file's change counter is
/// a limit: see below). SQLite replays any
/// log onto the file it finds it beside; every command looked at the file
/// alone and `run`, `import` and `resume` wrote into the mixture. Now each is
/// refused, exit 2, the file and the log unchanged, nothing made beside them.
/// A log that is the file's own (left by a killed writer) is read.
#[test]
fn a_write_ahead_log_from_another_copy_is_refused_by_every_command() {
    let bench = Bench::new();
    bench.write("valid.csv", VALID_CSV);
    bench.small_survey(true);
    let copy = |name: &str| std::fs::copy(bench.path("survey.db"), bench.path(name)).unwrap();
    // Another copy's log: both copies changed page 1 after they parted.
    copy("other.db");
    log_of(&bench, "other.db", "other.wal", &format!("PRAGMA user_version = 7; {}", grow("other")));
    copy("diverged.db");
    rusqlite::Connection::open(bench.path("diverged.db")).unwrap().execute_batch(&grow("mine")).unwrap();
    std::fs::copy(bench.path("other.wal"), bench.path("diverged.db-wal")).unwrap();
    // The file's own log, from before its last transactions.
    copy("stale.db");
    log_of(&bench, "stale.db", "stale.wal", &grow("first"));
    rusqlite::Connection::open(bench.path("stale.db")).unwrap().execute_batch(&grow("then")).unwrap();
    std::fs::copy(bench.path("stale.wal"), bench.path("stale.db-wal")).unwrap();
    // Another copy's log of a change within its pages, beside a file that grew.
    copy("inplace.db");
    log_of(&bench, "inplace.db", "inplace.wal", "UPDATE events SET level = 'note' WHERE id = 1");
    copy("grown.db");
    rusqlite::Connection::open(bench.path("grown.db")).unwrap().execute_batch(&grow("grown")).unwrap();
    std::fs::copy(bench.path("inplace.wal"), bench.path("grown.db-wal")).unwrap();
    // "diverged.db": both copies changed page 1 at one change counter (in
    // WAL mode SQLite need not count every transaction); the seal every
    // write of survey renews in the header tells them apart.
    for (db, why) in [("stale.db", "newer than the log"), ("grown.db", "another copy"), ("diverged.db", "another copy")]
    {
        assert_no_sidecars_but_the_log(&bench, db);
        let before = std::fs::read(bench.path(db)).unwrap();
        let log = std::fs::read(bench.path(&format!("{db}-wal"))).unwrap();
        for args in EVERY_COMMAND {
            let mut all = vec!["--db", db];
            all.extend(args);
            let out = bench.survey(&all).bad_input(&[db, "is damaged", "does not belong to it", why, "move"]);
            assert!(!out.stderr.contains("(code:"), "{out}");
            assert!(std::fs::read(bench.path(db)).unwrap() == before, "the file unchanged\n{out}");
            assert!(std::fs::read(bench.path(&format!("{db}-wal"))).unwrap() == log, "the log unchanged\n{out}");
            assert_no_sidecars_but_the_log(&bench, db);
        }
        // Moved aside, the file reads as of its last checkpoint.
        std::fs::rename(bench.path(&format!("{db}-wal")), bench.path(&format!("{db}.aside"))).unwrap();
        bench.survey(&["--db", db, "stats"]).success();
    }
    // The file's own log, as a killed writer leaves it: read, and written.
    copy("killed.db");
    let conn = rusqlite::Connection::open(bench.path("killed.db")).unwrap();
    // A write sealed as survey seals it (the state it followed, a new one).
    let state: i64 = conn.query_row("PRAGMA user_version", [], |r| r.get(0)).unwrap();
    conn.execute_batch(&format!(
        "PRAGMA wal_autocheckpoint = 0; BEGIN; PRAGMA application_id = {state}; PRAGMA user_version = 3; {}; COMMIT",
        grow("killed")
    ))
    .unwrap();
    std::fs::copy(bench.path("killed.db"), bench.path("own.db")).unwrap();
    std::fs::copy(bench.path("killed.db-wal"), bench.path("own.db-wal")).unwrap();
    drop(conn);
    bench.survey(&["--db", "own.db", "stats"]).success();
    bench.survey(&["--db", "own.db", "import", "valid.csv"]).success();
    let events: i64 = rusqlite::Connection::open(bench.path("own.db"))
        .unwrap()
        .query_row("SELECT count(*) FROM events WHERE message LIKE 'killed%'", [], |r| r.get(0))
        .unwrap();
    assert_eq!(events, 8, "the log's transaction is the file's");
}

#[track_caller]
fn assert_no_sidecars_but_the_log(bench: &Bench, name: &str) {
    for suffix in ["-shm", "-journal"] {
        assert!(!bench.exists(&format!("{name}{suffix}")), "{name}{suffix} is there");
    }
}
