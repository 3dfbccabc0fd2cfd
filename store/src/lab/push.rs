//! `survey push`: complete surveys copied from a station's SQLite file into
//! the lab store, each exactly once by its uid, each in one transaction (all
//! of it or nothing: a push killed midway leaves nothing of the survey it was
//! copying, and the next push copies it). The uid is unique in the lab store:
//! a survey already there is not copied again (pushing again stores nothing
//! new), and two pushes of one survey at once store it once (the second
//! insert of its row waits for the first transaction and then finds it).
//!
//! Every column is copied as stored (an f64 bit for bit), the survey's rows
//! keyed by its id in the lab store. A verification names the survey it
//! verifies by that survey's id, so the verified survey is copied first and
//! the verification is rewritten to its lab id; a check's recalibration,
//! copied after the check, completes the check's row there.

use super::super::tx::WriteTx;
use super::super::{Backend, Store};
use crate::error::bad_input;
use crate::survey::{SurveyRecord, SurveyRef, SurveySource};
use serde::Serialize;
use sqlx::{AssertSqlSafe, PgPool, Postgres, QueryBuilder, Row, SqlitePool};

/// For tests only: with this variable set to `k`, the process aborts (as a
/// killed push does) with the `k`-th survey it copies written but not committed.
const ABORT_AT: &str = "SURVEY_TEST_PUSH_ABORT_AT";

/// Which surveys to push.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Which {
    /// The latest survey.
    Latest,
    /// One survey (an id or a uid of the station's file).
    One(SurveyRef),
    /// Every complete survey.
    All,
}

/// What a push did, by uid.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct PushReport {
    /// Copied now.
    pub pushed: Vec<String>,
    /// In the lab store already (copied before, by this station or another push).
    pub already: Vec<String>,
    /// Not complete (running, interrupted, failed): not pushed.
    pub not_complete: Vec<String>,
}

/// How a column is read and written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Int,
    Real,
    Text,
    Bool,
    Blob,
}

/// A value as stored.
#[derive(Debug, Clone, PartialEq)]
enum Cell {
    Int(Option<i64>),
    Real(Option<f64>),
    Text(Option<String>),
    Bool(Option<bool>),
    Blob(Option<Vec<u8>>),
}

/// A table of a survey: its columns besides the survey's key, and the order
/// its rows are copied in.
struct Table {
    name: &'static str,
    columns: &'static [(&'static str, Kind)],
    order: &'static str,
}

use Kind::{Blob, Bool, Int, Real, Text};

/// The survey's own row (keyed by `id`, which the lab store assigns).
const SURVEY: Table = Table {
    name: "surveys",
    columns: &[
        ("uid", Text),
        ("asset", Text),
        ("check_of", Text),
        ("created_at", Text),
        ("updated_at", Text),
        ("status", Text),
        ("source", Text),
        ("points", Int),
        ("runs", Int),
        ("bidirectional", Bool),
        ("config_json", Text),
        ("model_toml", Text),
        ("instruments_json", Text),
        ("axis_json", Text),
        ("started_at_s", Real),
        ("ended_at_s", Real),
        ("planned_samples", Int),
    ],
    order: "id",
};

