//! A damaged survey database is refused on open: its schema against the
//! migrations', and SQLite's `PRAGMA quick_check` where it is cheap.
//!
//! # The schema
//!
//! What a survey database of schema `v` must hold is what migrations 1 to `v`
//! make: they are applied once per process to an empty in-memory database
//! (the same bundled SQLite, through rusqlite), and its tables with their
//! columns, its indexes and its triggers are the expected set ([`expected`]).
//! So the check can never drift from the migrations: a new migration is
//! checked as soon as it is added. A file that lacks any of them (a table
//! dropped, a column missing, an index or a trigger gone) is damaged. What a
//! file holds beyond them (SQLite's own `sqlite_stat1` after an `ANALYZE`,
//! say) is left alone. Reading the schema costs well under a millisecond.
//!
//! # The pages
//!
//! `PRAGMA quick_check` reads every page of the file and checks the b-trees'
//! structure, the free list and each row's format (not the indexes' content
//! against their tables: that is `integrity_check`, not much slower, but it
//! adds nothing for the damage a copy or a disk does to a page). Its cost
//! grows with the file: 0.41 s on a 227 MB file of 1.8 million samples, 0.09 s
//! on one of 58 MB (docs/integrity.md). So it is run over the whole file up
//! to [`WHOLE_CHECK_BYTES`] (about 0.05 s), and over a larger one on every table
//! but the three that hold the samples (`samples`, `raw_readings`,
//! `sample_packs`: a few milliseconds), whose pages SQLite still refuses when
//! a command reads one it cannot parse ("damaged", exit status 2).
//!
//! # Where
//!
//! On every open of a station's file, by a command that writes before
//! anything is written, by a command that reads before its connection is
//! made: the inspection reads the file as `immutable` (no lock, no `-wal` or
//! `-shm` file made beside it), so a refused file is left exactly as it was.
//! An immutable reading sees the file as of its last checkpoint; a writer's
//! checkpoint while the check reads could make a sound file look damaged,
//! so a damage found while a write-ahead log is there is confirmed on an
//! ordinary read-only connection before the file is refused.

use std::collections::{BTreeMap, BTreeSet};
use std::os::unix::fs::MetadataExt as _;
use std::path::Path;
use std::sync::{Mutex, OnceLock};

use sqlx::{AssertSqlSafe, Row, SqlitePool};

use super::{MIGRATIONS, NotFound};

mod file;
pub(crate) use file::{examine, wal_path};

/// Files up to this size are checked whole by `PRAGMA quick_check` on open;
/// larger ones on every table but the samples' (see the module's documentation).
pub const WHOLE_CHECK_BYTES: u64 = 32 * 1024 * 1024;

/// What is said of a file whose pages SQLite cannot read at all
/// (`SQLITE_CORRUPT`).
pub(crate) const MALFORMED: &str = "SQLite cannot read it (database disk image is malformed)";

/// The tables that hold the samples: the bulk of a large file.
const BULK_TABLES: [&str; 3] = ["samples", "raw_readings", "sample_packs"];

/// The schema objects of a database, as far as damage is concerned.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Shape {
    /// Every table with its columns.
    tables: BTreeMap<String, BTreeSet<String>>,
    /// Named indexes (not SQLite's automatic ones).
    indexes: BTreeSet<String>,
    /// Triggers.
    triggers: BTreeSet<String>,
}

impl Shape {
    /// A table's column, as found.
    pub(crate) fn add_column(&mut self, table: &str, column: Option<&str>) {
        let columns = self.tables.entry(table.to_string()).or_default();
        if let Some(c) = column {
            columns.insert(c.to_string());
        }
    }

    /// A named index, as found.
    pub(crate) fn add_index(&mut self, name: &str) {
        self.indexes.insert(name.to_string());
    }

    /// The tables.
    pub(crate) fn table_names(&self) -> impl Iterator<Item = &str> {
        self.tables.keys().map(String::as_str)
    }

