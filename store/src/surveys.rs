//! The surveys: creating one, its status, axis, locate points and event log,
//! and looking surveys up.

use anyhow::Context;
use serde::Serialize;
use sqlx::sqlite::SqliteConnection;
use sqlx::{QueryBuilder, Row, Sqlite};
use survey_drivers::SmrMeasurement;
use survey_processing::geometry::AxisFit;

use super::tx::WriteTx;
use super::{AcquirerLock, Backend, CHUNK_ROWS, NotFound, Store, on_pool, real};
use crate::survey::{NewSurvey, StoredColumns, SurveyRecord, SurveyRef, SurveyStatus};

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

/// The query of surveys, `$tail` (a `WHERE`, an `ORDER BY`) appended: the
/// same text on either backend. Each survey's sample count is a `COUNT(*)`
/// over its samples (a walk of every row), or with `uncounted;` first, 0 (a
/// BIGINT, as the count is on PostgreSQL).
macro_rules! select_surveys {
    ($tail:literal) => {
        select_surveys!("(SELECT COUNT(*) FROM samples AS c WHERE c.survey_id = s.id)", $tail)
    };
    (uncounted; $tail:literal) => {
        select_surveys!("CAST(0 AS BIGINT)", $tail)
    };
    ($count:literal, $tail:literal) => {
        concat!(
            "SELECT s.id, s.uid, s.asset, s.check_of, s.created_at, s.updated_at, s.status, s.source, \
             s.points, s.runs, s.bidirectional, s.config_json, s.model_toml, s.instruments_json, \
             s.axis_json, s.started_at_s, s.ended_at_s, s.planned_samples, ",
            $count,
            " AS sample_count FROM surveys AS s",
            $tail
        )
    };
}

/// The stored columns of the survey rows `rows` (of either backend), unparsed.
macro_rules! columns_of {
    ($rows:expr) => {
        $rows.iter().map(|row| columns_from_row!(row)).collect::<anyhow::Result<Vec<StoredColumns>>>()
    };
}

/// The stored columns of a survey row (of either backend), unparsed (see
/// [`SurveyRecord::parse`]).
macro_rules! columns_from_row {
    ($row:expr) => {
        (|| -> anyhow::Result<StoredColumns> {
            let row = $row;
            let id: i64 = row.try_get("id")?;
            let small = |col: &str| -> anyhow::Result<Option<u32>> {
                let v: Option<i64> = row.try_get(col)?;
                v.map(|v| u32::try_from(v).with_context(|| format!("survey {id}: bad {col} {v}"))).transpose()
            };
            let planned: Option<i64> = row.try_get("planned_samples")?;
            let count: i64 = row.try_get("sample_count")?;
            Ok(StoredColumns {
                id,
                uid: row.try_get("uid")?,
                asset: row.try_get("asset")?,
                check_of: row.try_get("check_of")?,
                created_at: row.try_get("created_at")?,
                updated_at: row.try_get("updated_at")?,
                status: row.try_get("status")?,
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
                    .map(|p| u64::try_from(p).with_context(|| format!("survey {id}: bad planned_samples {p}")))
                    .transpose()?,
                sample_count: u64::try_from(count).unwrap_or(0),
            })
        })()
    };
}