/// The survey's rows in the other tables (keyed by `survey_id`), parents
/// before children.
const ROWS: &[Table] = &[
    Table {
        name: "samples",
        columns: &[
            ("seq", Int),
            ("run", Int),
            ("direction", Text),
            ("target_deg", Real),
            ("readout_deg", Real),
            ("actual_deg", Real),
            ("timestamp_s", Real),
        ],
        order: "seq",
    },
    Table {
        name: "raw_readings",
        columns: &[
            ("seq", Int),
            ("kind", Text),
            ("smr_x_mm", Real),
            ("smr_y_mm", Real),
            ("smr_z_mm", Real),
            ("smr_sx_mm", Real),
            ("smr_sy_mm", Real),
            ("smr_sz_mm", Real),
            ("measurement_time_s", Real),
            ("ac_face", Int),
            ("ac_x_arcsec", Real),
            ("ac_y_arcsec", Real),
        ],
        order: "seq",
    },
    Table {
        name: "locate_points",
        columns: &[
            ("idx", Int),
            ("readout_deg", Real),
            ("x_mm", Real),
            ("y_mm", Real),
            ("z_mm", Real),
            ("sx", Real),
            ("sy", Real),
            ("sz", Real),
            ("measurement_time_s", Real),
        ],
        order: "idx",
    },
    // Copied in the order they were logged; the lab store numbers them anew.
    Table { name: "events", columns: &[("at_s", Real), ("level", Text), ("message", Text)], order: "id" },
    Table {
        name: "drift_points",
        columns: &[
            ("idx", Int),
            ("before_seq", Int),
            ("at_s", Real),
            ("reference_deg", Real),
            ("readout_deg", Real),
            ("actual_deg", Real),
        ],
        order: "idx",
    },
    Table {
        name: "check_points",
        columns: &[
            ("seq", Int),
            ("run", Int),
            ("direction", Text),
            ("target_deg", Real),
            ("readout_deg", Real),
            ("actual_deg", Real),
            ("timestamp_s", Real),
        ],
        order: "seq",
    },
    Table { name: "survey_time", columns: &[("component", Text), ("seconds", Real)], order: "component" },
    Table {
        name: "scan_passes",
        columns: &[
            ("pass", Int),
            ("run", Int),
            ("direction", Text),
            ("velocity_deg_s", Real),
            ("latency_s", Real),
            ("latency_se_s", Real),
            ("readout_captured", Bool),
            ("readout_offset_s", Real),
            ("readout_rate", Real),
            ("tracker_offset_s", Real),
            ("tracker_rate", Real),
            ("started_at_s", Real),
            ("ended_at_s", Real),
        ],
        order: "pass",
    },
    Table {
        name: "scan_streams",
        columns: &[("pass", Int), ("stream", Text), ("chunk", Int), ("records", Int), ("data", Blob)],
        order: "pass, stream, chunk",
    },
    Table {
        name: "checks",
        columns: &[
            ("against_uid", Text),
            ("verdict", Text),
            ("table_holds", Bool),
            ("recalibrate", Bool),
            ("reason", Text),
            ("recalibration_uid", Text),
            ("table_file", Text),
        ],
        order: "survey_id",
    },
];

/// Every table of a survey, with the column that keys it to the survey.
fn tables() -> impl Iterator<Item = (&'static Table, &'static str)> {
    std::iter::once((&SURVEY, "id")).chain(ROWS.iter().map(|t| (t, "survey_id")))
}

/// The tables and columns `survey push` copies (the schema test checks
/// they are every table and column of both schemas).
#[cfg(test)]
fn copied_columns() -> Vec<(&'static str, Vec<&'static str>)> {
    tables()
        .map(|(t, key)| {
            let mut cols: Vec<&str> = t.columns.iter().map(|c| c.0).collect();
            cols.push(key);
            // `events` keeps its own `id` in each store.
            if t.name == "events" {
                cols.push("id");
            }
            (t.name, cols)
        })
        .collect()
}

/// Push `which` surveys of the station's store into the lab store (see the
/// module documentation).
pub async fn push(station: &Store, lab: &Store, which: Which) -> anyhow::Result<PushReport> {
    let (Backend::Sqlite(from), Backend::Lab(to)) = (&station.backend, &lab.backend) else {
        return Err(bad_input("survey push copies from a station's SQLite file (--db PATH) to a lab store (--to URL)"));
    };
    let chosen: Vec<SurveyRecord> = match which {
        Which::All => station.list().await?,
        Which::Latest => vec![station.resolve(None).await?],
        Which::One(r) => vec![station.resolve(Some(r)).await?],
    };
    let mut report = PushReport::default();
    for s in &chosen {
        if !s.is_complete() {
            if chosen.len() == 1 {
                return Err(bad_input(format!(
                    "survey {} of {} is {}: only complete surveys are pushed (`survey resume --survey {}` completes it)",
                    s.id,
                    station.path().display(),
                    s.status.as_str(),
                    s.id
                )));
            }
            report.not_complete.push(s.uid.clone());
            continue;
        }
        copy(station, from, to, s, &mut report).await?;
    }
    sync_checks(from, to).await?;
    Ok(report)
}

/// The lab store's id of the survey with `uid`, if it is there.
async fn lab_id(to: &PgPool, uid: &str) -> anyhow::Result<Option<i64>> {
    Ok(sqlx::query_scalar("SELECT id FROM surveys WHERE uid = $1").bind(uid).fetch_optional(to).await?)
}