    /// The same without what `other` holds (its tables whole, its indexes
    /// and triggers), and without any trigger: the lab store's shape is the
    /// station's without migration 7's packs and SQLite's triggers.
    pub(crate) fn without(&self, other: &Shape) -> Shape {
        let mut out = self.clone();
        out.tables.retain(|t, _| !other.tables.contains_key(t));
        out.indexes.retain(|i| !other.indexes.contains(i));
        out.triggers.clear();
        out
    }

    /// What `self` (the expected) has that `found` lacks, in words, one entry
    /// a missing object.
    pub(crate) fn missing_from(&self, found: &Shape) -> Vec<String> {
        let mut out = Vec::new();
        for (table, columns) in &self.tables {
            match found.tables.get(table) {
                None => out.push(format!("the table `{table}` is missing")),
                Some(have) => {
                    for c in columns.difference(have) {
                        out.push(format!("the table `{table}` has no column `{c}`"));
                    }
                }
            }
        }
        for i in self.indexes.difference(&found.indexes) {
            out.push(format!("the index `{i}` is missing"));
        }
        for t in self.triggers.difference(&found.triggers) {
            out.push(format!("the trigger `{t}` is missing"));
        }
        out
    }
}

/// What migrations 1 to `version` make: applied to an empty in-memory
/// database, once per version and process.
pub(crate) fn expected(version: i64) -> anyhow::Result<Shape> {
    static MADE: OnceLock<Mutex<BTreeMap<i64, Shape>>> = OnceLock::new();
    let made = MADE.get_or_init(Default::default);
    if let Some(shape) = made.lock().expect("not poisoned").get(&version) {
        return Ok(shape.clone());
    }
    let conn = rusqlite::Connection::open_in_memory()?;
    for (v, description, sql) in MIGRATIONS.iter().filter(|m| m.0 <= version) {
        conn.execute_batch(sql)
            .map_err(|e| anyhow::anyhow!("migration {v} ({description}) does not apply to an empty database: {e}"))?;
    }
    let mut shape = Shape::default();
    let mut objects =
        conn.prepare(r"SELECT type, name FROM sqlite_master WHERE name NOT LIKE 'sqlite\_%' ESCAPE '\'")?;
    let rows: Vec<(String, String)> =
        objects.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?.collect::<Result<_, _>>()?;
    for (kind, name) in rows {
        match kind.as_str() {
            "table" => {
                let mut cols = conn.prepare("SELECT name FROM pragma_table_info(?1)")?;
                let columns = cols.query_map([&name], |r| r.get::<_, String>(0))?.collect::<Result<_, _>>()?;
                shape.tables.insert(name, columns);
            }
            "index" => {
                shape.indexes.insert(name);
            }
            "trigger" => {
                shape.triggers.insert(name);
            }
            _ => {}
        }
    }
    made.lock().expect("not poisoned").insert(version, shape.clone());
    Ok(shape)
}

/// The schema objects of the database of `pool`.
async fn found(pool: &SqlitePool) -> Result<Shape, sqlx::Error> {
    let rows = sqlx::query(
        r"SELECT m.type AS kind, m.name AS name, p.name AS column_name
          FROM sqlite_master AS m LEFT JOIN pragma_table_info(m.name) AS p ON m.type = 'table'
          WHERE m.name NOT LIKE 'sqlite\_%' ESCAPE '\'",
    )
    .fetch_all(pool)
    .await?;
    let mut shape = Shape::default();
    for row in rows {
        let kind: String = row.try_get("kind")?;
        let name: String = row.try_get("name")?;
        match kind.as_str() {
            "table" => {
                let columns = shape.tables.entry(name).or_default();
                if let Some(c) = row.try_get::<Option<String>, _>("column_name")? {
                    columns.insert(c);
                }
            }
            "index" => {
                shape.indexes.insert(name);
            }
            "trigger" => {
                shape.triggers.insert(name);
            }
            _ => {}
        }
    }
    Ok(shape)
}

