//! The SQLite store: surveys, their samples with the raw reference readings,
//! the SMR positions that located the axis, and an event log.
//!
//! One database file holds every survey (`survey.db` by default). The schema is
//! in `migrations/` at the root of the repository; it is embedded in the binary
//! and applied when a database is opened.
//!
//! # Durability
//!
//! The database runs in WAL mode with `synchronous = FULL`: a transaction that
//! has committed is on the disk and survives a power loss. [`Store::append`]
//! writes a batch of samples in one transaction, so a batch is stored entirely
//! or not at all, and [`StoreSink`] acknowledges a sample (see
//! [`SampleSink`]) only when the transaction that holds it has committed.
//!
//! # Errors
//!
//! Errors are [`anyhow::Error`]s. Those caused by what the user asked for (no
//! database at the path, no survey with that id, an empty database, a file that
//! is not a database) carry a [`NotFound`]: find it with [`is_not_found`] and
//! exit with status 2; everything else is a run-time failure (status 1).
//!
//! # Layout
//!
//! - this file: opening the database (schema migrations, pragmas) and the
//!   user errors ([`NotFound`]);
//! - `surveys`: the surveys themselves (create, status, axis, locate points,
//!   events, look-ups);
//! - `samples`: storing and reading samples with their raw readings;
//! - `sink`: [`StoreSink`], the batching [`SampleSink`].

mod drift;
mod lock;
mod samples;
mod scan;
mod sink;
mod surveys;
#[cfg(test)]
mod tests;
mod tx;

pub use lock::{AcquirerLock, Holder, SurveyBusy, lock_path};
pub use samples::SmrPosition;
pub use scan::StoredPass;
pub use sink::StoreSink;
pub use surveys::EventRow;

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, anyhow};
use sqlx::migrate::{Migration, MigrationType, Migrator};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteRow, SqliteSynchronous};
use sqlx::{ConnectOptions as _, Row, SqlSafeStr, SqlitePool};

#[cfg(doc)]
use crate::acquire::SampleSink;

/// How long a statement waits for another connection's lock before it fails.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

/// Limits of a store's connection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoreLimits {
    /// How long one statement waits for another connection's write lock.
    pub busy_timeout: Duration,
    /// SQLite's `max_page_count` (tests of a full disk); `None`: no limit.
    pub max_pages: Option<u32>,
}

impl Default for StoreLimits {
    fn default() -> Self {
        StoreLimits { busy_timeout: BUSY_TIMEOUT, max_pages: None }
    }
}

/// The one way this project builds an SQLite pool: one connection, and no
/// maintenance task. sqlx-core 0.9.0's reaper (spawned when an idle timeout or
/// a maximum lifetime is set, and sqlx sets both by default) can spin at 100 %
/// CPU forever after a `num_idle` underflow (sqlx issue 3645, fixed by pull
/// request 4289, not in 0.9.0), and a process whose runtime waits for it never
/// exits. A single connection kept for the store's life has nothing to reap.
pub(crate) fn single_connection_pool() -> SqlitePoolOptions {
    SqlitePoolOptions::new().max_connections(1).min_connections(0).idle_timeout(None).max_lifetime(None)
}

/// Rows per multi-row `INSERT`: the widest row (a raw reading) binds 12 values,
/// so a statement binds at most 4 800, far under SQLite's limit of 32 766.
const CHUNK_ROWS: usize = 400;

/// The schema migrations, embedded in the binary (the same versions,
/// descriptions and checksums `sqlx::migrate!("../migrations")` would give).
const MIGRATIONS: &[(i64, &str, &str)] = &[
    (1, "init", include_str!("../../../migrations/0001_init.sql")),
    (2, "drift", include_str!("../../../migrations/0002_drift.sql")),
    (3, "instrument time", include_str!("../../../migrations/0003_instrument_time.sql")),
];

fn migrator() -> Migrator {
    Migrator::with_migrations(
        MIGRATIONS
            .iter()
            .map(|&(version, description, sql)| {
                Migration::new(version, Cow::Borrowed(description), MigrationType::Simple, sql.into_sql_str(), false)
            })
            .collect(),
    )
}