impl Store {
    /// Store a new survey; returns its id.
    pub async fn create_survey(&self, s: &NewSurvey) -> anyhow::Result<i64> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let id = insert_survey(tx.conn(), s)
            .await
            .with_context(|| format!("cannot store a new survey in {}", self.path.display()))?;
        tx.commit().await.with_context(|| format!("cannot store a new survey in {}", self.path.display()))?;
        Ok(id)
    }

    /// Store a new survey to be acquired by this process, and take its
    /// acquisition lock before the survey is visible to any other connection
    /// (the lock is taken inside the transaction that inserts it), so no
    /// `resume` can ever see the survey unlocked while this process acquires it.
    pub async fn create_acquired_survey(&self, s: &NewSurvey) -> anyhow::Result<(i64, AcquirerLock)> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let id = insert_survey(tx.conn(), s)
            .await
            .with_context(|| format!("cannot store a new survey in {}", self.path.display()))?;
        let lock = AcquirerLock::acquire(&self.path, id)?;
        tx.commit().await.with_context(|| format!("cannot store a new survey in {}", self.path.display()))?;
        Ok((id, lock))
    }

    /// Date a survey made on a virtual clock (a simulated year of checks):
    /// its `created_at` (which the intervals read) set to `at`, in whole
    /// seconds as the store writes it. A [`NotFound`] error when there is
    /// no such survey. Surveys made on the wall clock are dated by the store.
    pub async fn set_created_at(&self, id: i64, at: std::time::SystemTime) -> anyhow::Result<()> {
        let created_at = humantime::format_rfc3339_seconds(at).to_string();
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let done = sqlx::query("UPDATE surveys SET created_at = ? WHERE id = ?")
            .bind(&created_at)
            .bind(id)
            .execute(tx.conn())
            .await?;
        if done.rows_affected() == 0 {
            tx.abort().await;
            return Err(self.no_survey(id).into());
        }
        tx.commit().await?;
        Ok(())
    }

    /// Set a survey's status and, when given, the instrument time it ended.
    /// A [`NotFound`] error when there is no such survey.
    ///
    /// On a full disk, the space the survey's acquisition lock keeps for
    /// this write ([`crate::RESERVE_BYTES`]) is given back and the write
    /// tried once more: a survey stopped by a full disk is stored as what
    /// it is, not left `running`.
    pub async fn set_status(&self, id: i64, status: SurveyStatus, ended_at_s: Option<f64>) -> anyhow::Result<()> {
        match self.write_status(id, status, ended_at_s).await {
            Err(e) if is_full(&e) => {
                // The failed write's connection is being closed (in the
                // background): were it the last one, its close would
                // checkpoint the log into the database file and take the
                // space given back. A reader held open meanwhile keeps it
                // from being the last.
                let guard =
                    rusqlite::Connection::open_with_flags(&self.path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
                        .and_then(|c| c.query_row("SELECT COUNT(*) FROM sqlite_master", [], |_| Ok(())).map(|()| c));
                if !crate::lock::release_reserve(&self.path, id) {
                    return Err(e);
                }
                tracing::warn!(survey = id, error = %crate::error::said(&e), "the disk is full: the status is written into the reserve");
                let written = self.write_status(id, status, ended_at_s).await;
                drop(guard);
                written
            }
            other => other,
        }
    }

    /// [`Store::set_status`] without the reserve (tests of a full disk).
    pub(crate) async fn write_status(
        &self,
        id: i64,
        status: SurveyStatus,
        ended_at_s: Option<f64>,
    ) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let done = sqlx::query(
            "UPDATE surveys SET status = ?, ended_at_s = COALESCE(?, ended_at_s), \
             updated_at = strftime('%Y-%m-%dT%H:%M:%SZ', 'now') WHERE id = ?",
        )
        .bind(status.as_str())
        .bind(ended_at_s)
        .bind(id)
        .execute(tx.conn())
        .await?;
        if done.rows_affected() == 0 {
            tx.abort().await;
            return Err(self.no_survey(id).into());
        }
        tx.commit().await?;
        // The acquisition is whole: the samples are packed for the reads.
        if matches!(status, SurveyStatus::Processing | SurveyStatus::Complete | SurveyStatus::Imported) {
            self.pack(id).await;
        }
        Ok(())
    }

    /// Set the instrument time at which acquisition started.
    pub async fn set_started(&self, id: i64, started_at_s: f64) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let done = sqlx::query(
            "UPDATE surveys SET started_at_s = ?, \
             updated_at = strftime('%Y-%m-%dT%H:%M:%SZ', 'now') WHERE id = ?",
        )
        .bind(started_at_s)
        .bind(id)
        .execute(tx.conn())
        .await?;
        if done.rows_affected() == 0 {
            tx.abort().await;
            return Err(self.no_survey(id).into());
        }
        tx.commit().await?;
        Ok(())
    }

    /// Store the located axis.
    pub async fn set_axis(&self, id: i64, axis: &AxisFit) -> anyhow::Result<()> {
        let axis_json = serde_json::to_string(axis).context("cannot encode the located axis")?;
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let done = sqlx::query(
            "UPDATE surveys SET axis_json = ?, \
             updated_at = strftime('%Y-%m-%dT%H:%M:%SZ', 'now') WHERE id = ?",
        )
        .bind(axis_json)
        .bind(id)
        .execute(tx.conn())
        .await?;
        if done.rows_affected() == 0 {
            tx.abort().await;
            return Err(self.no_survey(id).into());
        }
        tx.commit().await?;
        Ok(())
    }

    /// Add SMR positions measured to locate the axis, `(readout_deg,
    /// measurement)`, after those already stored for the survey (one transaction).
    pub async fn add_locate_points(&self, id: i64, points: &[(f64, SmrMeasurement)]) -> anyhow::Result<()> {
        if points.is_empty() {
            return Ok(());
        }
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let next: i64 = sqlx::query_scalar("SELECT COALESCE(MAX(idx) + 1, 0) FROM locate_points WHERE survey_id = ?")
            .bind(id)
            .fetch_one(tx.conn())
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
            qb.build().execute(tx.conn()).await.map_err(|e| {
                self.fk_to_not_found(id, e).context(format!("cannot store the locate points of survey {id}"))
            })?;
        }
        tx.commit().await?;
        Ok(())
    }

    /// The SMR positions that located the axis, in the order they were stored.
    /// A coordinate SQLite held as NULL (the instrument gave NaN) reads as NaN.
    pub async fn locate_points(&self, id: i64) -> anyhow::Result<Vec<(f64, SmrMeasurement)>> {
        on_pool!(self, |pool| {
            let rows = sqlx::query(
                "SELECT readout_deg, x_mm, y_mm, z_mm, sx, sy, sz, measurement_time_s \
                 FROM locate_points WHERE survey_id = $1 ORDER BY idx",
            )
            .bind(id)
            .fetch_all(pool)
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
                            // The air is read by `Store::environment`, not with the samples.
                            environment: None,
                        },
                    ))
                })
                .collect()
        })
    }

    /// Log an event (a fault survived, a resume) at instrument time `at_s`.
    /// `level` is free text; the engine uses `info`, `warn` and `error`.
    pub async fn log_event(&self, id: i64, at_s: f64, level: &str, message: &str) -> anyhow::Result<()> {
        let context = || format!("cannot log an event of survey {id}");
        let mut tx = WriteTx::begin(self.sqlite()?).await.with_context(context)?;
        self.insert_event(&mut tx, id, at_s, level, message).await.with_context(context)?;
        tx.commit().await.with_context(context)?;
        Ok(())
    }

    /// One event of survey `id` in `tx` (a survey that is not there: [`NotFound`](crate::NotFound)).
    async fn insert_event(
        &self,
        tx: &mut WriteTx,
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
            .execute(tx.conn())
            .await
            .map_err(|e| self.fk_to_not_found(id, e))?;
        Ok(())
    }

    /// Store a survey's setup with new transport addresses (`resume
    /// --config`: see `config::readdress`) and the event that says which,
    /// in one transaction: a later resume uses the new addresses, and the
    /// events keep the old ones.
    pub async fn readdress(
        &self,
        id: i64,
        setup: &crate::survey::Setup,
        at_s: f64,
        message: &str,
    ) -> anyhow::Result<()> {
        let context = || format!("cannot store the new addresses of survey {id}");
        let mut tx = WriteTx::begin(self.sqlite()?).await.with_context(context)?;
        sqlx::query("UPDATE surveys SET config_json = ? WHERE id = ?")
            .bind(setup.to_column())
            .bind(id)
            .execute(tx.conn())
            .await
            .with_context(context)?;
        self.insert_event(&mut tx, id, at_s, "info", message).await.with_context(context)?;
        tx.commit().await.with_context(context)?;
        Ok(())
    }

    /// A survey's events, in the order they were logged.
    pub async fn events(&self, id: i64) -> anyhow::Result<Vec<EventRow>> {
        on_pool!(self, |pool| {
            let rows = sqlx::query("SELECT id, at_s, level, message FROM events WHERE survey_id = $1 ORDER BY id")
                .bind(id)
                .fetch_all(pool)
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
        })
    }

    /// One survey. A [`NotFound`] error (`no survey with id 7 in survey.db`)
    /// when there is none with that id.
    pub async fn survey(&self, id: i64) -> anyhow::Result<SurveyRecord> {
        self.survey_counted(id, true).await
    }

    /// [`Store::survey`], its sample count left 0 unless `counted`.
    async fn survey_counted(&self, id: i64, counted: bool) -> anyhow::Result<SurveyRecord> {
        let query = match counted {
            true => select_surveys!(" WHERE s.id = $1"),
            false => select_surveys!(uncounted; " WHERE s.id = $1"),
        };
        let columns = on_pool!(self, |pool| {
            let rows = sqlx::query(query).bind(id).fetch_all(pool).await?;
            columns_of!(rows)?
        });
        match columns.into_iter().next() {
            Some(c) => self.shown(self.record(c)?).await,
            None => Err(self.no_survey(id).into()),
        }
    }

    /// The id of the latest survey (the highest id), if any.
    pub async fn latest_survey_id(&self) -> anyhow::Result<Option<i64>> {
        let id: Option<i64> =
            on_pool!(self, |pool| sqlx::query_scalar("SELECT MAX(id) FROM surveys").fetch_one(pool).await?);
        Ok(id)
    }

    /// The survey with this uid. A [`NotFound`] error when there is none.
    pub async fn survey_by_uid(&self, uid: &str) -> anyhow::Result<SurveyRecord> {
        self.survey_by_uid_counted(uid, true).await
    }

    /// [`Store::survey_by_uid`], its sample count left 0 unless `counted`.
    async fn survey_by_uid_counted(&self, uid: &str, counted: bool) -> anyhow::Result<SurveyRecord> {
        let uid = uid.to_ascii_lowercase();
        let query = match counted {
            true => select_surveys!(" WHERE s.uid = $1"),
            false => select_surveys!(uncounted; " WHERE s.uid = $1"),
        };
        let columns = on_pool!(self, |pool| {
            let rows = sqlx::query(query).bind(&uid).fetch_all(pool).await?;
            columns_of!(rows)?
        });
        match columns.into_iter().next() {
            Some(c) => self.shown(self.record(c)?).await,
            None => Err(NotFound(format!("no survey with uid {uid} in {}", self.path.display())).into()),
        }
    }

    /// The survey named by `r` (an id or a uid), or the latest one when `r`
    /// is `None`. A [`NotFound`] error when that survey does not exist or the
    /// database holds none. The latest is the latest survey that is not check
    /// points (source `resolving`: they are part of the survey they resolve,
    /// which [`Store::check_points`] reads): `survey run` then
    /// `survey process` processes the survey, not its check points.
    pub async fn resolve(&self, r: Option<SurveyRef>) -> anyhow::Result<SurveyRecord> {
        self.resolve_counted(r, true).await
    }

    /// [`Store::resolve`] with the survey's `sample_count` left 0: for a
    /// caller that reads every sample anyway and counts them as it does
    /// (`survey_lab::load`), so that the samples are not walked twice.
    pub async fn resolve_uncounted(&self, r: Option<SurveyRef>) -> anyhow::Result<SurveyRecord> {
        self.resolve_counted(r, false).await
    }

    async fn resolve_counted(&self, r: Option<SurveyRef>, counted: bool) -> anyhow::Result<SurveyRecord> {
        let latest = on_pool!(self, |pool| {
            sqlx::query_scalar("SELECT MAX(id) FROM surveys WHERE source <> 'resolving'").fetch_one(pool).await?
        });
        self.resolve_with(r, latest, counted).await
    }

    /// [`Store::resolve`] with check points included in "the latest" (what
    /// `survey resume` finishes).
    pub async fn resolve_any(&self, r: Option<SurveyRef>) -> anyhow::Result<SurveyRecord> {
        let latest = self.latest_survey_id().await?;
        self.resolve_with(r, latest, true).await
    }

    async fn resolve_with(
        &self,
        r: Option<SurveyRef>,
        latest: Option<i64>,
        counted: bool,
    ) -> anyhow::Result<SurveyRecord> {
        match r {
            Some(SurveyRef::Id(id)) => self.survey_counted(id, counted).await,
            Some(SurveyRef::Uid(uid)) => self.survey_by_uid_counted(&uid, counted).await,
            None => match latest {
                Some(id) => self.survey_counted(id, counted).await,
                None => Err(NotFound(format!(
                    "no survey in {}: run `survey run` or `survey import` first",
                    self.path.display()
                ))
                .into()),
            },
        }
    }

    /// Every survey, oldest first.
    pub async fn list(&self) -> anyhow::Result<Vec<SurveyRecord>> {
        self.list_counted(true).await
    }

    /// [`Store::list`] with every `sample_count` left 0: no walk of every
    /// sample of the store (what `survey serve`'s `/` needs of the surveys).
    pub async fn list_uncounted(&self) -> anyhow::Result<Vec<SurveyRecord>> {
        self.list_counted(false).await
    }

    async fn list_counted(&self, counted: bool) -> anyhow::Result<Vec<SurveyRecord>> {
        let query = match counted {
            true => select_surveys!(" ORDER BY s.id"),
            false => select_surveys!(uncounted; " ORDER BY s.id"),
        };
        let columns = on_pool!(self, |pool| {
            let rows = sqlx::query(query).fetch_all(pool).await?;
            columns_of!(rows)?
        });
        self.records(columns).await
    }

    /// The surveys of an asset, in the order they were made (oldest first).
    pub async fn surveys_of_asset(&self, asset: &str) -> anyhow::Result<Vec<SurveyRecord>> {
        self.surveys_of_asset_counted(asset, true).await
    }

    /// [`Store::surveys_of_asset`] with every `sample_count` left 0: no walk
    /// of the asset's samples (the history counts a survey's samples as it
    /// measures it, or reads the count it kept).
    pub async fn surveys_of_asset_uncounted(&self, asset: &str) -> anyhow::Result<Vec<SurveyRecord>> {
        self.surveys_of_asset_counted(asset, false).await
    }

    async fn surveys_of_asset_counted(&self, asset: &str, counted: bool) -> anyhow::Result<Vec<SurveyRecord>> {
        let query = match counted {
            true => select_surveys!(" WHERE s.asset = $1 ORDER BY s.created_at, s.id"),
            false => select_surveys!(uncounted; " WHERE s.asset = $1 ORDER BY s.created_at, s.id"),
        };
        let columns = on_pool!(self, |pool| {
            let rows = sqlx::query(query).bind(asset).fetch_all(pool).await?;
            columns_of!(rows)?
        });
        self.records(columns).await
    }

    /// The surveys being acquired (stored as `running`, and a live process
    /// holds their acquisition lock: [`Store::shown`]), oldest first, each
    /// with its samples counted: what `survey serve`'s live paths poll,
    /// without reading (or counting the samples of) every other survey.
    pub async fn running(&self) -> anyhow::Result<Vec<SurveyRecord>> {
        let columns = on_pool!(self, |pool| {
            let rows =
                sqlx::query(select_surveys!(" WHERE s.status = 'running' ORDER BY s.id")).fetch_all(pool).await?;
            columns_of!(rows)?
        });
        let mut live = self.records(columns).await?;
        live.retain(|r| r.status == SurveyStatus::Running);
        Ok(live)
    }

    /// Records of the columns `columns`, each as readers must show it ([`Store::shown`]).
    async fn records(&self, columns: Vec<StoredColumns>) -> anyhow::Result<Vec<SurveyRecord>> {
        let mut out = Vec::with_capacity(columns.len());
        for c in columns {
            out.push(self.shown(self.record(c)?).await?);
        }
        Ok(out)
    }

    /// The survey `record` as every reader must show it (`list`, `show`,
    /// `history`, the pages): a survey stored as `running` that no live
    /// process acquires (its acquisition lock is free: [`crate::is_held`])
    /// is `interrupted`, whatever killed its acquirer (a kill, a crash, a
    /// power loss, a disk too full to store the status). The one place this
    /// is decided: every look-up of surveys goes through it.
    ///
    /// The lock is asked about without being taken, so no acquirer is ever
    /// refused for it. An acquisition that ends between the read of the row
    /// and the question (its lock released, its final status stored) is
    /// caught by reading the status again: a free lock and a stored `running`
    /// together mean the acquirer is gone. Where the question cannot be
    /// answered (the lock file cannot be opened), the stored status is
    /// shown. The lab store holds only complete surveys (`survey push`):
    /// its statuses are shown as stored.
    pub async fn shown(&self, mut record: SurveyRecord) -> anyhow::Result<SurveyRecord> {
        let Backend::Sqlite(pool) = &self.backend else { return Ok(record) };
        if record.status != SurveyStatus::Running || crate::is_held(&self.path, record.id) != Some(false) {
            return Ok(record);
        }
        let now: Option<String> =
            sqlx::query_scalar("SELECT status FROM surveys WHERE id = ?").bind(record.id).fetch_optional(pool).await?;
        record.status = match now.as_deref().and_then(SurveyStatus::from_column) {
            Some(SurveyStatus::Running) | None => SurveyStatus::Interrupted,
            Some(other) => other,
        };
        Ok(record)
    }

    /// A survey's columns, typed (see [`crate::survey`]): a column that does
    /// not parse is a [`crate::survey::Damaged`] error.
    fn record(&self, columns: StoredColumns) -> anyhow::Result<SurveyRecord> {
        Ok(SurveyRecord::parse(columns, &self.path.display().to_string())?)
    }
}

