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

use std::borrow::Cow;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::{Duration, Instant};

use anyhow::{Context, anyhow, bail};
use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use sqlx::migrate::{Migration, MigrationType, Migrator};
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteConnection, SqliteJournalMode, SqlitePoolOptions, SqliteRow,
    SqliteSynchronous,
};
use sqlx::{QueryBuilder, Row, SqlSafeStr, Sqlite, SqlitePool};
use survey_drivers::{AcReading, SmrMeasurement};
use survey_processing::geometry::AxisFit;
use survey_processing::{Direction, Sample};

use crate::record::{RawReading, RecordedSample, SampleSink};

/// How long a statement waits for another connection's lock before it fails.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

/// Rows per multi-row `INSERT`: the widest row (a raw reading) binds 12 values,
/// so a statement binds at most 4 800, far under SQLite's limit of 32 766.
const CHUNK_ROWS: usize = 400;

/// The schema migrations, embedded in the binary (the same versions,
/// descriptions and checksums `sqlx::migrate!("../migrations")` would give).
const MIGRATIONS: &[(i64, &str, &str)] =
    &[(1, "init", include_str!("../../migrations/0001_init.sql"))];

fn migrator() -> Migrator {
    Migrator::with_migrations(
        MIGRATIONS
            .iter()
            .map(|&(version, description, sql)| {
                Migration::new(
                    version,
                    Cow::Borrowed(description),
                    MigrationType::Simple,
                    sql.into_sql_str(),
                    false,
                )
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

/// Where a survey stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SurveyStatus {
    /// Acquisition is under way (or the process died without saying otherwise:
    /// `survey resume` treats a `running` survey like an interrupted one).
    Running,
    /// Acquisition stopped before the plan was complete; `survey resume` continues it.
    Interrupted,
    /// Every planned sample is stored.
    Complete,
    /// Acquisition gave up on an error.
    Failed,
    /// Data imported from a CSV file.
    Imported,
}

impl SurveyStatus {
    /// The name stored in the database and shown to users.
    pub fn as_str(self) -> &'static str {
        match self {
            SurveyStatus::Running => "running",
            SurveyStatus::Interrupted => "interrupted",
            SurveyStatus::Complete => "complete",
            SurveyStatus::Failed => "failed",
            SurveyStatus::Imported => "imported",
        }
    }
}

impl fmt::Display for SurveyStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for SurveyStatus {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "running" => Ok(SurveyStatus::Running),
            "interrupted" => Ok(SurveyStatus::Interrupted),
            "complete" => Ok(SurveyStatus::Complete),
            "failed" => Ok(SurveyStatus::Failed),
            "imported" => Ok(SurveyStatus::Imported),
            other => Err(format!(
                "unknown survey status '{other}' (expected running, interrupted, complete, failed or imported)"
            )),
        }
    }
}

/// What [`Store::create_survey`] and [`Store::import`] store about a new survey.
#[derive(Debug, Clone, PartialEq)]
pub struct NewSurvey {
    /// `Running` for an acquisition, `Imported` for an import.
    pub status: SurveyStatus,
    /// `simulated`, `instruments` or `import:<file>`.
    pub source: String,
    /// Target positions per revolution, when known.
    pub points: Option<u32>,
    /// Runs in the plan, when known.
    pub runs: Option<u32>,
    /// Runs go both ways (forward then reverse).
    pub bidirectional: bool,
    /// The full survey configuration and plan, JSON.
    pub config_json: String,
    /// The simulated positioner model (TOML), when simulated.
    pub model_toml: Option<String>,
    /// The names of the instrument drivers, JSON.
    pub instruments_json: String,
    /// How many samples the plan holds, when known.
    pub planned_samples: Option<u64>,
}

impl Default for NewSurvey {
    /// A running survey with no configuration (`{}`) and no instruments (`[]`).
    fn default() -> Self {
        NewSurvey {
            status: SurveyStatus::Running,
            source: String::new(),
            points: None,
            runs: None,
            bidirectional: false,
            config_json: "{}".to_string(),
            model_toml: None,
            instruments_json: "[]".to_string(),
            planned_samples: None,
        }
    }
}

/// A stored survey, with the number of samples stored for it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurveyRow {
    /// The survey id (`--survey ID`).
    pub id: i64,
    /// UTC ISO-8601, e.g. `2025-03-01T14:02:11Z`.
    pub created_at: String,
    /// UTC ISO-8601: the last change of status or axis.
    pub updated_at: String,
    /// Where the survey stands.
    pub status: SurveyStatus,
    /// `simulated`, `instruments` or `import:<file>`.
    pub source: String,
    /// Target positions per revolution, when known.
    pub points: Option<u32>,
    /// Runs in the plan, when known.
    pub runs: Option<u32>,
    /// Runs go both ways.
    pub bidirectional: bool,
    /// The full survey configuration and plan, JSON.
    pub config_json: String,
    /// The simulated positioner model (TOML), when simulated.
    pub model_toml: Option<String>,
    /// The names of the instrument drivers, JSON.
    pub instruments_json: String,
    /// The located axis, JSON, once located.
    pub axis_json: Option<String>,
    /// Instrument time when acquisition started, seconds (see [`Store::set_started`]).
    pub started_at_s: Option<f64>,
    /// Instrument time when acquisition ended, seconds.
    pub ended_at_s: Option<f64>,
    /// How many samples the plan holds, when known.
    pub planned_samples: Option<u64>,
    /// Samples stored for this survey.
    pub sample_count: u64,
}

/// One entry of a survey's event log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventRow {
    /// Increasing in the order the events were logged.
    pub id: i64,
    /// Instrument time, seconds since the survey started (NaN if not given).
    pub at_s: f64,
    /// `info`, `warn`, `error` (free text).
    pub level: String,
    /// What happened.
    pub message: String,
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
}

const SURVEY_COLUMNS: &str = "SELECT s.id, s.created_at, s.updated_at, s.status, s.source, \
     s.points, s.runs, s.bidirectional, s.config_json, s.model_toml, s.instruments_json, \
     s.axis_json, s.started_at_s, s.ended_at_s, s.planned_samples, \
     (SELECT COUNT(*) FROM samples AS c WHERE c.survey_id = s.id) AS sample_count \
     FROM surveys AS s";

impl Store {
    /// Open the database at `path`, creating it if missing, and bring its schema
    /// up to date. WAL journal, `synchronous = FULL` (a committed transaction
    /// survives power loss), busy timeout 5 s, foreign keys enforced.
    pub async fn open(path: &Path) -> anyhow::Result<Store> {
        Self::connect(path, true).await
    }

