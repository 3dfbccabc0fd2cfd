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
//! - `pack`: the samples packed once a survey's acquisition is whole (what
//!   the whole-survey reads decode);
//! - `sink`: [`StoreSink`], the batching [`SampleSink`].

pub use survey_config as config;
pub use survey_config::asset;
pub mod error;
pub mod runtime;
pub mod survey;

mod cache;
mod certificates;
mod check_points;
mod checks;
mod damage;
mod drift;
pub mod environment;
pub mod lab;
mod lock;
mod pack;
mod samples;
mod scan;
mod sink;
mod surveys;
#[cfg(test)]
mod tests;
mod tx;

pub use certificates::Issued;
pub use checks::CheckDecision;
pub use damage::WHOLE_CHECK_BYTES;
pub use lock::{AcquirerLock, Holder, RESERVE_BYTES, SurveyBusy, is_held, lock_path};
pub use pack::SmrPositions;
pub use scan::StoredPass;
pub use sink::StoreSink;
pub use surveys::EventRow;

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, anyhow};
use sqlx::migrate::{Migration, MigrationType, Migrator};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{ConnectOptions as _, Row, SqlSafeStr, SqlitePool};

#[cfg(doc)]
use survey_acquire::SampleSink;

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

/// Rows per multi-row `INSERT`: the widest row (a raw reading) binds 15 values,
/// so a statement binds at most 6 000, far under SQLite's limit of 32 766.
const CHUNK_ROWS: usize = 400;

/// The schema migrations, embedded in the binary (the same versions,
/// descriptions and checksums `sqlx::migrate!("../migrations")` would give).
const MIGRATIONS: &[(i64, &str, &str)] = &[
    (1, "init", include_str!("../../migrations/0001_init.sql")),
    (2, "drift", include_str!("../../migrations/0002_drift.sql")),
    (3, "instrument time", include_str!("../../migrations/0003_instrument_time.sql")),
    (4, "check points", include_str!("../../migrations/0004_check_points.sql")),
    (5, "assets", include_str!("../../migrations/0005_assets.sql")),
    (6, "processing", include_str!("../../migrations/0006_processing.sql")),
    (7, "sample packs", include_str!("../../migrations/0007_sample_packs.sql")),
    (8, "history cache", include_str!("../../migrations/0008_history_cache.sql")),
    (9, "environment", include_str!("../../migrations/0009_environment.sql")),
    (10, "smr readings", include_str!("../../migrations/0010_smr_readings.sql")),
    (11, "certificates", include_str!("../../migrations/0011_certificates.sql")),
    (12, "intervals", include_str!("../../migrations/0012_intervals.sql")),
    (13, "certificate numbers", include_str!("../../migrations/0013_certificate_numbers.sql")),
];

/// The schema that keeps the certificates issued (`certificates`).
const CERTIFICATE_SCHEMA: i64 = 11;

/// The schema that keeps the air of every tracker measurement (`raw_readings.air_*`).
const ENVIRONMENT_SCHEMA: i64 = 9;

/// The schema that keeps what each check measured of the table in force
/// (`checks.residual_peak_deg`, `stated_u_deg`: the control chart's).
const CONTROL_SCHEMA: i64 = 12;

/// The schema that brings the history's cache (`survey_summaries`,
/// `survey_changes`): a file of an older schema has none.
const CACHE_SCHEMA: i64 = 8;