/// A user error from the store: what was asked for is not there (the database
/// file, a survey id, any survey at all), or the file is not a survey database.
///
/// The command line exits with status 2 when an error holds one (see
/// [`is_not_found`]); its text is the whole message, e.g.
/// `no survey with id 7 in survey.db`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct NotFound(pub String);

/// Whether `err`, or any error in its chain, is a [`NotFound`] (a user error).
pub fn is_not_found(err: &anyhow::Error) -> bool {
    err.downcast_ref::<NotFound>().is_some() || err.chain().any(|e| e.is::<NotFound>())
}

/// The survey database. Cheap to clone: clones share one connection.
///
/// The pool holds a single connection (one writer; calls from several tasks
/// take turns, waiting up to sqlx's acquire timeout of 30 s). Other processes
/// can read the file at the same time (WAL); a second writer waits up to
/// [`BUSY_TIMEOUT`] for the lock.
#[derive(Debug, Clone)]
pub struct Store {
    pool: SqlitePool,
    path: PathBuf,
    /// Opened `immutable` (read-only media): the bulk reader must be too.
    immutable: bool,
}

impl Store {
    /// Open the database at `path`, creating it if missing, and bring its schema
    /// up to date. WAL journal, `synchronous = FULL` (a committed transaction
    /// survives power loss), busy timeout 5 s, foreign keys enforced.
    pub async fn open(path: &Path) -> anyhow::Result<Store> {
        Self::connect(path, true, StoreLimits::default()).await
    }

    /// [`Store::open`] with the database limited to `max_pages` pages
    /// (SQLite's `max_page_count`): when it is reached, a write fails with
    /// the same `SQLITE_FULL` a full disk gives. For tests of a full disk.
    pub async fn open_limited(path: &Path, max_pages: u32) -> anyhow::Result<Store> {
        Self::connect(path, true, StoreLimits { max_pages: Some(max_pages), ..StoreLimits::default() }).await
    }

    /// [`Store::open`] with other limits (tests: a short busy timeout).
    pub async fn open_with(path: &Path, limits: StoreLimits) -> anyhow::Result<Store> {
        Self::connect(path, true, limits).await
    }

    /// Open an existing database (for the commands that only read). Fails with a
    /// [`NotFound`] when there is no file at `path`, and does not create one.
    pub async fn open_existing(path: &Path) -> anyhow::Result<Store> {
        existing_file(path)?;
        Self::connect(path, false, StoreLimits::default()).await
    }

    /// Open an existing survey database for a command that only reads. It
    /// never writes: the connection is read-only, no migration runs, the
    /// journal mode is left as it is, and on read-only media (where SQLite
    /// cannot make the WAL's shared-memory file) the file is opened as
    /// immutable. A file that is not a survey database (another
    /// application's SQLite file, or not SQLite at all), a damaged one, or one
    /// written by a newer version of `survey` is refused with one message form
    /// naming the file ([`NotFound`]: bad input, exit status 2).
    pub async fn open_read_only(path: &Path) -> anyhow::Result<Store> {
        existing_file(path)?;
        let options = SqliteConnectOptions::new()
            .filename(path)
            .read_only(true)
            .busy_timeout(BUSY_TIMEOUT)
            .log_slow_statements(log::LevelFilter::Debug, Duration::from_secs(1));
        // Connect and read the schema once: in WAL mode SQLite only finds out
        // at the first read that it cannot make the shared-memory file.
        let connect = |options: SqliteConnectOptions| async move {
            let pool = single_connection_pool().connect_with(options).await?;
            match sqlx::query("SELECT 1 FROM sqlite_master LIMIT 1").fetch_optional(&pool).await {
                Ok(_) => Ok(pool),
                Err(e) => {
                    pool.close().await;
                    Err(e)
                }
            }
        };
        let (pool, immutable) = match connect(options.clone()).await {
            Ok(pool) => (pool, false),
            Err(e) if sqlite_code(&e).is_some_and(|c| matches!(c & 0xff, 8 | 14)) => {
                // SQLITE_READONLY / SQLITE_CANTOPEN: read-only media.
                let pool = connect(options.immutable(true)).await.map_err(|e| open_error(path, e))?;
                (pool, true)
            }
            Err(e) => return Err(open_error(path, e)),
        };
        let store = Store { pool, path: path.to_path_buf(), immutable };
        if let Err(e) = store.check_schema().await {
            store.close().await;
            return Err(e);
        }
        Ok(store)
    }