    /// Open an existing database (for the commands that only read). Fails with a
    /// [`NotFound`] when there is no file at `path`, and does not create one.
    pub async fn open_existing(path: &Path) -> anyhow::Result<Store> {
        match std::fs::metadata(path) {
            Ok(m) if m.is_file() => {}
            Ok(_) => {
                return Err(NotFound(format!(
                    "{} is not a survey database (it is not a file)",
                    path.display()
                ))
                .into());
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(NotFound(format!(
                    "no survey database at {}: run `survey run` or `survey import` first",
                    path.display()
                ))
                .into());
            }
            Err(e) => {
                return Err(
                    anyhow!(e).context(format!("cannot open the database {}", path.display()))
                );
            }
        }
        Self::connect(path, false).await
    }

    async fn connect(path: &Path, create: bool) -> anyhow::Result<Store> {
        // busy_timeout is applied when the connection is made, before the
        // pragmas (so the switch to WAL waits for a lock instead of failing).
        let options = SqliteConnectOptions::new()
            .filename(path)
            .create_if_missing(create)
            .busy_timeout(BUSY_TIMEOUT)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .foreign_keys(true);
        let pool = SqlitePoolOptions::new()
            .max_connections(1)
            .min_connections(0)
            .connect_with(options)
            .await
            .map_err(|e| open_error(path, e))?;
        migrator()
            .run(&pool)
            .await
            .map_err(|e| match e {
                sqlx::migrate::MigrateError::Execute(inner) => open_error(path, inner),
                other => anyhow!(other),
            })
            .with_context(|| format!("cannot set up the survey database {}", path.display()))?;
        Ok(Store {
            pool,
            path: path.to_path_buf(),
        })
    }

    /// The database file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The SQLite journal mode in force (`"wal"`).
    pub async fn journal_mode(&self) -> anyhow::Result<String> {
        let mode: String = sqlx::query_scalar("PRAGMA journal_mode")
            .fetch_one(&self.pool)
            .await?;
        Ok(mode)
    }

    /// Store a new survey; returns its id.
    pub async fn create_survey(&self, s: &NewSurvey) -> anyhow::Result<i64> {
        let mut conn = self.pool.acquire().await?;
        let id = insert_survey(&mut conn, s)
            .await
            .with_context(|| format!("cannot store a new survey in {}", self.path.display()))?;
        Ok(id)
    }

    /// Store samples of survey `survey_id` with their raw readings, in one
    /// transaction: all of them or, on any error, none. A `seq` already stored
    /// is an error (never a silent replace). When this returns `Ok`, the samples
    /// are durable.
    pub async fn append(&self, survey_id: i64, samples: &[RecordedSample]) -> anyhow::Result<()> {
        if samples.is_empty() {
            return Ok(());
        }
        let mut tx = self.pool.begin().await?;
        insert_samples(&mut tx, survey_id, samples)
            .await
            .with_context(|| {
                format!(
                    "cannot store samples {}..={} of survey {} in {}",
                    samples[0].seq,
                    samples[samples.len() - 1].seq,
                    survey_id,
                    self.path.display()
                )
            })?;
        tx.commit().await.with_context(|| {
            format!(
                "cannot commit samples of survey {survey_id} in {}",
                self.path.display()
            )
        })?;
        Ok(())
    }

    /// Store a new survey and all its samples (seq 0, 1, 2, ... in the given
    /// order, no raw readings) in one transaction: if anything fails, nothing
    /// is stored. Returns the new survey's id.
    pub async fn import(&self, s: &NewSurvey, samples: &[Sample]) -> anyhow::Result<i64> {
        let recorded: Vec<RecordedSample> = samples
            .iter()
            .enumerate()
            .map(|(i, sample)| RecordedSample {
                seq: i as u64,
                sample: *sample,
                raw: RawReading::None,
            })
            .collect();
        let mut tx = self.pool.begin().await?;
        let id = insert_survey(&mut tx, s).await?;
        insert_samples(&mut tx, id, &recorded).await?;
        tx.commit().await?;
        Ok(id)
    }

    /// The samples of a survey, ordered by seq, with their raw readings.
    pub async fn samples(&self, survey_id: i64) -> anyhow::Result<Vec<RecordedSample>> {
        let rows = sqlx::query(
            "SELECT s.seq, s.run, s.direction, s.target_deg, s.readout_deg, s.actual_deg, \
             s.timestamp_s, r.kind, r.smr_x_mm, r.smr_y_mm, r.smr_z_mm, r.smr_sx_mm, \
             r.smr_sy_mm, r.smr_sz_mm, r.measurement_time_s, r.ac_face, r.ac_x_arcsec, \
             r.ac_y_arcsec \
             FROM samples AS s LEFT JOIN raw_readings AS r \
             ON r.survey_id = s.survey_id AND r.seq = s.seq \
             WHERE s.survey_id = ? ORDER BY s.seq",
        )
        .bind(survey_id)
        .fetch_all(&self.pool)
        .await
        .with_context(|| format!("cannot read the samples of survey {survey_id}"))?;
        rows.iter()
            .map(sample_from_row)
            .collect::<anyhow::Result<Vec<_>>>()
            .with_context(|| {
                format!(
                    "survey {survey_id} in {} holds a bad sample",
                    self.path.display()
                )
            })
    }

    /// Set a survey's status and, when given, the instrument time it ended.
    /// A [`NotFound`] error when there is no such survey.
    pub async fn set_status(
        &self,
        id: i64,
        status: SurveyStatus,
        ended_at_s: Option<f64>,
    ) -> anyhow::Result<()> {
        let done = sqlx::query(
            "UPDATE surveys SET status = ?, ended_at_s = COALESCE(?, ended_at_s), \
             updated_at = strftime('%Y-%m-%dT%H:%M:%SZ', 'now') WHERE id = ?",
        )
        .bind(status.as_str())
        .bind(ended_at_s)
        .bind(id)
        .execute(&self.pool)
        .await?;
        if done.rows_affected() == 0 {
            return Err(self.no_survey(id).into());
        }
        Ok(())
    }

