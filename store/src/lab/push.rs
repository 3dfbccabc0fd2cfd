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
//! copied after the check, completes the check's row there. The history's
//! cache of a survey (its summary, its comparison with the survey before it
//! on the station) is copied with it, as made: what the lab store lacks of
//! an asset's history (a pair of surveys from two stations) is made there
//! by `survey push` itself after the copy (`survey_lab::life::cache::fill`).

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
            ("air_temperature_c", Real),
            ("air_pressure_hpa", Real),
            ("air_humidity_pct", Real),
        ],
        order: "seq",
    },
    Table {
        name: "smr_readings",
        columns: &[
            ("seq", Int),
            ("smr", Int),
            ("x_mm", Real),
            ("y_mm", Real),
            ("z_mm", Real),
            ("sx_mm", Real),
            ("sy_mm", Real),
            ("sz_mm", Real),
            ("measurement_time_s", Real),
            ("air_temperature_c", Real),
            ("air_pressure_hpa", Real),
            ("air_humidity_pct", Real),
        ],
        order: "seq, smr",
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
    // The history's cache of the survey, made by the station (its
    // summary, and its comparison with the survey before it there): what
    // the lab store would compute the same from the rows copied.
    Table { name: "survey_summaries", columns: &[("version", Text), ("data", Blob)], order: "version" },
    Table {
        name: "survey_changes",
        columns: &[("from_uid", Text), ("version", Text), ("data", Blob)],
        order: "from_uid, version",
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
            ("residual_peak_deg", Real),
            ("stated_u_deg", Real),
            ("cells_outside", Int),
            ("allowed_outside", Int),
        ],
        order: "survey_id",
    },
    // The certificates issued, as issued (one issued after the survey was
    // pushed goes with the next push: `sync_certificates`).
    Table {
        name: "certificates",
        columns: &[
            ("number", Text),
            ("seq", Int),
            ("issued_at", Text),
            ("replaces", Text),
            ("reason", Text),
            ("page", Text),
            ("dcc", Text),
        ],
        order: "seq",
    },
];

/// Every table of a survey, with the column that keys it to the survey.
#[cfg(test)]
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
    for uid in &report.already {
        if let Some(s) = chosen.iter().find(|s| &s.uid == uid) {
            sync_certificates(station, to, s)
                .await
                .map_err(|e| e.context(format!("cannot push the certificates of survey {} ({})", s.id, s.uid)))?;
        }
    }
    Ok(report)
}