    /// The file is a survey database of a schema this version reads.
    async fn check_schema(&self) -> anyhow::Result<()> {
        let path = self.path.display();
        let tables: Vec<String> = sqlx::query_scalar(
            "SELECT name FROM sqlite_master WHERE type = 'table' AND name IN ('_sqlx_migrations', 'surveys', 'samples')",
        )
        .fetch_all(&self.pool)
        .await
        .map_err(|e| open_error(&self.path, e))?;
        if tables.len() < 3 {
            return Err(NotFound(format!(
                "{path} is not a survey database (it is an SQLite file without the survey tables)"
            ))
            .into());
        }
        let version: Option<i64> = sqlx::query_scalar("SELECT MAX(version) FROM _sqlx_migrations WHERE success")
            .fetch_one(&self.pool)
            .await
            .map_err(|e| open_error(&self.path, e))?;
        let known = MIGRATIONS.last().map_or(0, |m| m.0);
        match version {
            Some(v) if v > known => Err(NotFound(format!(
                "{path} was written by a newer version of survey (schema {v}; this version reads up to {known})"
            ))
            .into()),
            Some(v) if v < known => Err(NotFound(format!(
                "{path} has an older schema ({v}; this version reads {known}): any command that writes \
                 (`survey resume`, `survey import`) upgrades it"
            ))
            .into()),
            Some(_) => Ok(()),
            None => Err(NotFound(format!("{path} is not a survey database (its schema was never set up)")).into()),
        }
    }

    async fn connect(path: &Path, create: bool, limits: StoreLimits) -> anyhow::Result<Store> {
        // busy_timeout is applied when the connection is made, before the
        // pragmas (so the switch to WAL waits for a lock instead of failing).
        let options = SqliteConnectOptions::new()
            .filename(path)
            .create_if_missing(create)
            .busy_timeout(limits.busy_timeout)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .foreign_keys(true)
            // A long import or load is expected: sqlx's slow-statement notice
            // (with the full SQL) stays at debug, not on every user's stderr.
            .log_slow_statements(log::LevelFilter::Debug, Duration::from_secs(1));
        let options = match limits.max_pages {
            Some(n) => options.pragma("max_page_count", n.to_string()),
            None => options,
        };
        // Two processes opening a new database at the same moment race to
        // switch it to WAL (SQLite answers SQLITE_BUSY at once rather than
        // wait, to avoid a deadlock) and to apply migration 1 (the loser's
        // transaction fails with "table surveys already exists" and leaves
        // nothing behind). Either way the loser opens again, and then finds
        // the database set up; a few tries, a short pause between them.
        const TRIES: u32 = 10;
        let mut tries = 0;
        loop {
            tries += 1;
            let e: sqlx::migrate::MigrateError = match single_connection_pool().connect_with(options.clone()).await {
                Ok(pool) => match migrator().run(&pool).await {
                    Ok(()) => return Ok(Store { pool, path: path.to_path_buf(), immutable: false }),
                    Err(e) => {
                        pool.close().await;
                        e
                    }
                },
                Err(e) => sqlx::migrate::MigrateError::Execute(e),
            };
            let raced = match &e {
                sqlx::migrate::MigrateError::Execute(inner)
                | sqlx::migrate::MigrateError::ExecuteMigration(inner, _) => {
                    inner.as_database_error().is_some_and(|d| d.message().contains("already exists"))
                        || sqlite_code(inner).is_some_and(|c| matches!(c & 0xff, 5 | 6))
                }
                _ => false,
            };
            if raced && tries < TRIES {
                tracing::debug!(path = %path.display(), tries, "another process is setting the database up; again");
                tokio::time::sleep(Duration::from_millis(20 * u64::from(tries))).await;
                continue;
            }
            return Err(match e {
                sqlx::migrate::MigrateError::Execute(inner) => open_error(path, inner),
                sqlx::migrate::MigrateError::ExecuteMigration(inner, _) => open_error(path, inner),
                other => anyhow!(other),
            })
            .with_context(|| format!("cannot set up the survey database {}", path.display()));
        }
    }