    /// Set the instrument time at which acquisition started.
    pub async fn set_started(&self, id: i64, started_at_s: f64) -> anyhow::Result<()> {
        let done = sqlx::query(
            "UPDATE surveys SET started_at_s = ?, \
             updated_at = strftime('%Y-%m-%dT%H:%M:%SZ', 'now') WHERE id = ?",
        )
        .bind(started_at_s)
        .bind(id)
        .execute(&self.pool)
        .await?;
        if done.rows_affected() == 0 {
            return Err(self.no_survey(id).into());
        }
        Ok(())
    }

    /// Store the located axis (JSON).
    pub async fn set_axis(&self, id: i64, axis_json: &str) -> anyhow::Result<()> {
        let done = sqlx::query(
            "UPDATE surveys SET axis_json = ?, \
             updated_at = strftime('%Y-%m-%dT%H:%M:%SZ', 'now') WHERE id = ?",
        )
        .bind(axis_json)
        .bind(id)
        .execute(&self.pool)
        .await?;
        if done.rows_affected() == 0 {
            return Err(self.no_survey(id).into());
        }
        Ok(())
    }

    /// Add SMR positions measured to locate the axis, `(readout_deg,
    /// measurement)`, after those already stored for the survey (one transaction).
    pub async fn add_locate_points(
        &self,
        id: i64,
        points: &[(f64, SmrMeasurement)],
    ) -> anyhow::Result<()> {
        if points.is_empty() {
            return Ok(());
        }
        let mut tx = self.pool.begin().await?;
        let next: i64 = sqlx::query_scalar(
            "SELECT COALESCE(MAX(idx) + 1, 0) FROM locate_points WHERE survey_id = ?",
        )
        .bind(id)
        .fetch_one(&mut *tx)
        .await?;
        for (chunk_no, chunk) in points.chunks(CHUNK_ROWS).enumerate() {
            let base = next + (chunk_no * CHUNK_ROWS) as i64;
            let mut qb: QueryBuilder<Sqlite> = QueryBuilder::new(
                "INSERT INTO locate_points (survey_id, idx, readout_deg, x_mm, y_mm, z_mm, \
                 sx, sy, sz, measurement_time_s) ",
            );
            qb.push_values(chunk.iter().enumerate(), |mut b, (i, (readout, m))| {
                b.push_bind(id)
                    .push_bind(base + i as i64)
                    .push_bind(*readout)
                    .push_bind(m.x_mm)
                    .push_bind(m.y_mm)
                    .push_bind(m.z_mm)
                    .push_bind(m.std_dev_mm[0])
                    .push_bind(m.std_dev_mm[1])
                    .push_bind(m.std_dev_mm[2])
                    .push_bind(m.measurement_time_s);
            });
            qb.build().execute(&mut *tx).await.map_err(|e| {
                self.fk_to_not_found(id, e)
                    .context(format!("cannot store the locate points of survey {id}"))
            })?;
        }
        tx.commit().await?;
        Ok(())
    }

    /// The SMR positions that located the axis, in the order they were stored.
    /// A coordinate SQLite held as NULL (the instrument gave NaN) reads as NaN.
    pub async fn locate_points(&self, id: i64) -> anyhow::Result<Vec<(f64, SmrMeasurement)>> {
        let rows = sqlx::query(
            "SELECT readout_deg, x_mm, y_mm, z_mm, sx, sy, sz, measurement_time_s \
             FROM locate_points WHERE survey_id = ? ORDER BY idx",
        )
        .bind(id)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| -> anyhow::Result<(f64, SmrMeasurement)> {
                Ok((
                    r.try_get("readout_deg")?,
                    SmrMeasurement {
                        x_mm: real(r, "x_mm")?,
                        y_mm: real(r, "y_mm")?,
                        z_mm: real(r, "z_mm")?,
                        std_dev_mm: [real(r, "sx")?, real(r, "sy")?, real(r, "sz")?],
                        measurement_time_s: real(r, "measurement_time_s")?,
                    },
                ))
            })
            .collect()
    }

    /// Log an event (a fault survived, a resume) at instrument time `at_s`.
    /// `level` is free text; the engine uses `info`, `warn` and `error`.
    pub async fn log_event(
        &self,
        id: i64,
        at_s: f64,
        level: &str,
        message: &str,
    ) -> anyhow::Result<()> {
        sqlx::query("INSERT INTO events (survey_id, at_s, level, message) VALUES (?, ?, ?, ?)")
            .bind(id)
            .bind(at_s)
            .bind(level)
            .bind(message)
            .execute(&self.pool)
            .await
            .map_err(|e| {
                self.fk_to_not_found(id, e)
                    .context(format!("cannot log an event of survey {id}"))
            })?;
        Ok(())
    }

    /// A survey's events, in the order they were logged.
    pub async fn events(&self, id: i64) -> anyhow::Result<Vec<EventRow>> {
        let rows = sqlx::query(
            "SELECT id, at_s, level, message FROM events WHERE survey_id = ? ORDER BY id",
        )
        .bind(id)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| -> anyhow::Result<EventRow> {
                Ok(EventRow {
                    id: r.try_get("id")?,
                    at_s: real(r, "at_s")?,
                    level: r.try_get("level")?,
                    message: r.try_get("message")?,
                })
            })
            .collect()
    }

    /// One survey. A [`NotFound`] error (`no survey with id 7 in survey.db`)
    /// when there is none with that id.
    pub async fn survey(&self, id: i64) -> anyhow::Result<SurveyRow> {
        let mut qb: QueryBuilder<Sqlite> = QueryBuilder::new(SURVEY_COLUMNS);
        qb.push(" WHERE s.id = ").push_bind(id);
        let row = qb.build().fetch_optional(&self.pool).await?;
        match row {
            Some(row) => survey_from_row(&row),
            None => Err(self.no_survey(id).into()),
        }
    }

    /// The id of the latest survey (the highest id), if any.
    pub async fn latest_survey_id(&self) -> anyhow::Result<Option<i64>> {
        let id: Option<i64> = sqlx::query_scalar("SELECT MAX(id) FROM surveys")
            .fetch_one(&self.pool)
            .await?;
        Ok(id)
    }

    /// The survey `id`, or the latest one when `id` is `None`. A [`NotFound`]
    /// error when that survey does not exist or the database holds none.
    pub async fn resolve(&self, id: Option<i64>) -> anyhow::Result<SurveyRow> {
        match id {
            Some(id) => self.survey(id).await,
            None => match self.latest_survey_id().await? {
                Some(id) => self.survey(id).await,
                None => Err(NotFound(format!(
                    "no survey in {}: run `survey run` or `survey import` first",
                    self.path.display()
                ))
                .into()),
            },
        }
    }

    /// Every survey, oldest first.
    pub async fn list(&self) -> anyhow::Result<Vec<SurveyRow>> {
        let mut qb: QueryBuilder<Sqlite> = QueryBuilder::new(SURVEY_COLUMNS);
        qb.push(" ORDER BY s.id");
        let rows = qb.build().fetch_all(&self.pool).await?;
        rows.iter().map(survey_from_row).collect()
    }

    /// The highest seq stored for a survey (`None` when it has no sample yet).
    /// Samples are stored in plan order, so a resume continues at `last + 1`.
    pub async fn last_seq(&self, id: i64) -> anyhow::Result<Option<u64>> {
        let seq: Option<i64> =
            sqlx::query_scalar("SELECT MAX(seq) FROM samples WHERE survey_id = ?")
                .bind(id)
                .fetch_one(&self.pool)
                .await?;
        seq.map(|s| u64::try_from(s).context("negative seq in the database"))
            .transpose()
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
        if is_foreign_key_error(&e) {
            self.no_survey(id).into()
        } else {
            e.into()
        }
    }
}