/// Copy survey `s` unless it is there; a verification's verified survey first.
async fn copy(
    station: &Store,
    from: &SqlitePool,
    to: &PgPool,
    s: &SurveyRecord,
    report: &mut PushReport,
) -> anyhow::Result<()> {
    if report.pushed.contains(&s.uid) || report.already.contains(&s.uid) {
        return Ok(());
    }
    if lab_id(to, &s.uid).await?.is_some() {
        report.already.push(s.uid.clone());
        return Ok(());
    }
    let mut verified_lab_id = None;
    if let (SurveySource::Verification, Some(v)) = (&s.source, &s.verification) {
        let native = station.survey(v.verifies_survey).await?;
        if !native.is_complete() {
            return Err(bad_input(format!(
                "survey {} verifies survey {}, which is {}: push it once that survey is complete",
                s.id,
                native.id,
                native.status.as_str()
            )));
        }
        Box::pin(copy(station, from, to, &native, report)).await?;
        verified_lab_id = lab_id(to, &native.uid).await?;
    }
    let mut rows = Vec::new();
    for (t, key) in tables() {
        rows.push(read(from, t, key, s.id).await?);
    }
    if let Some(id) = verified_lab_id {
        let instruments = SURVEY.columns.iter().position(|c| c.0 == "instruments_json").expect("a column");
        if let Cell::Text(Some(text)) = &mut rows[0][0][instruments] {
            let mut doc: serde_json::Value = serde_json::from_str(text)?;
            doc["verifies_survey"] = id.into();
            *text = doc.to_string();
        }
    }
    let mut tx = WriteTx::begin(to).await?;
    let written = write(&mut tx, &rows).await;
    match written {
        Ok(true) => {
            if std::env::var(ABORT_AT).is_ok_and(|n| n == (report.pushed.len() + 1).to_string()) {
                tracing::debug!("{ABORT_AT}: the process aborts before committing survey {}", s.uid);
                std::process::abort();
            }
            tx.commit().await?;
            report.pushed.push(s.uid.clone());
        }
        Ok(false) => {
            tx.abort().await;
            report.already.push(s.uid.clone());
        }
        Err(e) => {
            tx.abort().await;
            return Err(e.context(format!("cannot push survey {} ({})", s.id, s.uid)));
        }
    }
    Ok(())
}

/// The rows of table `t` of survey `id` in the station's file.
async fn read(from: &SqlitePool, t: &Table, key: &str, id: i64) -> anyhow::Result<Vec<Vec<Cell>>> {
    let columns: Vec<&str> = t.columns.iter().map(|c| c.0).collect();
    let sql = format!("SELECT {} FROM {} WHERE {key} = $1 ORDER BY {}", columns.join(", "), t.name, t.order);
    let rows = sqlx::query(AssertSqlSafe(sql)).bind(id).fetch_all(from).await?;
    rows.iter()
        .map(|r| {
            t.columns
                .iter()
                .map(|&(c, kind)| {
                    Ok(match kind {
                        Int => Cell::Int(r.try_get(c)?),
                        Real => Cell::Real(r.try_get(c)?),
                        Text => Cell::Text(r.try_get(c)?),
                        Bool => Cell::Bool(r.try_get(c)?),
                        Blob => Cell::Blob(r.try_get(c)?),
                    })
                })
                .collect::<Result<Vec<Cell>, sqlx::Error>>()
                .map_err(anyhow::Error::from)
        })
        .collect()
}

/// PostgreSQL binds at most 65 535 values a statement; a stream's chunk is
/// up to 640 kB, so blobs go a few rows at a time.
fn rows_per_statement(t: &Table) -> usize {
    if t.columns.iter().any(|c| c.1 == Blob) { 8 } else { 60_000 / (t.columns.len() + 1) }
}

