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