fn is_foreign_key_error(e: &sqlx::Error) -> bool {
    e.as_database_error()
        .is_some_and(|d| d.is_foreign_key_violation())
}

/// An error opening `path`: "file is not a database" (SQLITE_NOTADB, 26) is a
/// user error, anything else a run-time failure; both name the path.
fn open_error(path: &Path, e: sqlx::Error) -> anyhow::Error {
    let not_a_db = e
        .as_database_error()
        .and_then(|d| d.code())
        .is_some_and(|c| c == "26");
    if not_a_db {
        NotFound(format!(
            "{} is not a survey database (SQLite: file is not a database)",
            path.display()
        ))
        .into()
    } else {
        anyhow::Error::new(e).context(format!("cannot open the database {}", path.display()))
    }
}

async fn insert_survey(conn: &mut SqliteConnection, s: &NewSurvey) -> anyhow::Result<i64> {
    let planned = s
        .planned_samples
        .map(i64::try_from)
        .transpose()
        .context("planned_samples is too large")?;
    let done = sqlx::query(
        "INSERT INTO surveys (status, source, points, runs, bidirectional, config_json, \
         model_toml, instruments_json, planned_samples) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
    )
    .bind(s.status.as_str())
    .bind(s.source.as_str())
    .bind(s.points.map(i64::from))
    .bind(s.runs.map(i64::from))
    .bind(s.bidirectional)
    .bind(s.config_json.as_str())
    .bind(s.model_toml.as_deref())
    .bind(s.instruments_json.as_str())
    .bind(planned)
    .execute(&mut *conn)
    .await?;
    Ok(done.last_insert_rowid())
}

/// Check what SQLite would reject with a less helpful message (or silently
/// change: SQLite stores NaN as NULL).
fn check_sample(r: &RecordedSample) -> anyhow::Result<()> {
    let s = &r.sample;
    if i64::try_from(r.seq).is_err() {
        bail!("sample seq {} is too large", r.seq);
    }
    if s.run == 0 {
        bail!("sample seq {}: run 0 (runs count from 1)", r.seq);
    }
    for (name, v) in [
        ("target_deg", s.target_deg),
        ("readout_deg", s.readout_deg),
        ("actual_deg", s.actual_deg),
    ] {
        if v.is_nan() {
            bail!("sample seq {}: {name} is NaN", r.seq);
        }
    }
    if s.timestamp_s.is_some_and(f64::is_nan) {
        bail!("sample seq {}: timestamp_s is NaN", r.seq);
    }
    Ok(())
}

async fn insert_samples(
    conn: &mut SqliteConnection,
    survey_id: i64,
    samples: &[RecordedSample],
) -> anyhow::Result<()> {
    // Checked up front so that the database is not touched by a bad batch.
    for r in samples {
        check_sample(r)?;
    }
    for chunk in samples.chunks(CHUNK_ROWS) {
        let mut qb: QueryBuilder<Sqlite> = QueryBuilder::new(
            "INSERT INTO samples (survey_id, seq, run, direction, target_deg, readout_deg, \
             actual_deg, timestamp_s) ",
        );
        qb.push_values(chunk, |mut b, r| {
            b.push_bind(survey_id)
                .push_bind(r.seq as i64) // checked above
                .push_bind(i64::from(r.sample.run))
                .push_bind(r.sample.direction.as_str())
                .push_bind(r.sample.target_deg)
                .push_bind(r.sample.readout_deg)
                .push_bind(r.sample.actual_deg)
                .push_bind(r.sample.timestamp_s);
        });
        qb.build().execute(&mut *conn).await.map_err(|e| {
            if is_foreign_key_error(&e) {
                NotFound(format!("no survey with id {survey_id}")).into()
            } else {
                anyhow::Error::new(e)
            }
        })?;

        let raws: Vec<&RecordedSample> = chunk
            .iter()
            .filter(|r| !matches!(r.raw, RawReading::None))
            .collect();
        if raws.is_empty() {
            continue;
        }
        let mut qb: QueryBuilder<Sqlite> = QueryBuilder::new(
            "INSERT INTO raw_readings (survey_id, seq, kind, smr_x_mm, smr_y_mm, smr_z_mm, \
             smr_sx_mm, smr_sy_mm, smr_sz_mm, measurement_time_s, ac_face, ac_x_arcsec, \
             ac_y_arcsec) ",
        );
        qb.push_values(raws, |mut b, r| {
            b.push_bind(survey_id).push_bind(r.seq as i64);
            match r.raw {
                RawReading::Smr(m) => {
                    b.push_bind("smr")
                        .push_bind(m.x_mm)
                        .push_bind(m.y_mm)
                        .push_bind(m.z_mm)
                        .push_bind(m.std_dev_mm[0])
                        .push_bind(m.std_dev_mm[1])
                        .push_bind(m.std_dev_mm[2])
                        .push_bind(m.measurement_time_s)
                        .push_bind(None::<i64>)
                        .push_bind(None::<f64>)
                        .push_bind(None::<f64>);
                }
                RawReading::Autocollimator { face, reading } => {
                    b.push_bind("autocollimator");
                    for _ in 0..7 {
                        b.push_bind(None::<f64>);
                    }
                    b.push_bind(i64::from(face))
                        .push_bind(reading.x_arcsec)
                        .push_bind(reading.y_arcsec);
                }
                RawReading::None => unreachable!("filtered out above"),
            }
        });
        qb.build().execute(&mut *conn).await?;
    }
    Ok(())
}