/// Write the survey's rows (`rows[0]`: the survey's own) in the open
/// transaction; `false` when its uid is there already (another push got
/// there first).
async fn write(tx: &mut WriteTx<Postgres>, rows: &[Vec<Vec<Cell>>]) -> anyhow::Result<bool> {
    let columns: Vec<&str> = SURVEY.columns.iter().map(|c| c.0).collect();
    let mut qb: QueryBuilder<Postgres> = QueryBuilder::new(format!("INSERT INTO surveys ({}) ", columns.join(", ")));
    qb.push_values(&rows[0], |mut b, row| {
        for cell in row {
            bind(&mut b, cell);
        }
    });
    qb.push(" ON CONFLICT (uid) DO NOTHING RETURNING id");
    let Some(id) = qb.build_query_scalar::<i64>().fetch_optional(&mut *tx.conn()).await? else {
        return Ok(false);
    };
    for (t, table_rows) in ROWS.iter().zip(&rows[1..]) {
        let columns: Vec<&str> = t.columns.iter().map(|c| c.0).collect();
        for chunk in table_rows.chunks(rows_per_statement(t)) {
            let mut qb: QueryBuilder<Postgres> =
                QueryBuilder::new(format!("INSERT INTO {} (survey_id, {}) ", t.name, columns.join(", ")));
            qb.push_values(chunk, |mut b, row| {
                b.push_bind(id);
                for cell in row {
                    bind(&mut b, cell);
                }
            });
            qb.build().execute(&mut *tx.conn()).await?;
        }
    }
    Ok(true)
}

/// A check copied before the recalibration it called for was recorded: the
/// station's record of the recalibration completes the lab's (once; a
/// check's recalibration is never changed after).
async fn sync_checks(from: &SqlitePool, to: &PgPool) -> anyhow::Result<()> {
    let done = sqlx::query(
        "SELECT s.uid, c.recalibration_uid, c.table_file FROM checks AS c JOIN surveys AS s ON s.id = c.survey_id \
         WHERE c.recalibration_uid IS NOT NULL",
    )
    .fetch_all(from)
    .await?;
    for r in done {
        let (check, recal, table): (String, String, Option<String>) = (r.try_get(0)?, r.try_get(1)?, r.try_get(2)?);
        let mut tx = WriteTx::begin(to).await?;
        let updated = sqlx::query(
            "UPDATE checks SET recalibration_uid = $1, table_file = $2 \
             WHERE recalibration_uid IS NULL AND survey_id = (SELECT id FROM surveys WHERE uid = $3)",
        )
        .bind(&recal)
        .bind(&table)
        .bind(&check)
        .execute(&mut *tx.conn())
        .await;
        match updated {
            Ok(_) => tx.commit().await?,
            Err(e) => {
                tx.abort().await;
                return Err(e.into());
            }
        }
    }
    Ok(())
}

fn bind(b: &mut sqlx::query_builder::Separated<'_, Postgres, &'static str>, cell: &Cell) {
    match cell {
        Cell::Int(v) => b.push_bind(*v),
        Cell::Real(v) => b.push_bind(*v),
        Cell::Text(v) => b.push_bind(v.clone()),
        Cell::Bool(v) => b.push_bind(*v),
        Cell::Blob(v) => b.push_bind(v.clone()),
    };
}

#[cfg(test)]
mod tests {
    use super::copied_columns;
    use crate::Store;
    use sqlx::Row;

    /// Every table and column of the schema is copied (the lab store's schema
    /// is the same: `tests/cli/lab.rs` compares them), but the station's
    /// sample packs: a copy of its rows for its own reads, which the lab
    /// store reads from the rows pushed.
    #[tokio::test]
    async fn a_push_copies_every_table_and_column_of_a_survey() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("s.db")).await.unwrap();
        let pool = store.sqlite().unwrap();
        let tables: Vec<String> = sqlx::query_scalar(
            "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite_%' AND name <> '_sqlx_migrations' \
             AND name <> 'sample_packs' ORDER BY name",
        )
        .fetch_all(pool)
        .await
        .unwrap();
        let mut copied = copied_columns();
        copied.sort_by_key(|(t, _)| *t);
        assert_eq!(tables, copied.iter().map(|(t, _)| t.to_string()).collect::<Vec<_>>());
        for (table, columns) in &copied {
            let rows =
                sqlx::query(sqlx::AssertSqlSafe(format!("PRAGMA table_info({table})"))).fetch_all(pool).await.unwrap();
            let mut names: Vec<String> = rows.iter().map(|r| r.get::<String, _>("name")).collect();
            let mut columns: Vec<String> = columns.iter().map(|c| c.to_string()).collect();
            names.sort();
            columns.sort();
            assert_eq!(names, columns, "{table}");
        }
        store.close().await;
    }
}