/// The certificates of survey `s` issued at the station after it was
/// pushed: copied into the lab store, each once (a number the lab store
/// holds for another survey is refused there, and said).
async fn sync_certificates(station: &Store, to: &PgPool, s: &SurveyRecord) -> anyhow::Result<()> {
    let Some(id) = lab_id(to, &s.uid).await? else { return Ok(()) };
    let there: Vec<String> =
        sqlx::query_scalar("SELECT number FROM certificates WHERE survey_id = $1").bind(id).fetch_all(to).await?;
    for c in station.certificates(s.id).await?.into_iter().filter(|c| !there.contains(&c.number)) {
        let mut tx = WriteTx::begin(to).await?;
        let inserted = sqlx::query(
            "INSERT INTO certificates (survey_id, number, seq, issued_at, replaces, reason, page, dcc) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8)",
        )
        .bind(id)
        .bind(&c.number)
        .bind(c.seq)
        .bind(&c.issued_at)
        .bind(&c.replaces)
        .bind(&c.reason)
        .bind(&c.page)
        .bind(&c.dcc)
        .execute(&mut *tx.conn())
        .await;
        match inserted {
            Ok(_) => tx.commit().await?,
            Err(e) => {
                tx.abort().await;
                if e.as_database_error().is_some_and(|d| d.is_unique_violation()) {
                    return Err(bad_input(format!(
                        "certificate number {} is in the lab store already, issued for another survey: a number is \
                         issued once in a lab (amend this survey's certificate with another --certificate-number)",
                        c.number
                    )));
                }
                return Err(e.into());
            }
        }
    }
    Ok(())
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
    let mut survey_row = read(from, &SURVEY, "id", s.id).await?;
    if let (Some(id), Some(row)) = (verified_lab_id, survey_row.first_mut()) {
        let instruments = SURVEY.columns.iter().position(|c| c.0 == "instruments_json").expect("a column");
        if let Cell::Text(Some(text)) = &mut row[instruments] {
            let mut doc: serde_json::Value = serde_json::from_str(text)?;
            doc["verifies_survey"] = id.into();
            *text = doc.to_string();
        }
    }
    let mut tx = WriteTx::begin(to).await?;
    let written = write(&mut tx, station, s.id, &survey_row).await;
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

/// The `SELECT` of table `t`'s rows of one survey (`$1`, by `key`), in its order.
/// A station file of a schema before 9 has no air columns: they are read as NULL.
fn select(t: &Table, key: &str, has_air: bool) -> String {
    let columns: Vec<String> = t
        .columns
        .iter()
        .map(|c| if !has_air && c.0.starts_with("air_") { format!("NULL AS {}", c.0) } else { c.0.to_string() })
        .collect();
    format!("SELECT {} FROM {} WHERE {key} = $1 ORDER BY {}", columns.join(", "), t.name, t.order)
}

/// The cells of a row of table `t`, as stored.
fn cells(t: &Table, r: &sqlx::sqlite::SqliteRow) -> Result<Vec<Cell>, sqlx::Error> {
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
        .collect()
}

/// The rows of table `t` of survey `id` in the station's file (the
/// survey's own row, read whole).
async fn read(from: &SqlitePool, t: &Table, key: &str, id: i64) -> anyhow::Result<Vec<Vec<Cell>>> {
    let rows = sqlx::query(AssertSqlSafe(select(t, key, true))).bind(id).fetch_all(from).await?;
    rows.iter().map(|r| cells(t, r).map_err(anyhow::Error::from)).collect()
}

/// Write the survey (its own row `survey_row`, then its rows of every other
/// table, streamed from the station's file) in the open transaction;
/// `false` when its uid is there already (another push got there first).
async fn write(
    tx: &mut WriteTx<Postgres>,
    station: &Store,
    station_id: i64,
    survey_row: &[Vec<Cell>],
) -> anyhow::Result<bool> {
    let columns: Vec<&str> = SURVEY.columns.iter().map(|c| c.0).collect();
    let mut qb: QueryBuilder<Postgres> = QueryBuilder::new(format!("INSERT INTO surveys ({}) ", columns.join(", ")));
    qb.push_values(survey_row, |mut b, row| {
        for cell in row {
            bind(&mut b, cell);
        }
    });
    qb.push(" ON CONFLICT (uid) DO NOTHING RETURNING id");
    let Some(id) = qb.build_query_scalar::<i64>().fetch_optional(&mut *tx.conn()).await? else {
        return Ok(false);
    };
    for t in ROWS {
        // A station's file of schema 7 has no history cache to copy.
        if t.name.starts_with("survey_") && !station.has_history_cache() {
            continue;
        }
        copy_rows(tx, station, t, station_id, id).await.map_err(|e| e.context(format!("copying its {}", t.name)))?;
    }
    Ok(true)
}

/// What a binary `COPY` stream is sent in, bytes at a time.
const COPY_CHUNK: usize = 1 << 20;

/// A table of no more rows than this is written with multi-row `INSERT`s,
/// a larger one with a binary `COPY`: a `COPY` ends with a message of a few
/// bytes after its data, which TCP holds back until the data is
/// acknowledged (Nagle's algorithm against the server's delayed
/// acknowledgement: about 40 ms a table, most of a small survey's push),
/// while a statement's answer carries the acknowledgement with it.
const FEW_ROWS: usize = 4096;

/// What the reader of a table sends the writer.
enum Batch {
    /// Every row of a table of few rows.
    Rows(Vec<Vec<Cell>>),
    /// A chunk of binary `COPY` data (the first with the header, the last
    /// with the trailer).
    Copy(Vec<u8>),
}

/// Write the rows of table `t` of the station's survey `station_id` into
/// the lab store's survey `lab_id`: a blocking thread reads them through a
/// read-only rusqlite connection (as the samples are read) and sends them a
/// batch at a time, a large table as binary `COPY` data (no text between
/// the two stores: every value goes as it is stored, an f64 by its bits).
/// A survey's rows are never all in memory; a table without rows sends
/// nothing.
async fn copy_rows(
    tx: &mut WriteTx<Postgres>,
    station: &Store,
    t: &'static Table,
    station_id: i64,
    lab_id: i64,
) -> anyhow::Result<()> {
    let (path, immutable, has_air) = (station.path.clone(), station.immutable, station.environment);
    let (batches_in, mut batches) = tokio::sync::mpsc::channel::<Batch>(2);
    let reader = tokio::task::spawn_blocking(move || {
        binary::read_rows(&path, immutable, has_air, t, station_id, lab_id, &batches_in)
    });
    let written = match batches.recv().await {
        // No row: nothing to write.
        None => Ok(None),
        Some(Batch::Rows(rows)) => insert_rows(tx, t, lab_id, &rows).await.map(|()| None),
        Some(Batch::Copy(first)) => {
            let columns: Vec<&str> = t.columns.iter().map(|c| c.0).collect();
            let statement = format!("COPY {} (survey_id, {}) FROM STDIN (FORMAT binary)", t.name, columns.join(", "));
            match tx.conn().copy_in_raw(&statement).await {
                Ok(mut copy) => {
                    let mut sent = copy.send(first).await.map(|_| ());
                    while sent.is_ok()
                        && let Some(Batch::Copy(chunk)) = batches.recv().await
                    {
                        sent = copy.send(chunk).await.map(|_| ());
                    }
                    Ok(Some((copy, sent)))
                }
                Err(e) => Err(e.into()),
            }
        }
    };
    drop(batches);
    let read = match reader.await {
        Ok(read) => read,
        Err(e) => Err(anyhow::anyhow!("the reader of {} stopped: {e}", t.name)),
    };
    match written {
        Err(e) => Err(e),
        Ok(None) => read,
        Ok(Some((copy, sent))) => match sent.map_err(anyhow::Error::from).and(read) {
            Ok(()) => {
                copy.finish().await?;
                Ok(())
            }
            Err(e) => {
                // The transaction is rolled back and its connection retired by the caller.
                let _ = copy.abort(format!("{e:#}")).await;
                Err(e)
            }
        },
    }
}

/// PostgreSQL binds at most 65 535 values a statement; a stream's chunk is
/// up to 640 kB, so blobs go a few rows at a time.
fn rows_per_statement(t: &Table) -> usize {
    if t.columns.iter().any(|c| c.1 == Blob) { 8 } else { 60_000 / (t.columns.len() + 1) }
}

/// Insert `rows` of table `t` for the lab store's survey `lab_id`.
async fn insert_rows(tx: &mut WriteTx<Postgres>, t: &Table, lab_id: i64, rows: &[Vec<Cell>]) -> anyhow::Result<()> {
    let columns: Vec<&str> = t.columns.iter().map(|c| c.0).collect();
    for chunk in rows.chunks(rows_per_statement(t)) {
        let mut qb: QueryBuilder<Postgres> =
            QueryBuilder::new(format!("INSERT INTO {} (survey_id, {}) ", t.name, columns.join(", ")));
        qb.push_values(chunk, |mut b, row| {
            b.push_bind(lab_id);
            for cell in row {
                bind(&mut b, cell);
            }
        });
        qb.build().execute(&mut *tx.conn()).await?;
    }
    Ok(())
}

/// PostgreSQL's binary `COPY` format: a header, each row as its field count
/// and each field's length (-1: NULL) and bytes in network order, a
/// trailer; and the rows read for it.
mod binary {
    use super::{Batch, Cell, FEW_ROWS, Kind, Table};

    /// The signature, no flags, no header extension.
    fn header() -> Vec<u8> {
        let mut buf = Vec::with_capacity(super::COPY_CHUNK + 4096);
        buf.extend_from_slice(b"PGCOPY\n\xff\r\n\0");
        buf.extend_from_slice(&0i32.to_be_bytes());
        buf.extend_from_slice(&0i32.to_be_bytes());
        buf
    }

    fn field(buf: &mut Vec<u8>, bytes: Option<&[u8]>) {
        match bytes {
            Some(b) => {
                buf.extend_from_slice(&(b.len() as i32).to_be_bytes());
                buf.extend_from_slice(b);
            }
            None => buf.extend_from_slice(&(-1i32).to_be_bytes()),
        }
    }

    /// A row: the survey's key, then its cells (BIGINT, DOUBLE PRECISION,
    /// TEXT, BOOLEAN, BYTEA as the columns are).
    fn row(buf: &mut Vec<u8>, key: i64, cells: &[Cell]) {
        buf.extend_from_slice(&(1 + cells.len() as i16).to_be_bytes());
        field(buf, Some(&key.to_be_bytes()));
        for c in cells {
            match c {
                Cell::Int(v) => field(buf, v.map(i64::to_be_bytes).as_ref().map(|b| &b[..])),
                Cell::Real(v) => field(buf, v.map(|x| x.to_bits().to_be_bytes()).as_ref().map(|b| &b[..])),
                Cell::Text(v) => field(buf, v.as_deref().map(str::as_bytes)),
                Cell::Bool(v) => field(buf, v.map(|b| [u8::from(b)]).as_ref().map(|b| &b[..])),
                Cell::Blob(v) => field(buf, v.as_deref()),
            }
        }
    }

    /// The cells of a row of table `t` as stored; a value of another kind
    /// than its column's is an error naming the column.
    fn cells(t: &Table, r: &rusqlite::Row<'_>) -> anyhow::Result<Vec<Cell>> {
        use rusqlite::types::ValueRef as V;
        let mut out = Vec::with_capacity(t.columns.len());
        for (i, &(name, kind)) in t.columns.iter().enumerate() {
            let v = r.get_ref(i)?;
            out.push(match (kind, v) {
                (Kind::Int, V::Null) => Cell::Int(None),
                (Kind::Int, V::Integer(x)) => Cell::Int(Some(x)),
                (Kind::Real, V::Null) => Cell::Real(None),
                (Kind::Real, V::Real(x)) => Cell::Real(Some(x)),
                (Kind::Real, V::Integer(x)) => Cell::Real(Some(x as f64)),
                (Kind::Bool, V::Null) => Cell::Bool(None),
                (Kind::Bool, V::Integer(x @ (0 | 1))) => Cell::Bool(Some(x == 1)),
                (Kind::Text, V::Null) => Cell::Text(None),
                (Kind::Text, V::Text(x)) => Cell::Text(Some(std::str::from_utf8(x)?.to_string())),
                (Kind::Blob, V::Null) => Cell::Blob(None),
                (Kind::Blob, V::Blob(x)) => Cell::Blob(Some(x.to_vec())),
                (_, v) => anyhow::bail!("{}.{name} holds a {:?} where a {kind:?} belongs", t.name, v.data_type()),
            });
        }
        Ok(out)
    }

    /// Read the rows of table `t` of survey `station_id` from the station's
    /// file at `path` and send them for the lab store's survey `lab_id`:
    /// [`FEW_ROWS`] or fewer as one batch of rows, more as binary `COPY`
    /// data a chunk at a time; nothing when there is no row. Stops early
    /// when nobody receives any more.
    pub(super) fn read_rows(
        path: &std::path::Path,
        immutable: bool,
        has_air: bool,
        t: &Table,
        station_id: i64,
        lab_id: i64,
        out: &tokio::sync::mpsc::Sender<Batch>,
    ) -> anyhow::Result<()> {
        let conn = crate::samples::open_reader(path, immutable)?;
        let mut statement = conn.prepare(&super::select(t, "survey_id", has_air))?;
        let mut rows = statement.query([station_id])?;
        let (mut few, mut copy): (Vec<Vec<Cell>>, Option<Vec<u8>>) = (Vec::new(), None);
        while let Some(r) = rows.next()? {
            let c = cells(t, r)?;
            match &mut copy {
                None if few.len() < FEW_ROWS => few.push(c),
                None => {
                    let mut buf = header();
                    for earlier in few.drain(..) {
                        row(&mut buf, lab_id, &earlier);
                    }
                    row(&mut buf, lab_id, &c);
                    copy = Some(buf);
                }
                Some(buf) => {
                    row(buf, lab_id, &c);
                    if buf.len() >= super::COPY_CHUNK && out.blocking_send(Batch::Copy(std::mem::take(buf))).is_err() {
                        return Ok(());
                    }
                }
            }
        }
        let last = match copy {
            Some(mut buf) => {
                buf.extend_from_slice(&(-1i16).to_be_bytes());
                Batch::Copy(buf)
            }
            None if few.is_empty() => return Ok(()),
            None => Batch::Rows(few),
        };
        let _ = out.blocking_send(last);
        Ok(())
    }
}

/// A check copied before the recalibration it called for was recorded: the
/// station's record of the recalibration completes the lab's (once; a
/// check's recalibration is never changed after).
async fn sync_checks(from: &SqlitePool, to: &PgPool) -> anyhow::Result<()> {
    // Only the lab's checks still waiting for theirs are written (a push
    // costs one read of each side, not a transaction a check).
    let waiting: std::collections::HashSet<String> = sqlx::query_scalar(
        "SELECT s.uid FROM checks AS c JOIN surveys AS s ON s.id = c.survey_id WHERE c.recalibration_uid IS NULL",
    )
    .fetch_all(to)
    .await?
    .into_iter()
    .collect();
    if waiting.is_empty() {
        return Ok(());
    }
    let done = sqlx::query(
        "SELECT s.uid, c.recalibration_uid, c.table_file FROM checks AS c JOIN surveys AS s ON s.id = c.survey_id \
         WHERE c.recalibration_uid IS NOT NULL",
    )
    .fetch_all(from)
    .await?;
    for r in done {
        let (check, recal, table): (String, String, Option<String>) = (r.try_get(0)?, r.try_get(1)?, r.try_get(2)?);
        if !waiting.contains(&check) {
            continue;
        }
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
    /// store reads from the rows pushed; and the laboratory's certificate
    /// numbers, which are the lab store's own (drawn there, not pushed).
    #[tokio::test]
    async fn a_push_copies_every_table_and_column_of_a_survey() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("s.db")).await.unwrap();
        let pool = store.sqlite().unwrap();
        let tables: Vec<String> = sqlx::query_scalar(
            "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite_%' AND name <> '_sqlx_migrations' \
             AND name NOT IN ('sample_packs', 'certificate_numbers') ORDER BY name",
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