/// The first lines `PRAGMA quick_check` reports on the database of `pool`
/// (none: sound), over the whole file when it is at most
/// [`WHOLE_CHECK_BYTES`] long, over every table but the bulk ones otherwise.
async fn quick_check(pool: &SqlitePool, file_bytes: u64, tables: &BTreeSet<&str>) -> Result<Vec<String>, sqlx::Error> {
    const SHOWN: usize = 3;
    let mut problems = Vec::new();
    let statements: Vec<String> = if file_bytes <= WHOLE_CHECK_BYTES {
        vec![format!("PRAGMA quick_check({SHOWN})")]
    } else {
        // Table names from the migrations (no user text).
        tables.iter().filter(|t| !BULK_TABLES.contains(t)).map(|t| format!("PRAGMA quick_check(\"{t}\")")).collect()
    };
    for sql in statements {
        let lines: Vec<String> = sqlx::query_scalar(AssertSqlSafe(sql)).fetch_all(pool).await?;
        problems.extend(lines.into_iter().filter(|l| l != "ok"));
        if problems.len() >= SHOWN {
            break;
        }
    }
    problems.truncate(SHOWN);
    Ok(problems)
}

/// The file's length and its write-ahead log, checked before SQLite reads
/// them ([`examine`]): whether the log has frames SQLite will replay, or the
/// refusal of the file. Found wrong while the file or its log changed (a
/// writer's checkpoint, a commit), it is looked at again: refused only when
/// two looks at an unchanged file and log agree.
pub(crate) async fn settled(path: &Path) -> anyhow::Result<bool> {
    let stamp = || {
        let of = |p: &Path| std::fs::metadata(p).ok().map(|m| (m.len(), m.modified().ok()));
        (of(path), of(&wal_path(path)))
    };
    let mut last = None;
    for tries in 1..=6u64 {
        let before = stamp();
        let found = examine(path)
            .map_err(|e| anyhow::Error::new(e).context(format!("cannot read the database {}", path.display())))?;
        if found.problems.is_empty() {
            return Ok(found.replays);
        }
        let after = stamp();
        if before == after && (last.as_ref() == Some(&after) || tries == 6) {
            return Err(damaged(path, &found.problems));
        }
        last = (before == after).then_some(after);
        tokio::time::sleep(std::time::Duration::from_millis(10 * tries)).await;
    }
    unreachable!("the sixth look decides")
}

/// The refusal of a damaged file ([`NotFound`]: bad input, exit status 2).
pub(crate) fn damaged(path: &Path, what: &[String]) -> anyhow::Error {
    NotFound(format!(
        "{} is damaged: {}; nothing was read from it or written to it: restore it from a backup (docs/integrity.md)",
        path.display(),
        what.join("; ")
    ))
    .into()
}

/// What is wrong with the survey database of `pool` (at `path`), of schema
/// `version`: its missing schema objects, or else the first lines of
/// `PRAGMA quick_check`; empty when it is sound. A page SQLite cannot read
/// at all while checking is damage too.
///
/// `with_wal`: the connection reads the write-ahead log beside the file (an
/// ordinary connection), so what was found sound is remembered with the
/// log's length and time too.
pub(crate) async fn problems(
    pool: &SqlitePool,
    path: &Path,
    version: i64,
    with_wal: bool,
) -> anyhow::Result<Vec<String>> {
    let expected = expected(version)?;
    let corrupt = |e: sqlx::Error| -> anyhow::Result<Vec<String>> {
        match super::sqlite_code(&e).map(|c| c & 0xff) {
            Some(11 | 26) => {
                Ok(vec![format!("SQLite cannot read it ({})", e.as_database_error().map_or("", |d| d.message()))])
            }
            _ => Err(super::open_error(path, e)),
        }
    };
    let shape = match found(pool).await {
        Ok(shape) => shape,
        Err(e) => return corrupt(e),
    };
    let missing = expected.missing_from(&shape);
    if !missing.is_empty() {
        return Ok(missing);
    }
    // A file found sound by this process and not changed since (the same
    // file, length and modification time: in WAL mode the file changes only
    // at a checkpoint) is not read again: `survey serve` opens the store for
    // every request.
    static SOUND: OnceLock<Mutex<BTreeSet<Stamp>>> = OnceLock::new();
    let sound = SOUND.get_or_init(Default::default);
    let meta = std::fs::metadata(path).ok();
    let wal = with_wal.then(|| std::fs::metadata(wal_path(path)).ok().map(|m| (m.len(), m.modified().ok()))).flatten();
    let stamp = meta.as_ref().map(|m| (m.dev(), m.ino(), m.len(), m.modified().ok(), wal));
    if stamp.as_ref().is_some_and(|s| sound.lock().expect("not poisoned").contains(s)) {
        return Ok(Vec::new());
    }
    let tables: BTreeSet<&str> = expected.tables.keys().map(String::as_str).collect();
    match quick_check(pool, meta.map_or(0, |m| m.len()), &tables).await {
        Ok(lines) if lines.is_empty() => {
            if let Some(stamp) = stamp {
                sound.lock().expect("not poisoned").insert(stamp);
            }
            Ok(Vec::new())
        }
        Ok(lines) => Ok(lines.into_iter().map(|l| format!("SQLite's quick_check: {}", l.replace('\n', " "))).collect()),
        Err(e) => corrupt(e),
    }
}