/// A nullable REAL column: NULL (how SQLite stores NaN) reads as NaN.
fn real(row: &SqliteRow, col: &str) -> anyhow::Result<f64> {
    let v: Option<f64> = row.try_get(col)?;
    Ok(v.unwrap_or(f64::NAN))
}

fn sample_from_row(row: &SqliteRow) -> anyhow::Result<RecordedSample> {
    let seq: i64 = row.try_get("seq")?;
    let run: i64 = row.try_get("run")?;
    let direction: String = row.try_get("direction")?;
    let sample = Sample {
        run: u32::try_from(run).with_context(|| format!("seq {seq}: bad run {run}"))?,
        direction: Direction::from_str(&direction).map_err(|e| anyhow!("seq {seq}: {e}"))?,
        target_deg: row.try_get("target_deg")?,
        readout_deg: row.try_get("readout_deg")?,
        actual_deg: row.try_get("actual_deg")?,
        timestamp_s: row.try_get("timestamp_s")?,
    };
    let kind: Option<String> = row.try_get("kind")?;
    let raw = match kind.as_deref() {
        None => RawReading::None,
        Some("smr") => RawReading::Smr(SmrMeasurement {
            x_mm: real(row, "smr_x_mm")?,
            y_mm: real(row, "smr_y_mm")?,
            z_mm: real(row, "smr_z_mm")?,
            std_dev_mm: [
                real(row, "smr_sx_mm")?,
                real(row, "smr_sy_mm")?,
                real(row, "smr_sz_mm")?,
            ],
            measurement_time_s: real(row, "measurement_time_s")?,
        }),
        Some("autocollimator") => {
            let face: i64 = row.try_get("ac_face")?;
            RawReading::Autocollimator {
                face: u32::try_from(face)
                    .with_context(|| format!("seq {seq}: bad polygon face {face}"))?,
                reading: AcReading {
                    x_arcsec: real(row, "ac_x_arcsec")?,
                    y_arcsec: real(row, "ac_y_arcsec")?,
                },
            }
        }
        Some(other) => bail!("seq {seq}: unknown raw reading kind '{other}'"),
    };
    Ok(RecordedSample {
        seq: u64::try_from(seq).with_context(|| format!("negative seq {seq}"))?,
        sample,
        raw,
    })
}

fn survey_from_row(row: &SqliteRow) -> anyhow::Result<SurveyRow> {
    let id: i64 = row.try_get("id")?;
    let status: String = row.try_get("status")?;
    let small = |col: &str| -> anyhow::Result<Option<u32>> {
        let v: Option<i64> = row.try_get(col)?;
        v.map(|v| u32::try_from(v).with_context(|| format!("survey {id}: bad {col} {v}")))
            .transpose()
    };
    let planned: Option<i64> = row.try_get("planned_samples")?;
    let count: i64 = row.try_get("sample_count")?;
    Ok(SurveyRow {
        id,
        created_at: row.try_get("created_at")?,
        updated_at: row.try_get("updated_at")?,
        status: SurveyStatus::from_str(&status).map_err(|e| anyhow!("survey {id}: {e}"))?,
        source: row.try_get("source")?,
        points: small("points")?,
        runs: small("runs")?,
        bidirectional: row.try_get("bidirectional")?,
        config_json: row.try_get("config_json")?,
        model_toml: row.try_get("model_toml")?,
        instruments_json: row.try_get("instruments_json")?,
        axis_json: row.try_get("axis_json")?,
        started_at_s: row.try_get("started_at_s")?,
        ended_at_s: row.try_get("ended_at_s")?,
        planned_samples: planned
            .map(|p| {
                u64::try_from(p).with_context(|| format!("survey {id}: bad planned_samples {p}"))
            })
            .transpose()?,
        sample_count: u64::try_from(count).unwrap_or(0),
    })
}

/// A [`SampleSink`] that writes to the store in batches.
///
/// `record` buffers the sample and writes the buffer (one [`Store::append`]
/// transaction) when
/// - it holds `batch` samples (default 256), or
/// - its oldest sample has waited `max_age` (default 1 s), or
/// - the previous sample was recorded `max_age` or more ago: samples come
///   slowly, so waiting for the next one would hold this one too long.
///
/// `max_age` is measured in real time ([`Instant`]), because durability is
/// about the real disk. A sample is acknowledged (durable) when a flush that
/// holds it returns `Ok`: on `flush()` or on the automatic flushes above. With
/// real instruments a sample takes seconds, so each one (from the second on)
/// is on disk as soon as it is recorded; a fast simulation writes in batches.
/// The sink has no timer of its own: the engine calls `flush()` before anything
/// that may wait (a fault recovery, a pause) and at the end.
///
/// When a write fails, the samples stay in the buffer (the transaction rolled
/// back, nothing of them is stored) and the next flush tries again.
#[derive(Debug)]
pub struct StoreSink {
    store: Store,
    survey_id: i64,
    batch: usize,
    max_age: Duration,
    buffer: Vec<RecordedSample>,
    oldest: Option<Instant>,
    last_record: Option<Instant>,
    acknowledged: Option<u64>,
}

impl StoreSink {
    /// Default number of samples per write.
    pub const DEFAULT_BATCH: usize = 256;
    /// Default longest time a sample waits in the buffer.
    pub const DEFAULT_MAX_AGE: Duration = Duration::from_secs(1);

    /// A sink writing the samples of survey `survey_id` into `store`.
    pub fn new(store: Store, survey_id: i64) -> Self {
        StoreSink {
            store,
            survey_id,
            batch: Self::DEFAULT_BATCH,
            max_age: Self::DEFAULT_MAX_AGE,
            buffer: Vec::new(),
            oldest: None,
            last_record: None,
            acknowledged: None,
        }
    }

    /// Write every `batch` samples (at least 1).
    pub fn with_batch(mut self, batch: usize) -> Self {
        self.batch = batch.max(1);
        self
    }

    /// Write when the oldest buffered sample has waited `max_age`.
    pub fn with_max_age(mut self, max_age: Duration) -> Self {
        self.max_age = max_age;
        self
    }

    /// The survey the samples go to.
    pub fn survey_id(&self) -> i64 {
        self.survey_id
    }

    /// The store.
    pub fn store(&self) -> &Store {
        &self.store
    }

    /// Samples recorded but not yet acknowledged.
    pub fn pending(&self) -> usize {
        self.buffer.len()
    }