/// The disk (or the database's page limit) is full: `SQLITE_FULL` anywhere
/// in the chain, or an I/O error of no space left.
fn is_full(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<sqlx::Error>().and_then(super::sqlite_code).is_some_and(|code| code & 0xff == 13)
            || c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::StorageFull)
    })
}

pub(super) async fn insert_survey(conn: &mut SqliteConnection, s: &NewSurvey) -> anyhow::Result<i64> {
    let planned = s.planned_samples.map(i64::try_from).transpose().context("planned_samples is too large")?;
    let done = sqlx::query(
        "INSERT INTO surveys (uid, asset, check_of, status, source, points, runs, bidirectional, config_json, \
         model_toml, instruments_json, planned_samples) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
    )
    .bind(crate::survey::new_uid())
    .bind(&s.asset)
    .bind(&s.check_of)
    .bind(s.status.as_str())
    .bind(s.source.to_column())
    .bind(s.points.map(i64::from))
    .bind(s.runs.map(i64::from))
    .bind(s.bidirectional)
    .bind(s.setup.to_column())
    .bind(s.model.as_ref().map(|m| m.to_toml()))
    .bind(s.instruments_column())
    .bind(planned)
    .execute(&mut *conn)
    .await?;
    Ok(done.last_insert_rowid())
}