    /// The database file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The SQLite journal mode in force (`"wal"`).
    pub async fn journal_mode(&self) -> anyhow::Result<String> {
        let mode: String = sqlx::query_scalar("PRAGMA journal_mode").fetch_one(&self.pool).await?;
        Ok(mode)
    }

    /// Close the connection (this checkpoints the WAL into the database file).
    pub async fn close(self) {
        self.pool.close().await;
    }

    fn no_survey(&self, id: i64) -> NotFound {
        NotFound(format!("no survey with id {id} in {}", self.path.display()))
    }

    /// A foreign key failure on `survey_id` means the survey does not exist.
    fn fk_to_not_found(&self, id: i64, e: sqlx::Error) -> anyhow::Error {
        if is_foreign_key_error(&e) { self.no_survey(id).into() } else { e.into() }
    }
}

/// The database was locked by another writer longer than the busy timeout
/// (`SQLITE_BUSY`, `SQLITE_LOCKED` and their extended codes), anywhere in the
/// error's chain: worth waiting for, not a failure of this process.
pub fn is_busy(e: &anyhow::Error) -> bool {
    e.chain().filter_map(|c| c.downcast_ref::<sqlx::Error>()).any(|e| {
        e.as_database_error()
            .and_then(|d| d.code())
            .and_then(|c| c.parse::<u32>().ok())
            .is_some_and(|c| matches!(c & 0xff, 5 | 6))
    })
}

fn is_foreign_key_error(e: &sqlx::Error) -> bool {
    e.as_database_error().is_some_and(|d| d.is_foreign_key_violation())
}

/// SQLite's (extended) result code of a database error.
fn sqlite_code(e: &sqlx::Error) -> Option<u32> {
    e.as_database_error().and_then(|d| d.code()).and_then(|c| c.parse().ok())
}

/// The file at `path` exists and is a file ([`NotFound`] otherwise).
fn existing_file(path: &Path) -> anyhow::Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => {}
        Ok(_) => {
            return Err(NotFound(format!("{} is not a survey database (it is not a file)", path.display())).into());
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(NotFound(format!(
                "no survey database at {}: run `survey run` or `survey import` first",
                path.display()
            ))
            .into());
        }
        Err(e) => {
            return Err(anyhow!(e).context(format!("cannot open the database {}", path.display())));
        }
    }
    Ok(())
}

/// An error opening `path`: "file is not a database" (SQLITE_NOTADB, 26) and
/// "database disk image is malformed" (SQLITE_CORRUPT, 11) are the user's
/// (a wrong or damaged file: bad input), anything else a run-time failure;
/// all name the path.
fn open_error(path: &Path, e: sqlx::Error) -> anyhow::Error {
    match sqlite_code(&e).map(|c| c & 0xff) {
        Some(26) => {
            NotFound(format!("{} is not a survey database (SQLite: file is not a database)", path.display())).into()
        }
        Some(11) => NotFound(format!(
            "{} is damaged (SQLite: database disk image is malformed); restore it from a backup",
            path.display()
        ))
        .into(),
        _ => anyhow::Error::new(e).context(format!("cannot open the database {}", path.display())),
    }
}

/// A nullable REAL column: NULL (how SQLite stores NaN) reads as NaN.
fn real(row: &SqliteRow, col: &str) -> anyhow::Result<f64> {
    let v: Option<f64> = row.try_get(col)?;
    Ok(v.unwrap_or(f64::NAN))
}