    /// The highest seq this sink has acknowledged (written durably), if any.
    pub fn last_acknowledged(&self) -> Option<u64> {
        self.acknowledged
    }

    async fn write(&mut self) -> anyhow::Result<()> {
        if self.buffer.is_empty() {
            return Ok(());
        }
        self.store.append(self.survey_id, &self.buffer).await?;
        let top = self.buffer.iter().map(|r| r.seq).max();
        self.acknowledged = self.acknowledged.max(top);
        self.buffer.clear();
        self.oldest = None;
        Ok(())
    }
}

#[async_trait]
impl SampleSink for StoreSink {
    async fn record(&mut self, sample: RecordedSample) -> anyhow::Result<()> {
        let now = Instant::now();
        let slow = self
            .last_record
            .is_some_and(|t| now.duration_since(t) >= self.max_age);
        self.last_record = Some(now);
        self.buffer.push(sample);
        let oldest = *self.oldest.get_or_insert(now);
        if slow || self.buffer.len() >= self.batch || now.duration_since(oldest) >= self.max_age {
            self.write().await?;
        }
        Ok(())
    }

    async fn flush(&mut self) -> anyhow::Result<()> {
        self.write().await
    }

    /// Stores the positions after those already stored (a resume that locates
    /// the axis again adds its own) and replaces the survey's axis (JSON of
    /// the [`AxisFit`]).
    async fn axis_located(
        &mut self,
        points: &[(f64, SmrMeasurement)],
        fit: &AxisFit,
    ) -> anyhow::Result<()> {
        let json = serde_json::to_string(fit).context("cannot encode the located axis")?;
        self.store.add_locate_points(self.survey_id, points).await?;
        self.store.set_axis(self.survey_id, &json).await
    }

    /// Logged at once (not buffered).
    async fn event(&mut self, at_s: f64, level: &str, message: &str) -> anyhow::Result<()> {
        self.store
            .log_event(self.survey_id, at_s, level, message)
            .await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn new_survey() -> NewSurvey {
        NewSurvey {
            status: SurveyStatus::Running,
            source: "simulated".into(),
            points: Some(36),
            runs: Some(2),
            bidirectional: true,
            config_json: r#"{"points":36}"#.into(),
            model_toml: Some("[design]\n".into()),
            instruments_json: r#"["sim-positioner","sim-tracker"]"#.into(),
            planned_samples: Some(144),
        }
    }

    fn recorded(seq: u64) -> RecordedSample {
        let f = seq as f64;
        let raw = match seq % 3 {
            0 => RawReading::None,
            1 => RawReading::Smr(SmrMeasurement {
                x_mm: 100.0 + f * 1e-3,
                y_mm: -50.0 + f / 7.0,
                z_mm: 0.1 + 0.2,
                std_dev_mm: [1e-3, 2e-3, f64::NAN],
                measurement_time_s: 2.5,
            }),
            _ => RawReading::Autocollimator {
                face: (seq % 24) as u32,
                reading: AcReading {
                    x_arcsec: f / 3.0,
                    y_arcsec: -f / 11.0,
                },
            },
        };
        RecordedSample {
            seq,
            sample: Sample {
                run: 1 + (seq / 1000) as u32,
                direction: if seq.is_multiple_of(2) {
                    Direction::Forward
                } else {
                    Direction::Reverse
                },
                target_deg: f * 0.36,
                readout_deg: f * 0.36 + 1e-4 / (1.0 + f),
                actual_deg: f * 0.36 - 1.0 / 3.0 * 1e-5,
                timestamp_s: if seq.is_multiple_of(5) {
                    None
                } else {
                    Some(f * 1.25)
                },
            },
            raw,
        }
    }

    /// Equal bit for bit (NaN equal to NaN).
    fn assert_same(a: &[RecordedSample], b: &[RecordedSample]) {
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(b) {
            let (sx, sy) = (format!("{x:?}"), format!("{y:?}"));
            assert_eq!(sx, sy);
            assert_eq!(
                x.sample.readout_deg.to_bits(),
                y.sample.readout_deg.to_bits()
            );
            assert_eq!(x.sample.actual_deg.to_bits(), y.sample.actual_deg.to_bits());
        }
    }

    async fn temp_store() -> (tempfile::TempDir, Store) {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("survey.db")).await.unwrap();
        (dir, store)
    }

    #[tokio::test]
    async fn wal_mode_and_reopen() {
        let (dir, store) = temp_store().await;
        assert_eq!(store.journal_mode().await.unwrap(), "wal");
        let sync: i64 = sqlx::query_scalar("PRAGMA synchronous")
            .fetch_one(&store.pool)
            .await
            .unwrap();
        assert_eq!(sync, 2, "synchronous = FULL");
        let fk: i64 = sqlx::query_scalar("PRAGMA foreign_keys")
            .fetch_one(&store.pool)
            .await
            .unwrap();
        assert_eq!(fk, 1);
        let id = store.create_survey(&new_survey()).await.unwrap();
        store.close().await;
        // reopening runs the (already applied) migrations again without harm
        let store = Store::open_existing(&dir.path().join("survey.db"))
            .await
            .unwrap();
        assert_eq!(store.journal_mode().await.unwrap(), "wal");
        assert_eq!(store.latest_survey_id().await.unwrap(), Some(id));
        store.close().await;
    }

    #[tokio::test]
    async fn append_in_chunks_and_read_back() {
        let (_dir, store) = temp_store().await;
        let id = store.create_survey(&new_survey()).await.unwrap();
        let samples: Vec<RecordedSample> = (0..5000).map(recorded).collect();
        // 5000 rows x 8 values = 40000 > 32766: must be chunked
        store.append(id, &samples[..4500]).await.unwrap();
        store.append(id, &samples[4500..]).await.unwrap();
        let back = store.samples(id).await.unwrap();
        assert_same(&back, &samples);
        assert_eq!(store.last_seq(id).await.unwrap(), Some(4999));
        assert_eq!(store.survey(id).await.unwrap().sample_count, 5000);
        // another survey is independent
        let other = store.create_survey(&new_survey()).await.unwrap();
        assert!(store.samples(other).await.unwrap().is_empty());
        assert_eq!(store.last_seq(other).await.unwrap(), None);
        store.close().await;
    }

