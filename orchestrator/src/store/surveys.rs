//! The surveys: creating one, its status, axis, locate points and event log,
//! and looking surveys up.

use std::fmt;
use std::str::FromStr;

use anyhow::{Context, anyhow};
use serde::{Deserialize, Serialize};
use sqlx::sqlite::{SqliteConnection, SqliteRow};
use sqlx::{QueryBuilder, Row, Sqlite};
use survey_drivers::SmrMeasurement;

use super::{CHUNK_ROWS, NotFound, Store, real};

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

const SURVEY_COLUMNS: &str = "SELECT s.id, s.created_at, s.updated_at, s.status, s.source, \
     s.points, s.runs, s.bidirectional, s.config_json, s.model_toml, s.instruments_json, \
     s.axis_json, s.started_at_s, s.ended_at_s, s.planned_samples, \
     (SELECT COUNT(*) FROM samples AS c WHERE c.survey_id = s.id) AS sample_count \
     FROM surveys AS s";

impl Store {
    /// Store a new survey; returns its id.
    pub async fn create_survey(&self, s: &NewSurvey) -> anyhow::Result<i64> {
        let mut conn = self.pool.acquire().await?;
        let id = insert_survey(&mut conn, s)
            .await
            .with_context(|| format!("cannot store a new survey in {}", self.path.display()))?;
        Ok(id)
    }

    /// Set a survey's status and, when given, the instrument time it ended.
    /// A [`NotFound`] error when there is no such survey.
    pub async fn set_status(&self, id: i64, status: SurveyStatus, ended_at_s: Option<f64>) -> anyhow::Result<()> {
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
    pub async fn add_locate_points(&self, id: i64, points: &[(f64, SmrMeasurement)]) -> anyhow::Result<()> {
        if points.is_empty() {
            return Ok(());
        }
        let mut tx = self.pool.begin().await?;
        let next: i64 = sqlx::query_scalar("SELECT COALESCE(MAX(idx) + 1, 0) FROM locate_points WHERE survey_id = ?")
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
                self.fk_to_not_found(id, e).context(format!("cannot store the locate points of survey {id}"))
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
    pub async fn log_event(&self, id: i64, at_s: f64, level: &str, message: &str) -> anyhow::Result<()> {
        sqlx::query("INSERT INTO events (survey_id, at_s, level, message) VALUES (?, ?, ?, ?)")
            .bind(id)
            .bind(at_s)
            .bind(level)
            .bind(message)
            .execute(&self.pool)
            .await
            .map_err(|e| self.fk_to_not_found(id, e).context(format!("cannot log an event of survey {id}")))?;
        Ok(())
    }

    /// A survey's events, in the order they were logged.
    pub async fn events(&self, id: i64) -> anyhow::Result<Vec<EventRow>> {
        let rows = sqlx::query("SELECT id, at_s, level, message FROM events WHERE survey_id = ? ORDER BY id")
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
        let id: Option<i64> = sqlx::query_scalar("SELECT MAX(id) FROM surveys").fetch_one(&self.pool).await?;
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
}

pub(super) async fn insert_survey(conn: &mut SqliteConnection, s: &NewSurvey) -> anyhow::Result<i64> {
    let planned = s.planned_samples.map(i64::try_from).transpose().context("planned_samples is too large")?;
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

fn survey_from_row(row: &SqliteRow) -> anyhow::Result<SurveyRow> {
    let id: i64 = row.try_get("id")?;
    let status: String = row.try_get("status")?;
    let small = |col: &str| -> anyhow::Result<Option<u32>> {
        let v: Option<i64> = row.try_get(col)?;
        v.map(|v| u32::try_from(v).with_context(|| format!("survey {id}: bad {col} {v}"))).transpose()
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
            .map(|p| u64::try_from(p).with_context(|| format!("survey {id}: bad planned_samples {p}")))
            .transpose()?,
        sample_count: u64::try_from(count).unwrap_or(0),
    })
}