/// A file as found: device, inode, length, modification time (and its
/// write-ahead log's length and time, when it was read).
type Stamp = (u64, u64, u64, Option<std::time::SystemTime>, Option<(u64, Option<std::time::SystemTime>)>);

/// An error met reading the file at `path` (a bulk read of samples): when
/// SQLite found a page it cannot parse (`SQLITE_CORRUPT`, `SQLITE_NOTADB`),
/// the refusal of a damaged file (bad input, exit status 2) rather than a
/// run-time failure; any other error as it is. The pages of the samples'
/// tables of a file larger than [`WHOLE_CHECK_BYTES`] are not checked on
/// open: this is where their damage is met.
pub(crate) fn on_read(path: &Path, what: &str, e: anyhow::Error) -> anyhow::Error {
    let corrupt = e.chain().find_map(|c| {
        if let Some(rusqlite::Error::SqliteFailure(f, message)) = c.downcast_ref::<rusqlite::Error>() {
            let said = message.clone().unwrap_or_else(|| f.to_string());
            return matches!(f.code, rusqlite::ErrorCode::DatabaseCorrupt | rusqlite::ErrorCode::NotADatabase)
                .then_some(said);
        }
        let d = c.downcast_ref::<sqlx::Error>()?.as_database_error()?;
        let code: u32 = d.code()?.parse().ok()?;
        matches!(code & 0xff, 11 | 26).then(|| d.message().to_string())
    });
    match corrupt {
        Some(said) if !e.chain().any(|c| c.is::<NotFound>()) => NotFound(format!(
            "{} is damaged: SQLite cannot read {what} ({said}); nothing was written to it: restore it from a backup \
             (docs/integrity.md)",
            path.display()
        ))
        .into(),
        _ => e,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_expected_schema_is_what_the_migrations_make() {
        let latest = MIGRATIONS.last().unwrap().0;
        let shape = expected(latest).unwrap();
        for table in ["surveys", "samples", "raw_readings", "locate_points", "events", "sample_packs", "survey_changes"]
        {
            assert!(shape.tables.contains_key(table), "{table}: {:?}", shape.tables.keys());
        }
        assert!(shape.tables["surveys"].contains("asset") && shape.tables["surveys"].contains("uid"));
        assert!(shape.triggers.contains("samples_insert_unpacks"), "{:?}", shape.triggers);
        // An older schema lacks what came after it.
        let v7 = expected(7).unwrap();
        assert!(!v7.tables.contains_key("survey_summaries") && v7.tables.contains_key("sample_packs"));
        let v1 = expected(1).unwrap();
        assert!(!v1.tables["surveys"].contains("asset"));
        let mut found = shape.clone();
        found.tables.remove("events");
        found.tables.get_mut("surveys").unwrap().remove("asset");
        found.triggers.remove("samples_insert_unpacks");
        assert_eq!(
            shape.missing_from(&found),
            [
                "the table `events` is missing",
                "the table `surveys` has no column `asset`",
                "the trigger `samples_insert_unpacks` is missing"
            ]
        );
        assert!(shape.missing_from(&shape).is_empty());
    }

    /// A log that belongs to the file as far as its bytes tell (no page 1,
    /// the file's size) but whose replay breaks a b-tree: the file as the
    /// log makes it is checked, and refused naming the log.
    #[tokio::test]
    async fn a_log_whose_replay_breaks_the_file_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("w.db");
        let store = crate::Store::open(&path).await.unwrap();
        store.create_survey(&crate::survey::NewSurvey::default()).await.unwrap();
        store.close().await;
        let bytes = std::fs::read(&path).unwrap();
        let pages = u32::from_be_bytes(bytes[28..32].try_into().unwrap());
        let conn = rusqlite::Connection::open_with_flags(&path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY).unwrap();
        let root: u32 =
            conn.query_row("SELECT rootpage FROM sqlite_master WHERE name = 'surveys'", [], |r| r.get(0)).unwrap();
        drop(conn);
        let noise: Vec<u8> = (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        std::fs::write(wal_path(&path), file::tests::log(4096, (3, 4), &[(root, pages, noise)])).unwrap();
        let e = crate::Store::open_read_only(&path).await.unwrap_err();
        let text = format!("{e:#}");
        assert!(crate::is_not_found(&e), "{text}");
        assert!(
            text.contains("w.db is damaged: as the write-ahead log beside it (") && text.contains("w.db-wal) makes it"),
            "{text}"
        );
        assert!(std::fs::read(&path).unwrap() == bytes, "the file unchanged");
        // The writers refuse it too.
        assert!(crate::is_not_found(&crate::Store::open(&path).await.unwrap_err()));
        assert!(std::fs::read(&path).unwrap() == bytes, "the file unchanged");
    }

    /// A page of the samples damaged after the file was checked (what a
    /// large file's unchecked bulk tables can hold): the read that meets it
    /// refuses the file as damaged (exit status 2), not a raw SQLite error.
    #[tokio::test]
    async fn a_damaged_page_met_while_reading_the_samples_is_the_file_s_damage() {
        use crate::survey::NewSurvey;
        use survey_acquire::{RawReading, RecordedSample};
        use survey_processing::{Direction, Sample};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.db");
        let store = crate::Store::open(&path).await.unwrap();
        let id = store.create_survey(&NewSurvey::default()).await.unwrap();
        let samples: Vec<RecordedSample> = (0..2000u64)
            .map(|seq| RecordedSample {
                seq,
                others: Vec::new(),
                sample: Sample {
                    run: 1,
                    direction: Direction::Forward,
                    target_deg: seq as f64 * 0.18,
                    readout_deg: seq as f64 * 0.18,
                    actual_deg: seq as f64 * 0.18 + 1e-4,
                    timestamp_s: None,
                },
                raw: RawReading::None,
            })
            .collect();
        store.append(id, &samples).await.unwrap();
        store.close().await;
        let store = crate::Store::open_read_only(&path).await.unwrap();
        // A leaf page of `samples` (not its root), overwritten with noise.
        let conn = rusqlite::Connection::open_with_flags(&path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY).unwrap();
        let root: i64 =
            conn.query_row("SELECT rootpage FROM sqlite_master WHERE name = 'samples'", [], |r| r.get(0)).unwrap();
        let leaf: i64 = conn
            .query_row(
                "SELECT pageno FROM dbstat WHERE name = 'samples' AND pagetype = 'leaf' LIMIT 1 OFFSET 3",
                [],
                |r| r.get(0),
            )
            .unwrap_or(root + 1);
        drop(conn);
        let noise: Vec<u8> = (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        let mut bytes = std::fs::read(&path).unwrap();
        let at = (leaf as usize - 1) * 4096;
        bytes[at..at + 4096].copy_from_slice(&noise);
        std::fs::write(&path, bytes).unwrap();
        let e = store.samples(id).await.unwrap_err();
        assert!(crate::is_not_found(&e), "{e:#}");
        let text = format!("{e:#}");
        assert!(text.contains("d.db is damaged: SQLite cannot read the samples of survey 1 ("), "{text}");
        assert!(text.contains("malformed"), "{text}");
        store.close().await;
    }
}