    #[tokio::test]
    async fn duplicate_seq_fails_and_stores_nothing_of_the_batch() {
        let (_dir, store) = temp_store().await;
        let id = store.create_survey(&new_survey()).await.unwrap();
        let first: Vec<RecordedSample> = (0..10).map(recorded).collect();
        store.append(id, &first).await.unwrap();
        // seq 10..1010 then 5 again (in the third chunk)
        let mut batch: Vec<RecordedSample> = (10..1010).map(recorded).collect();
        let mut dup = recorded(5);
        dup.sample.readout_deg = 99.0;
        batch.push(dup);
        let e = store.append(id, &batch).await.unwrap_err();
        assert!(!is_not_found(&e));
        assert!(
            format!("{e:#}").contains("UNIQUE constraint failed"),
            "{e:#}"
        );
        assert_same(&store.samples(id).await.unwrap(), &first);
        // unknown survey: a NotFound
        let e = store.append(999, &first).await.unwrap_err();
        assert!(is_not_found(&e), "{e:#}");
        store.close().await;
    }

    #[tokio::test]
    async fn negative_zero_and_extremes_survive_the_database() {
        let (_dir, store) = temp_store().await;
        let id = store.create_survey(&new_survey()).await.unwrap();
        let mut s = recorded(1);
        s.sample.target_deg = -0.0;
        s.sample.readout_deg = 5e-324;
        s.sample.actual_deg = f64::MAX;
        s.sample.timestamp_s = Some(f64::MIN_POSITIVE);
        store.append(id, &[s]).await.unwrap();
        let back = store.samples(id).await.unwrap();
        assert_eq!(back[0].sample.target_deg.to_bits(), (-0.0f64).to_bits());
        assert_same(&back, &[s]);
        let mut nan = recorded(2);
        nan.sample.actual_deg = f64::NAN;
        let e = store.append(id, &[nan]).await.unwrap_err();
        assert!(format!("{e:#}").contains("actual_deg is NaN"), "{e:#}");
        store.close().await;
    }

    #[tokio::test]
    async fn import_is_atomic() {
        let (_dir, store) = temp_store().await;
        let good: Vec<Sample> = (0..1000).map(|i| recorded(i).sample).collect();
        // a CHECK violation (run 0) at the end
        let mut bad = good.clone();
        bad[999].run = 0;
        let s = NewSurvey {
            status: SurveyStatus::Imported,
            source: "import:data.csv".into(),
            ..NewSurvey::default()
        };
        assert!(store.import(&s, &bad).await.is_err());
        assert!(store.list().await.unwrap().is_empty());
        // a failure inside SQLite in the third chunk
        sqlx::query(
            "CREATE TEMP TRIGGER boom BEFORE INSERT ON samples WHEN NEW.seq = 900 \
             BEGIN SELECT RAISE(ABORT, 'boom'); END",
        )
        .execute(&store.pool)
        .await
        .unwrap();
        let e = store.import(&s, &good).await.unwrap_err();
        assert!(format!("{e:#}").contains("boom"), "{e:#}");
        assert!(store.list().await.unwrap().is_empty());
        let n: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM samples")
            .fetch_one(&store.pool)
            .await
            .unwrap();
        assert_eq!(n, 0);
        sqlx::query("DROP TRIGGER boom")
            .execute(&store.pool)
            .await
            .unwrap();

        let id = store.import(&s, &good).await.unwrap();
        let row = store.survey(id).await.unwrap();
        assert_eq!(row.status, SurveyStatus::Imported);
        assert_eq!(row.source, "import:data.csv");
        assert_eq!(row.sample_count, 1000);
        let back: Vec<Sample> = store
            .samples(id)
            .await
            .unwrap()
            .iter()
            .map(|r| r.sample)
            .collect();
        assert_eq!(back, good);
        assert!(
            store
                .samples(id)
                .await
                .unwrap()
                .iter()
                .all(|r| r.raw == RawReading::None)
        );
        store.close().await;
    }

    #[tokio::test]
    async fn resolve_latest_and_not_found() {
        let (dir, store) = temp_store().await;
        let e = store.resolve(None).await.unwrap_err();
        assert!(is_not_found(&e));
        assert!(e.to_string().starts_with("no survey in "), "{e}");
        let a = store.create_survey(&new_survey()).await.unwrap();
        let b = store.create_survey(&new_survey()).await.unwrap();
        assert!(b > a);
        assert_eq!(store.resolve(None).await.unwrap().id, b);
        assert_eq!(store.resolve(Some(a)).await.unwrap().id, a);
        let e = store.resolve(Some(7)).await.unwrap_err();
        assert!(is_not_found(&e));
        assert!(e.downcast_ref::<NotFound>().is_some());
        assert_eq!(
            e.to_string(),
            format!(
                "no survey with id 7 in {}",
                dir.path().join("survey.db").display()
            )
        );
        assert!(is_not_found(
            &store
                .set_status(7, SurveyStatus::Failed, None)
                .await
                .unwrap_err()
        ));
        assert!(is_not_found(&store.set_axis(7, "{}").await.unwrap_err()));
        assert!(is_not_found(
            &store.log_event(7, 0.0, "info", "x").await.unwrap_err()
        ));
        let list = store.list().await.unwrap();
        assert_eq!(list.iter().map(|r| r.id).collect::<Vec<_>>(), vec![a, b]);
        store.close().await;
    }