/// The oldest schema a command that only reads reads as it is: the
/// migrations after it add only the history's cache, which a reader then
/// does without (computing on read what it would have read).
const READS_FROM: i64 = 7;

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
///
/// A station's store is an SQLite file; a laboratory's shared store is a
/// PostgreSQL database ([`lab`]), opened only to read (`--db postgres://...`)
/// or by `survey push`: every read works on either, with the same queries
/// where the dialects agree ([`on_pool`]).
#[derive(Debug, Clone)]
pub struct Store {
    backend: Backend,
    /// The file, or the lab store's URL without its password.
    path: PathBuf,
    /// Opened `immutable` (read-only media): the bulk reader must be too.
    immutable: bool,
    /// Opened to write: a station's file by a command that writes, the lab
    /// store by `survey push`.
    writable: bool,
    /// The history's cache tables are there (schema 8: every store opened
    /// to write; a file of schema 7 read as it is has none).
    cache: bool,
    /// The environment's columns are there (schema 9; an older file read as it is has none).
    environment: bool,
    /// The checks' control figures are there (schema 12; an older file read as it is has none).
    control: bool,
    /// The certificates' table is there (schema 11; an older file read as it is has none).
    certificates: bool,
}

/// The database behind a [`Store`].
#[derive(Debug, Clone)]
enum Backend {
    /// A station's SQLite file.
    Sqlite(SqlitePool),
    /// The lab store.
    Lab(sqlx::PgPool),
}

/// Run `$body` with `$pool` bound to the store's pool, SQLite or
/// PostgreSQL: the same query text on both (`$1`-style parameters, which
/// SQLite reads too), its rows mapped by the same code.
macro_rules! on_pool {
    ($store:expr, |$pool:ident| $body:expr) => {
        match &$store.backend {
            $crate::Backend::Sqlite($pool) => $body,
            $crate::Backend::Lab($pool) => $body,
        }
    };
}
use on_pool;

impl Store {
    /// Open the database at `path`, creating it if missing, and bring its schema
    /// up to date. WAL journal, `synchronous = FULL` (a committed transaction
    /// survives power loss), busy timeout 5 s, foreign keys enforced.
    ///
    /// Only a survey database, an empty file or none at all is opened: a
    /// folder, a device, another application's SQLite file, a damaged one or
    /// one of a newer version are refused ([`NotFound`], bad input) before
    /// anything is written to them.
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