    #[tokio::test]
    async fn survey_fields_status_axis_events_locate_points() {
        let (_dir, store) = temp_store().await;
        let id = store.create_survey(&new_survey()).await.unwrap();
        let row = store.survey(id).await.unwrap();
        assert_eq!(row.status, SurveyStatus::Running);
        assert_eq!(row.points, Some(36));
        assert_eq!(row.runs, Some(2));
        assert!(row.bidirectional);
        assert_eq!(row.planned_samples, Some(144));
        assert_eq!(row.model_toml.as_deref(), Some("[design]\n"));
        assert_eq!(row.axis_json, None);
        assert_eq!(row.ended_at_s, None);
        assert_eq!(row.sample_count, 0);
        assert!(
            row.created_at.ends_with('Z') && row.created_at.contains('T'),
            "{}",
            row.created_at
        );

        store.set_started(id, 0.5).await.unwrap();
        store.set_axis(id, r#"{"center":[0,0,0]}"#).await.unwrap();
        store
            .set_status(id, SurveyStatus::Interrupted, None)
            .await
            .unwrap();
        store
            .set_status(id, SurveyStatus::Complete, Some(3600.25))
            .await
            .unwrap();
        let row = store.survey(id).await.unwrap();
        assert_eq!(row.status, SurveyStatus::Complete);
        assert_eq!(row.started_at_s, Some(0.5));
        assert_eq!(row.ended_at_s, Some(3600.25));
        assert_eq!(row.axis_json.as_deref(), Some(r#"{"center":[0,0,0]}"#));

        store
            .log_event(id, 12.0, "warn", "beam broken, reacquired")
            .await
            .unwrap();
        store
            .log_event(id, 13.0, "info", "resumed at seq 40")
            .await
            .unwrap();
        let ev = store.events(id).await.unwrap();
        assert_eq!(ev.len(), 2);
        assert_eq!((ev[0].at_s, ev[0].level.as_str()), (12.0, "warn"));
        assert_eq!(ev[1].message, "resumed at seq 40");

        let m = |i: f64| SmrMeasurement {
            x_mm: i,
            y_mm: 2.0 * i,
            z_mm: -i,
            std_dev_mm: [0.001, 0.002, 0.003],
            measurement_time_s: 2.0,
        };
        store
            .add_locate_points(id, &[(0.0, m(1.0)), (120.0, m(2.0))])
            .await
            .unwrap();
        store
            .add_locate_points(id, &[(240.0, m(3.0))])
            .await
            .unwrap();
        let pts = store.locate_points(id).await.unwrap();
        assert_eq!(pts, vec![(0.0, m(1.0)), (120.0, m(2.0)), (240.0, m(3.0))]);

        for st in [
            SurveyStatus::Running,
            SurveyStatus::Interrupted,
            SurveyStatus::Complete,
            SurveyStatus::Failed,
            SurveyStatus::Imported,
        ] {
            assert_eq!(st.as_str().parse::<SurveyStatus>().unwrap(), st);
        }
        store.close().await;
    }

    #[tokio::test]
    async fn open_existing_does_not_create() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nothing.db");
        let e = Store::open_existing(&path).await.unwrap_err();
        assert!(is_not_found(&e));
        assert_eq!(
            e.to_string(),
            format!(
                "no survey database at {}: run `survey run` or `survey import` first",
                path.display()
            )
        );
        assert!(!path.exists());
        // a file that is not a database is a user error too
        let junk = dir.path().join("notes.txt");
        std::fs::write(&junk, "this is not a database, just some text that is long enough to be a header ......................................................").unwrap();
        let e = Store::open_existing(&junk).await.unwrap_err();
        assert!(is_not_found(&e), "{e:#}");
        assert!(e.to_string().contains("notes.txt"), "{e:#}");
        // open() names the path when it cannot create the file
        let e = Store::open(&dir.path().join("no/such/dir/x.db"))
            .await
            .unwrap_err();
        assert!(format!("{e:#}").contains("no/such/dir/x.db"), "{e:#}");
    }

    #[tokio::test]
    async fn store_sink_flushes_by_batch_and_on_flush() {
        let (_dir, store) = temp_store().await;
        let id = store.create_survey(&new_survey()).await.unwrap();
        let mut sink = StoreSink::new(store.clone(), id)
            .with_batch(10)
            .with_max_age(Duration::from_secs(60));
        for seq in 0..9 {
            sink.record(recorded(seq)).await.unwrap();
        }
        assert_eq!(store.last_seq(id).await.unwrap(), None);
        assert_eq!(sink.pending(), 9);
        sink.record(recorded(9)).await.unwrap();
        assert_eq!(store.last_seq(id).await.unwrap(), Some(9));
        assert_eq!(sink.pending(), 0);
        assert_eq!(sink.last_acknowledged(), Some(9));
        for seq in 10..13 {
            sink.record(recorded(seq)).await.unwrap();
        }
        assert_eq!(store.last_seq(id).await.unwrap(), Some(9));
        sink.flush().await.unwrap();
        assert_eq!(store.last_seq(id).await.unwrap(), Some(12));
        sink.flush().await.unwrap(); // nothing to write
        let expected: Vec<RecordedSample> = (0..13).map(recorded).collect();
        assert_same(&store.samples(id).await.unwrap(), &expected);
        store.close().await;
    }

    #[tokio::test]
    async fn store_sink_flushes_by_age_and_keeps_failed_batches() {
        let (_dir, store) = temp_store().await;
        let id = store.create_survey(&new_survey()).await.unwrap();
        let mut sink = StoreSink::new(store.clone(), id).with_max_age(Duration::from_millis(300));
        sink.record(recorded(0)).await.unwrap();
        sink.record(recorded(1)).await.unwrap();
        assert_eq!(store.last_seq(id).await.unwrap(), None);
        tokio::time::sleep(Duration::from_millis(350)).await;
        // the oldest has waited more than max_age
        sink.record(recorded(2)).await.unwrap();
        assert_eq!(store.last_seq(id).await.unwrap(), Some(2));
        // slow samples (more than max_age apart) are written as they come
        tokio::time::sleep(Duration::from_millis(350)).await;
        sink.record(recorded(3)).await.unwrap();
        assert_eq!(store.last_seq(id).await.unwrap(), Some(3));

        // events and the located axis go straight to the store
        sink.event(4.5, "warn", "beam broken").await.unwrap();
        let m = SmrMeasurement {
            x_mm: 1.0,
            y_mm: 2.0,
            z_mm: 3.0,
            std_dev_mm: [0.01; 3],
            measurement_time_s: 2.0,
        };
        let fit = AxisFit {
            center_mm: [0.0, 0.0, 0.0],
            normal: [0.0, 0.0, 1.0],
            u: [1.0, 0.0, 0.0],
            v: [0.0, 1.0, 0.0],
            radius_mm: 250.0,
            zero_offset_deg: 0.5,
            plane_rms_mm: 0.001,
            circle_rms_mm: 0.002,
            points: 3,
        };
        let pts = [(0.0, m), (120.0, m), (240.0, m)];
        sink.axis_located(&pts, &fit).await.unwrap();
        assert_eq!(store.locate_points(id).await.unwrap(), pts.to_vec());
        let axis: AxisFit =
            serde_json::from_str(&store.survey(id).await.unwrap().axis_json.unwrap()).unwrap();
        assert_eq!(axis, fit);
        assert_eq!(store.events(id).await.unwrap()[0].message, "beam broken");

        // a failing write keeps the samples for the next try
        sink.record(recorded(1)).await.unwrap(); // a duplicate seq, buffered
        sink.flush().await.unwrap_err();
        assert_eq!(sink.pending(), 1);
        assert_eq!(sink.last_acknowledged(), Some(3));
        store.close().await;
    }
}