    /// Open an existing survey database to write to it (`resume`): as
    /// [`Store::open`], and a [`NotFound`] when there is no file at `path`
    /// (none is created).
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
        if let Some(url) = lab::url_of(path) {
            return lab::open(url, false).await;
        }
        existing_file(path)?;
        // Another application's file and a damaged one are refused before a
        // connection that could make a WAL or shared-memory file beside it.
        inspect(path).await?;
        let (pool, immutable) = connect_read_only(path).await?;
        let mut store = Store {
            backend: Backend::Sqlite(pool),
            path: path.to_path_buf(),
            immutable,
            writable: false,
            cache: false,
            environment: false,
            control: false,
            certificates: false,
        };
        match store.check_schema().await {
            Ok(version) => {
                store.cache = version >= CACHE_SCHEMA;
                store.environment = version >= ENVIRONMENT_SCHEMA;
                store.control = version >= CONTROL_SCHEMA;
                store.certificates = version >= CERTIFICATE_SCHEMA;
            }
            Err(e) => {
                store.close().await;
                return Err(e);
            }
        }
        Ok(store)
    }

    /// The file is a survey database of a schema this version reads (this
    /// version's, or one from [`READS_FROM`] on, which lacks only the
    /// history's cache): its version.
    async fn check_schema(&self) -> anyhow::Result<i64> {
        let path = self.path.display();
        let known = MIGRATIONS.last().map_or(0, |m| m.0);
        match schema(self.sqlite()?, &self.path).await? {
            Schema::Unset => Err(NotFound(format!(
                "{path} is not a survey database (it is an SQLite file without the survey tables)"
            ))
            .into()),
            Schema::Survey(None) => {
                Err(NotFound(format!("{path} is not a survey database (its schema was never set up)")).into())
            }
            Schema::Survey(Some(v)) if v < READS_FROM => Err(NotFound(format!(
                "{path} has an older schema ({v}; this version reads {known}): any command that writes \
                 (`survey resume`, `survey import`) upgrades it"
            ))
            .into()),
            Schema::Survey(Some(v)) => Ok(v),
            Schema::Foreign => Err(foreign(&self.path)),
        }
    }

    /// What the file at `path` is, for a command that writes to it, found
    /// without writing anything: `true` when it is to be set up as a new survey
    /// database (there is no file, an empty one, or an SQLite file with no
    /// table yet: another `survey` process may be setting it up), `false` when
    /// it is a survey database. Everything else is refused with a
    /// [`NotFound`] (bad input) naming the file: a folder, a device or a pipe,
    /// a path whose folder does not exist, a file that is not SQLite, a
    /// damaged one, another application's database, a survey database of a
    /// newer version. Its bytes are left as they were.
    async fn writable_kind(path: &Path) -> anyhow::Result<bool> {
        let shown = path.display();
        let meta = match std::fs::metadata(path) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
                return match std::fs::metadata(parent) {
                    Ok(p) if p.is_dir() => Ok(true),
                    _ => Err(NotFound(format!(
                        "cannot create the database {shown}: the folder {} does not exist",
                        parent.display()
                    ))
                    .into()),
                };
            }
            Err(e) => return Err(anyhow!(e).context(format!("cannot open the database {shown}"))),
        };
        if let Some(e) = not_a_file(path, &meta) {
            return Err(e.into());
        }
        if meta.len() == 0 {
            return Ok(true);
        }
        inspect(path).await?;
        let (pool, _) = connect_read_only(path).await?;
        let found = schema(&pool, path).await;
        pool.close().await;
        match found? {
            Schema::Unset => Ok(true),
            Schema::Survey(_) => Ok(false),
            Schema::Foreign => Err(foreign(path)),
        }
    }

    async fn connect(path: &Path, create: bool, limits: StoreLimits) -> anyhow::Result<Store> {
        lab::refuse_writes(path)?;
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
        // transaction fails with "table surveys already exists", or with
        // "duplicate column name" for a later migration, and leaves nothing
        // behind). Either way the loser opens again, and then finds
        // the database set up; a few tries, a short pause between them.
        const TRIES: u32 = 10;
        let mut tries = 0;
        loop {
            tries += 1;
            // What the file is, found without writing to it: nothing but a
            // survey database (or a new one) is ever written.
            let new = match Self::writable_kind(path).await {
                Ok(new) => new,
                Err(e) if is_busy(&e) && tries < TRIES => {
                    tokio::time::sleep(Duration::from_millis(20 * u64::from(tries))).await;
                    continue;
                }
                Err(e) => return Err(e),
            };
            if new && !create {
                return Err(NotFound(format!(
                    "no survey database at {}: the file holds no survey table (run `survey run` or `survey import` first)",
                    path.display()
                ))
                .into());
            }
            // The store's own connection first, then the migrations on theirs:
            // closing the migrations' connection is then never closing the
            // last one, which would checkpoint the whole write-ahead log into
            // the database file (on a full disk just freed, that checkpoint
            // took the space the next write needed).
            let e: sqlx::migrate::MigrateError = match single_connection_pool().connect_with(options.clone()).await {
                Ok(pool) => match migrate(&options).await {
                    Ok(()) => {
                        return Ok(Store {
                            backend: Backend::Sqlite(pool),
                            path: path.to_path_buf(),
                            immutable: false,
                            writable: true,
                            cache: true,
                            environment: true,
                            control: true,
                            certificates: true,
                        });
                    }
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
                    inner.as_database_error().is_some_and(|d| {
                        d.message().contains("already exists")
                            || d.message().contains("_sqlx_migrations.version")
                            || d.message().contains("duplicate column name")
                    }) || sqlite_code(inner).is_some_and(|c| matches!(c & 0xff, 5 | 6))
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
        let mode: String = sqlx::query_scalar("PRAGMA journal_mode").fetch_one(self.sqlite()?).await?;
        Ok(mode)
    }

    /// Close the connection (this checkpoints the WAL into the database file).
    pub async fn close(self) {
        on_pool!(self, |pool| pool.close().await)
    }

    /// The SQLite pool of a station's store: what every write and the
    /// station-only reads use. The lab store is written only by `survey push`.
    fn sqlite(&self) -> anyhow::Result<&SqlitePool> {
        match &self.backend {
            Backend::Sqlite(pool) => Ok(pool),
            Backend::Lab(_) => Err(lab::written_by_push(&self.path)),
        }
    }

    /// Whether this is the lab store (PostgreSQL).
    pub fn is_lab(&self) -> bool {
        matches!(self.backend, Backend::Lab(_))
    }

    /// Whether this store was opened to write (a station's file by a
    /// command that writes, the lab store by `survey push`): a read-only
    /// open never writes, not even the history's cache.
    pub fn can_write(&self) -> bool {
        self.writable
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
pub(crate) fn sqlite_code(e: &sqlx::Error) -> Option<u32> {
    e.as_database_error().and_then(|d| d.code()).and_then(|c| c.parse().ok())
}

/// Bring the schema up to date on a connection of its own with foreign keys
/// off, as SQLite's procedure for rebuilding a table asks (migration 4
/// rebuilds `surveys` to change its CHECK; each migration commits with its
/// record), then, when a migration was applied, check them (`PRAGMA
/// foreign_key_check`, the procedure's last step): a row left without the
/// row it refers to fails the open. (The check reads every row of the
/// database: made on every open, it made each `survey run` on a station of
/// 3000 surveys cost 0.3 s more than on a new one.)
async fn migrate(options: &SqliteConnectOptions) -> Result<(), sqlx::migrate::MigrateError> {
    let pool = single_connection_pool().connect_with(options.clone().foreign_keys(false)).await?;
    // The schema applied (none when the migrations table is not there yet).
    let applied = || async {
        sqlx::query_scalar::<_, Option<i64>>("SELECT MAX(version) FROM _sqlx_migrations WHERE success")
            .fetch_one(&pool)
            .await
            .ok()
            .flatten()
    };
    let before = applied().await;
    let checked = match migrator().run(&pool).await {
        Ok(()) if applied().await == before => Ok(()),
        Ok(()) => match sqlx::query("PRAGMA foreign_key_check").fetch_all(&pool).await {
            Ok(rows) if rows.is_empty() => Ok(()),
            Ok(rows) => Err(sqlx::migrate::MigrateError::Source(
                format!("the schema upgrade left {} rows without the row they refer to", rows.len()).into(),
            )),
            Err(e) => Err(e.into()),
        },
        Err(e) => Err(e),
    };
    pool.close().await;
    checked
}

/// What an SQLite file holds, as far as `survey` is concerned.
enum Schema {
    /// No table at all, or only an empty migrations table: nothing set up
    /// (yet: another process may be setting it up).
    Unset,
    /// The survey tables, at this schema version (`None`: none recorded).
    Survey(Option<i64>),
    /// Another application's database: tables of its own.
    Foreign,
}

/// The refusal of another application's database ([`NotFound`]: bad input).
fn foreign(path: &Path) -> anyhow::Error {
    NotFound(format!(
        "{} is not a survey database (it is an SQLite file without the survey tables): nothing was written to it",
        path.display()
    ))
    .into()
}

/// What the SQLite file of `pool` (at `path`) holds: [`Schema`], or a
/// [`NotFound`] for a survey database of a newer version than this one.
async fn schema(pool: &SqlitePool, path: &Path) -> anyhow::Result<Schema> {
    let shown = path.display();
    let tables: Vec<String> = sqlx::query_scalar(
        r"SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite\_%' ESCAPE '\'",
    )
    .fetch_all(pool)
    .await
    .map_err(|e| open_error(path, e))?;
    let has = |name: &str| tables.iter().any(|t| t == name);
    let version: Option<i64> = match has("_sqlx_migrations") {
        true => sqlx::query_scalar("SELECT MAX(version) FROM _sqlx_migrations WHERE success")
            .fetch_one(pool)
            .await
            .map_err(|e| open_error(path, e))?,
        false => None,
    };
    let known = MIGRATIONS.last().map_or(0, |m| m.0);
    if has("surveys") && has("samples") && has("_sqlx_migrations") {
        return match version {
            Some(v) if v > known => Err(NotFound(format!(
                "{shown} was written by a newer version of survey (schema {v}; this version reads up to {known})"
            ))
            .into()),
            v => Ok(Schema::Survey(v)),
        };
    }
    if version.is_none() && tables.iter().all(|t| t == "_sqlx_migrations") {
        return Ok(Schema::Unset);
    }
    Ok(Schema::Foreign)
}

/// Refuse the SQLite file at `path` if it is another application's database
/// or a damaged survey database (see `damage`), as far as can be told without
/// leaving a trace: opened `immutable` (no lock, no WAL or shared-memory file
/// made beside it, which even a read-only connection to a WAL database
/// makes), it shows its last checkpoint. A survey database never looks
/// foreign that way (every checkpoint is a committed state of it); anything
/// this glance cannot read (a checkpoint under way, a file that is not
/// SQLite) is left to the connection that follows, which decides. Damage
/// seen while a write-ahead log or a rollback journal is there, or while the
/// file changed under the glance (a writer's checkpoint, a new database's
/// schema being made by another process), is confirmed on an ordinary
/// read-only connection first.
async fn inspect(path: &Path) -> anyhow::Result<()> {
    // The file's length and its write-ahead log, before SQLite reads either.
    let replays = damage::settled(path).await?;
    let stamp = |p: &Path| std::fs::metadata(p).ok().map(|m| (m.len(), m.modified().ok()));
    let before = stamp(path);
    let options = SqliteConnectOptions::new().filename(path).read_only(true).immutable(true);
    let Ok(pool) = single_connection_pool().connect_with(options).await else { return Ok(()) };
    let found = schema(&pool, path).await;
    let known = MIGRATIONS.last().map_or(0, |m| m.0);
    let problems = match found {
        Ok(Schema::Foreign) => {
            pool.close().await;
            return Err(foreign(path));
        }
        Ok(Schema::Survey(Some(v))) if v <= known => damage::problems(&pool, path, v, false).await,
        // Pages of the schema or the migrations' table that do not read.
        Err(e) if e.to_string().contains(damage::MALFORMED) => Ok(vec![damage::MALFORMED.to_string()]),
        _ => Ok(Vec::new()),
    };
    pool.close().await;
    let problems = problems?;
    if problems.is_empty() {
        return match replays {
            true => through_log(path).await,
            false => Ok(()),
        };
    }
    let beside = |suffix: &str| {
        let mut p = path.as_os_str().to_os_string();
        p.push(suffix);
        std::fs::metadata(p).is_ok_and(|m| m.len() > 0)
    };
    // Another process writing it (a write-ahead log, a rollback journal: a
    // new database's schema being made; or the file changed under the
    // glance) may have shown the glance a page mid-write: confirmed on an
    // ordinary read-only connection, which takes SQLite's locks.
    if beside("-wal") || beside("-journal") || stamp(path) != before {
        let (pool, _) = connect_read_only(path).await?;
        let again = match schema(&pool, path).await {
            Ok(Schema::Survey(Some(v))) if v <= known => damage::problems(&pool, path, v, true).await,
            _ => Ok(problems.clone()),
        };
        pool.close().await;
        if again?.is_empty() {
            return Ok(());
        }
    }
    Err(damage::damaged(path, &problems))
}

/// The survey database at `path` as its write-ahead log makes it (the log
/// has frames SQLite replays, and belongs to the file as far as its bytes
/// tell: `damage::settled`) is checked as the file alone was: its schema and
/// `PRAGMA quick_check`, on an ordinary read-only connection, which reads the
/// log as every reader and writer will (and may make SQLite's shared-memory
/// index beside it; the file and the log are not written).
async fn through_log(path: &Path) -> anyhow::Result<()> {
    let (pool, immutable) = connect_read_only(path).await?;
    let known = MIGRATIONS.last().map_or(0, |m| m.0);
    let problems = match schema(&pool, path).await {
        Ok(Schema::Survey(Some(v))) if v <= known && !immutable => damage::problems(&pool, path, v, true).await,
        Ok(_) => Ok(Vec::new()),
        Err(e) if e.to_string().contains(damage::MALFORMED) => Ok(vec![damage::MALFORMED.to_string()]),
        Err(e) => Err(e),
    };
    pool.close().await;
    let problems = problems?;
    if problems.is_empty() {
        return Ok(());
    }
    let log = damage::wal_path(path);
    let mut said = vec![format!("as the write-ahead log beside it ({}) makes it", log.display())];
    said.extend(problems);
    said.push(format!(
        "the file without that log reads as of its last checkpoint (move {} aside to read it so)",
        log.display()
    ));
    Err(damage::damaged(path, &said))
}

/// A read-only connection to the SQLite file at `path` that has read its
/// schema once (in WAL mode SQLite only finds out at the first read that it
/// cannot make the shared-memory file); on read-only media (SQLite cannot
/// make that file) the file is opened as immutable, and `true` says so.
async fn connect_read_only(path: &Path) -> anyhow::Result<(SqlitePool, bool)> {
    let options = SqliteConnectOptions::new()
        .filename(path)
        .read_only(true)
        .busy_timeout(BUSY_TIMEOUT)
        .log_slow_statements(log::LevelFilter::Debug, Duration::from_secs(1));
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
    match connect(options.clone()).await {
        Ok(pool) => Ok((pool, false)),
        Err(e) if sqlite_code(&e).is_some_and(|c| matches!(c & 0xff, 8 | 14)) => {
            // SQLITE_READONLY / SQLITE_CANTOPEN: read-only media.
            let pool = connect(options.immutable(true)).await.map_err(|e| open_error(path, e))?;
            Ok((pool, true))
        }
        Err(e) => Err(open_error(path, e)),
    }
}

/// The file at `path` exists and is a file ([`NotFound`] otherwise).
fn existing_file(path: &Path) -> anyhow::Result<()> {
    lab::refuse_writes(path)?;
    match std::fs::metadata(path) {
        Ok(m) => not_a_file(path, &m).map_or(Ok(()), |e| Err(e.into())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(NotFound(format!(
            "no survey database at {}: run `survey run` or `survey import` first",
            path.display()
        ))
        .into()),
        Err(e) => Err(anyhow!(e).context(format!("cannot open the database {}", path.display()))),
    }
}

/// What is wrong with `--db` naming something that is there but is not a
/// regular file: a folder, a device (`/dev/null`), a pipe.
fn not_a_file(path: &Path, meta: &std::fs::Metadata) -> Option<NotFound> {
    let shown = path.display();
    if meta.is_dir() {
        Some(NotFound(format!("{shown} is a folder, not a survey database: --db names the database file")))
    } else if !meta.is_file() {
        Some(NotFound(format!(
            "{shown} is not a regular file (a device or a pipe), not a survey database: --db names the database file"
        )))
    } else {
        None
    }
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
        Some(11) => damage::damaged(path, &[damage::MALFORMED.to_string()]),
        _ => anyhow::Error::new(e).context(format!("cannot open the database {}", path.display())),
    }
}

/// A nullable REAL column: NULL (how SQLite stores NaN) reads as NaN.
fn real<'r, R: Row>(row: &'r R, col: &str) -> anyhow::Result<f64>
where
    Option<f64>: sqlx::Decode<'r, R::Database> + sqlx::Type<R::Database>,
    for<'c> &'c str: sqlx::ColumnIndex<R>,
{
    let v: Option<f64> = row.try_get(col)?;
    Ok(v.unwrap_or(f64::NAN))
}
