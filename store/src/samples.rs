//! Samples: storing a batch (or a whole import) in one transaction, reading
//! them back with their raw readings.

use std::str::FromStr;

use anyhow::{Context, anyhow, bail};
use futures_util::TryStreamExt as _;
use sqlx::sqlite::SqliteConnection;
use sqlx::{QueryBuilder, Row, Sqlite};
use survey_drivers::{AcReading, SmrMeasurement};
use survey_processing::{Direction, Sample};

use super::pack::{self, SmrPositions};
use super::surveys::insert_survey;
use super::tx::WriteTx;
use super::{CHUNK_ROWS, NotFound, Store, is_foreign_key_error, on_pool, real};
use crate::survey::NewSurvey;
use survey_acquire::{RawReading, RecordedSample};

/// A sample row of either backend, with its raw reading when the query
/// joined one (a row without a `kind` column has none).
macro_rules! sample_from_row {
    ($row:expr) => {
        (|| -> anyhow::Result<RecordedSample> {
            let row = $row;
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
            let kind: Option<String> = match row.try_get("kind") {
                Err(sqlx::Error::ColumnNotFound(_)) => None,
                other => other?,
            };
            let raw = match kind.as_deref() {
                None => RawReading::None,
                Some("smr") => RawReading::Smr(SmrMeasurement {
                    x_mm: real(row, "smr_x_mm")?,
                    y_mm: real(row, "smr_y_mm")?,
                    z_mm: real(row, "smr_z_mm")?,
                    std_dev_mm: [real(row, "smr_sx_mm")?, real(row, "smr_sy_mm")?, real(row, "smr_sz_mm")?],
                    measurement_time_s: real(row, "measurement_time_s")?,
                    // The air is read by `Store::environment`, not with the samples.
                    environment: None,
                }),
                Some("autocollimator") => {
                    let face: i64 = row.try_get("ac_face")?;
                    RawReading::Autocollimator {
                        face: u32::try_from(face).with_context(|| format!("seq {seq}: bad polygon face {face}"))?,
                        reading: AcReading { x_arcsec: real(row, "ac_x_arcsec")?, y_arcsec: real(row, "ac_y_arcsec")? },
                    }
                }
                Some(other) => bail!("seq {seq}: unknown raw reading kind '{other}'"),
            };
            Ok(RecordedSample {
                seq: u64::try_from(seq).with_context(|| format!("negative seq {seq}"))?,
                sample,
                raw,
                others: Vec::new(),
            })
        })()
    };
}

impl Store {
    /// Store samples of survey `survey_id` with their raw readings, in one
    /// transaction: all of them or, on any error, none. A `seq` already stored
    /// is an error (never a silent replace). When this returns `Ok`, the samples
    /// are durable.
    pub async fn append(&self, survey_id: i64, samples: &[RecordedSample]) -> anyhow::Result<()> {
        if samples.is_empty() {
            return Ok(());
        }
        let mut tx = WriteTx::begin(self.sqlite()?)
            .await
            .with_context(|| format!("cannot store samples of survey {survey_id} in {}", self.path.display()))?;
        if let Err(e) = insert_samples(tx.conn(), survey_id, samples).await {
            tx.abort().await;
            return Err(e.context(format!(
                "cannot store samples {}..={} of survey {} in {}",
                samples[0].seq,
                samples[samples.len() - 1].seq,
                survey_id,
                self.path.display()
            )));
        }
        tx.commit()
            .await
            .with_context(|| format!("cannot commit samples of survey {survey_id} in {}", self.path.display()))?;
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
                others: Vec::new(),
            })
            .collect();
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let inserted = match insert_survey(tx.conn(), s).await {
            Ok(id) => insert_samples(tx.conn(), id, &recorded).await.map(|()| id),
            Err(e) => Err(e),
        };
        match inserted {
            Ok(id) => {
                tx.commit().await?;
                self.pack(id).await;
                Ok(id)
            }
            Err(e) => {
                tx.abort().await;
                Err(e)
            }
        }
    }

    /// The samples of a survey in acquisition order (by seq): only the six
    /// columns processing needs, read into a compact vector (48 bytes a
    /// sample; no raw readings, no join).
    ///
    /// This is the bulk read every command makes, so it does not go through
    /// sqlx: sqlx's SQLite driver hands each row from its worker thread over
    /// a channel, copying every value under SQLite's global mutex, which made
    /// loading cost twenty times the processing. It reads on a blocking thread
    /// through a read-only rusqlite connection to the same bundled SQLite
    /// (both link `libsqlite3-sys`), which sees every committed transaction
    /// (WAL) and writes nothing.
    ///
    /// From the lab store (PostgreSQL), the same columns through sqlx.
    pub async fn samples(&self, survey_id: i64) -> anyhow::Result<Vec<Sample>> {
        let read = match &self.backend {
            super::Backend::Sqlite(_) => {
                let (path, immutable) = (self.path.clone(), self.immutable);
                tokio::task::spawn_blocking(move || read_samples(&path, immutable, survey_id))
                    .await
                    .context("the sample reader stopped")?
            }
            super::Backend::Lab(pool) => {
                let rows = sqlx::query(
                    "SELECT seq, run, direction, target_deg, readout_deg, actual_deg, timestamp_s \
                     FROM samples WHERE survey_id = $1 ORDER BY seq",
                )
                .bind(survey_id)
                .fetch_all(pool)
                .await?;
                rows.iter().map(|row| sample_from_row!(row).map(|r| r.sample)).collect()
            }
        };
        read.with_context(|| format!("cannot read the samples of survey {survey_id}"))
            .map_err(|e| crate::damage::on_read(&self.path, &format!("the samples of survey {survey_id}"), e))
    }

    /// The positions of the SMRs beside the first (a survey of several SMRs,
    /// `smr_readings`): `(seq, smr, [x, y, z])` in seq then SMR order (`smr`
    /// 1 for the second); empty for a survey of one SMR, or of a store whose
    /// schema predates them.
    pub async fn other_smr_positions(&self, survey_id: i64) -> anyhow::Result<Vec<(u64, usize, [f64; 3])>> {
        const QUERY: &str =
            "SELECT seq, smr, x_mm, y_mm, z_mm FROM smr_readings WHERE survey_id = ?1 ORDER BY seq, smr";
        let read = match &self.backend {
            super::Backend::Sqlite(_) => {
                let (path, immutable) = (self.path.clone(), self.immutable);
                tokio::task::spawn_blocking(move || -> anyhow::Result<Vec<(u64, usize, [f64; 3])>> {
                    let conn = open_reader(&path, immutable)?;
                    let has: bool = conn
                        .query_row("SELECT count(*) FROM sqlite_schema WHERE name = 'smr_readings'", [], |r| {
                            r.get::<_, i64>(0)
                        })
                        .map(|n| n > 0)?;
                    if !has {
                        return Ok(Vec::new());
                    }
                    let mut stmt = conn.prepare(QUERY)?;
                    let rows = stmt.query_map([survey_id], |r| {
                        Ok((
                            r.get::<_, i64>(0)? as u64,
                            r.get::<_, i64>(1)? as usize,
                            [r.get(2)?, r.get(3)?, r.get(4)?],
                        ))
                    })?;
                    Ok(rows.collect::<Result<Vec<_>, _>>()?)
                })
                .await
                .context("the SMR reader stopped")?
            }
            super::Backend::Lab(pool) => {
                let rows = sqlx::query(
                    "SELECT seq, smr, x_mm, y_mm, z_mm FROM smr_readings WHERE survey_id = $1 ORDER BY seq, smr",
                )
                .bind(survey_id)
                .fetch_all(pool)
                .await?;
                rows.iter()
                    .map(|row| -> anyhow::Result<(u64, usize, [f64; 3])> {
                        let seq: i64 = row.try_get(0)?;
                        let smr: i64 = row.try_get(1)?;
                        Ok((seq as u64, smr as usize, [row.try_get(2)?, row.try_get(3)?, row.try_get(4)?]))
                    })
                    .collect()
            }
        };
        read.with_context(|| format!("cannot read the other SMRs' positions of survey {survey_id}"))
            .map_err(|e| crate::damage::on_read(&self.path, &format!("the SMR readings of survey {survey_id}"), e))
    }

    /// The samples of a survey as [`Store::samples`] reads them, with the SMR
    /// position behind each that has one (what the axis refit needs), after
    /// the points `before` (the locate points): [`SmrPositions`], x, y, z in
    /// mm (NaN where the tracker gave NaN) and each one's sample index. From
    /// the survey's pack, or like [`Store::samples`] from the samples and the
    /// SMR rows, each read in one pass in seq order, merged (no join).
    ///
    /// From the lab store (PostgreSQL), through sqlx: the samples with their
    /// raw readings ([`Store::recorded_samples`]).
    pub async fn samples_with_smr(
        &self,
        survey_id: i64,
        before: Vec<[f64; 3]>,
    ) -> anyhow::Result<(Vec<Sample>, SmrPositions)> {
        if let super::Backend::Lab(_) = &self.backend {
            let recorded = self.recorded_samples(survey_id).await?;
            let mut smr = SmrPositions::after(before, recorded.len());
            for (index, r) in recorded.iter().enumerate() {
                if let survey_acquire::RawReading::Smr(m) = &r.raw {
                    smr.push(index, m.xyz())?;
                }
            }
            return Ok((recorded.into_iter().map(|r| r.sample).collect(), smr));
        }
        let (path, immutable) = (self.path.clone(), self.immutable);
        tokio::task::spawn_blocking(move || read_samples_with_smr(&path, immutable, survey_id, before))
            .await
            .context("the sample reader stopped")?
            .with_context(|| format!("cannot read the samples of survey {survey_id}"))
            .map_err(|e| crate::damage::on_read(&self.path, &format!("the samples of survey {survey_id}"), e))
    }

    /// The samples of a survey, ordered by seq, with their raw readings and
    /// their place in the plan (for exports of raw data, tests).
    pub async fn recorded_samples(&self, survey_id: i64) -> anyhow::Result<Vec<RecordedSample>> {
        on_pool!(self, |pool| {
            let mut out = Vec::new();
            let mut rows = sqlx::query(
                "SELECT s.seq, s.run, s.direction, s.target_deg, s.readout_deg, s.actual_deg, \
                 s.timestamp_s, r.kind, r.smr_x_mm, r.smr_y_mm, r.smr_z_mm, r.smr_sx_mm, \
                 r.smr_sy_mm, r.smr_sz_mm, r.measurement_time_s, r.ac_face, r.ac_x_arcsec, \
                 r.ac_y_arcsec \
                 FROM samples AS s LEFT JOIN raw_readings AS r \
                 ON r.survey_id = s.survey_id AND r.seq = s.seq \
                 WHERE s.survey_id = $1 ORDER BY s.seq",
            )
            .bind(survey_id)
            .fetch(pool);
            while let Some(row) =
                rows.try_next().await.with_context(|| format!("cannot read the samples of survey {survey_id}"))?
            {
                out.push(
                    sample_from_row!(&row)
                        .with_context(|| format!("survey {survey_id} in {} holds a bad sample", self.path.display()))?,
                );
            }
            Ok(out)
        })
    }

    /// The latest instrument time stored for a survey: the last sample's
    /// timestamp, or when no sample has one, `None`.
    pub async fn last_sample_time(&self, id: i64) -> anyhow::Result<Option<f64>> {
        let t: Option<f64> = sqlx::query_scalar("SELECT MAX(timestamp_s) FROM samples WHERE survey_id = ?")
            .bind(id)
            .fetch_one(self.sqlite()?)
            .await?;
        Ok(t)
    }

    /// How many samples of a survey are stored (committed: what a reader sees).
    pub async fn sample_count(&self, id: i64) -> anyhow::Result<u64> {
        let n: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM samples WHERE survey_id = ?")
            .bind(id)
            .fetch_one(self.sqlite()?)
            .await?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    /// The highest seq stored for a survey (`None` when it has no sample yet).
    /// Samples are stored in plan order, so a resume continues at `last + 1`.
    pub async fn last_seq(&self, id: i64) -> anyhow::Result<Option<u64>> {
        let seq: Option<i64> = sqlx::query_scalar("SELECT MAX(seq) FROM samples WHERE survey_id = ?")
            .bind(id)
            .fetch_one(self.sqlite()?)
            .await?;
        seq.map(|s| u64::try_from(s).context("negative seq in the database")).transpose()
    }
}

impl Store {
    /// Write the pack of survey `id` from its rows, unless it has one. Best
    /// effort: the rows are the record, so a pack that cannot be written
    /// (a full disk, say) is logged and the survey is read from its rows.
    pub(super) async fn pack(&self, id: i64) {
        if let Err(e) = self.try_pack(id).await {
            tracing::warn!(survey = id, error = %format!("{e:#}"), "the samples were not packed: they are read from their rows");
        }
    }

    async fn try_pack(&self, id: i64) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        // Under the write lock from here: the rows read are the rows packed.
        let packed: Option<i64> = sqlx::query_scalar("SELECT 1 FROM sample_packs WHERE survey_id = ? LIMIT 1")
            .bind(id)
            .fetch_optional(tx.conn())
            .await?;
        if packed.is_some() {
            tx.commit().await?;
            return Ok(());
        }
        let (path, immutable) = (self.path.clone(), self.immutable);
        let records = tokio::task::spawn_blocking(move || read_records(&path, immutable, id))
            .await
            .context("the sample reader stopped")??;
        if !records.is_empty() {
            pack::write(tx.conn(), id, &records).await?;
        }
        tx.commit().await?;
        tracing::debug!(survey = id, samples = records.len(), "samples packed");
        Ok(())
    }
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
    for (name, v) in [("target_deg", s.target_deg), ("readout_deg", s.readout_deg), ("actual_deg", s.actual_deg)] {
        if v.is_nan() {
            bail!("sample seq {}: {name} is NaN", r.seq);
        }
    }
    if s.timestamp_s.is_some_and(f64::is_nan) {
        bail!("sample seq {}: timestamp_s is NaN", r.seq);
    }
    Ok(())
}

pub(super) async fn insert_samples(
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

        let raws: Vec<&RecordedSample> = chunk.iter().filter(|r| !matches!(r.raw, RawReading::None)).collect();
        if raws.is_empty() {
            continue;
        }
        let mut qb: QueryBuilder<Sqlite> = QueryBuilder::new(
            "INSERT INTO raw_readings (survey_id, seq, kind, smr_x_mm, smr_y_mm, smr_z_mm, \
             smr_sx_mm, smr_sy_mm, smr_sz_mm, measurement_time_s, ac_face, ac_x_arcsec, \
             ac_y_arcsec, air_temperature_c, air_pressure_hpa, air_humidity_pct) ",
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
                        .push_bind(None::<f64>)
                        .push_bind(m.environment.map(|a| a.temperature_c))
                        .push_bind(m.environment.map(|a| a.pressure_hpa))
                        .push_bind(m.environment.map(|a| a.humidity_pct));
                }
                RawReading::Autocollimator { face, reading } => {
                    b.push_bind("autocollimator");
                    for _ in 0..7 {
                        b.push_bind(None::<f64>);
                    }
                    b.push_bind(i64::from(face)).push_bind(reading.x_arcsec).push_bind(reading.y_arcsec);
                    b.push_bind(None::<f64>).push_bind(None::<f64>).push_bind(None::<f64>);
                }
                RawReading::None => unreachable!("filtered out above"),
            }
        });
        qb.build().execute(&mut *conn).await?;
        insert_other_smrs(conn, survey_id, chunk).await?;
    }
    Ok(())
}

/// The readings of the SMRs beside the first (`smr_readings`, migration 10)
/// of `samples`, in bounded multi-row statements.
async fn insert_other_smrs(
    conn: &mut SqliteConnection,
    survey_id: i64,
    samples: &[RecordedSample],
) -> anyhow::Result<()> {
    let rows: Vec<(u64, usize, &survey_drivers::SmrMeasurement)> =
        samples.iter().flat_map(|r| r.others.iter().enumerate().map(move |(k, m)| (r.seq, k + 1, m))).collect();
    for chunk in rows.chunks(CHUNK_ROWS) {
        let mut qb: QueryBuilder<Sqlite> = QueryBuilder::new(
            "INSERT INTO smr_readings (survey_id, seq, smr, x_mm, y_mm, z_mm, sx_mm, sy_mm, sz_mm, \
             measurement_time_s, air_temperature_c, air_pressure_hpa, air_humidity_pct) ",
        );
        qb.push_values(chunk, |mut b, (seq, k, m)| {
            b.push_bind(survey_id)
                .push_bind(*seq as i64)
                .push_bind(*k as i64)
                .push_bind(m.x_mm)
                .push_bind(m.y_mm)
                .push_bind(m.z_mm)
                .push_bind(m.std_dev_mm[0])
                .push_bind(m.std_dev_mm[1])
                .push_bind(m.std_dev_mm[2])
                .push_bind(m.measurement_time_s)
                .push_bind(m.environment.map(|a| a.temperature_c))
                .push_bind(m.environment.map(|a| a.pressure_hpa))
                .push_bind(m.environment.map(|a| a.humidity_pct));
        });
        qb.build().execute(&mut *conn).await?;
    }
    Ok(())
}

/// A read-only rusqlite connection to the database at `path` (with
/// `immutable=1` on read-only media).
pub(crate) fn open_reader(path: &std::path::Path, immutable: bool) -> anyhow::Result<rusqlite::Connection> {
    use rusqlite::OpenFlags;
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let conn = if immutable {
        // Read-only media: a URI with `immutable=1` (the characters a URI
        // reserves are escaped in the path).
        let mut uri = String::from("file:");
        for c in path.to_string_lossy().chars() {
            match c {
                '%' | '?' | '#' => uri.push_str(&format!("%{:02X}", c as u32)),
                c => uri.push(c),
            }
        }
        uri.push_str("?immutable=1");
        rusqlite::Connection::open_with_flags(uri, flags | OpenFlags::SQLITE_OPEN_URI)?
    } else {
        rusqlite::Connection::open_with_flags(path, flags)?
    };
    conn.busy_timeout(super::BUSY_TIMEOUT)?;
    Ok(conn)
}

/// Read the pages through a memory map rather than a read(2) copy each: for
/// the rows, whose bulk reads touch every page of a table once. (A pack is
/// read without: its blobs are copied out of their pages anyway, and the
/// mapped pages would stay resident beside the copy.)
fn map_pages(conn: &rusqlite::Connection) -> anyhow::Result<()> {
    conn.pragma_update(None, "mmap_size", 1i64 << 30)?;
    Ok(())
}

/// [`Store::samples`], on the calling thread: from the survey's pack when
/// it has one, from its rows otherwise.
fn read_samples(path: &std::path::Path, immutable: bool, survey_id: i64) -> anyhow::Result<Vec<Sample>> {
    let conn = open_reader(path, immutable)?;
    let last = last_seq(&conn, survey_id)?;
    let mut samples = Vec::with_capacity(capacity(last));
    if read_pack(&conn, survey_id, last, &mut samples, None)? {
        return Ok(samples);
    }
    map_pages(&conn)?;
    read_rows(&conn, survey_id, false, samples, |_, _, _| ())
}

/// [`Store::samples_with_smr`], on the calling thread: from the survey's
/// pack when it has one, from its rows otherwise.
fn read_samples_with_smr(
    path: &std::path::Path,
    immutable: bool,
    survey_id: i64,
    before: Vec<[f64; 3]>,
) -> anyhow::Result<(Vec<Sample>, SmrPositions)> {
    let conn = open_reader(path, immutable)?;
    let last = last_seq(&conn, survey_id)?;
    // At most a position a sample.
    let (mut samples, mut smr) = (Vec::with_capacity(capacity(last)), SmrPositions::after(before, capacity(last)));
    if read_pack(&conn, survey_id, last, &mut samples, Some(&mut smr))? {
        return Ok((samples, smr));
    }
    map_pages(&conn)?;
    let mut pushed = Ok(());
    let samples = read_rows(&conn, survey_id, true, samples, |index, _, xyz| {
        if let Some(xyz_mm) = xyz
            && pushed.is_ok()
        {
            pushed = smr.push(index, xyz_mm);
        }
    })?;
    pushed.map(|()| (samples, smr))
}

/// Every sample of survey `survey_id` with its seq and SMR position, from
/// its rows: what its pack is written from.
fn read_records(path: &std::path::Path, immutable: bool, survey_id: i64) -> anyhow::Result<Vec<pack::Record>> {
    let conn = open_reader(path, immutable)?;
    map_pages(&conn)?;
    let mut found = Vec::with_capacity(capacity(last_seq(&conn, survey_id)?));
    let samples = read_rows(&conn, survey_id, true, Vec::new(), |_, seq, smr_mm| found.push((seq, smr_mm)))?;
    Ok(found.into_iter().zip(samples).map(|((seq, smr_mm), sample)| pack::Record { seq, sample, smr_mm }).collect())
}

/// Read the pack of survey `survey_id` into `samples` (and `smr`) when it
/// has one that ends at its last sample (seq `last`, [`last_seq`]): `true`.
/// `false`, with nothing read, when it has none, or one that cannot be read
/// (logged: the rows are read instead, the record).
fn read_pack(
    conn: &rusqlite::Connection,
    survey_id: i64,
    last_stored: Option<i64>,
    samples: &mut Vec<Sample>,
    mut smr: Option<&mut SmrPositions>,
) -> anyhow::Result<bool> {
    let mut stmt = conn
        .prepare("SELECT first_seq, count, format, data FROM sample_packs WHERE survey_id = ?1 ORDER BY first_seq")?;
    let mut rows = stmt.query([survey_id])?;
    let mut last = None;
    let read = (|| -> anyhow::Result<bool> {
        while let Some(row) = rows.next()? {
            let (first_seq, count, format): (i64, i64, i64) = (row.get(0)?, row.get(1)?, row.get(2)?);
            if format != pack::FORMAT {
                bail!("the pack from seq {first_seq} is of format {format}, not {}", pack::FORMAT);
            }
            let data = row.get_ref(3)?.as_blob()?;
            last = Some(pack::decode(data, first_seq, count, last, samples, smr.as_deref_mut())?);
        }
        match (last, last_stored) {
            (None, _) => Ok(false),
            (Some(l), Some(s)) if l == s => Ok(true),
            (Some(l), s) => bail!("the pack ends at seq {l}, the samples at {s:?}"),
        }
    })();
    match read {
        Ok(read) => Ok(read),
        Err(e) => {
            tracing::warn!(survey = survey_id, error = %format!("{e:#}"), "the sample pack is not used: the rows are read");
            samples.clear();
            if let Some(smr) = smr {
                smr.truncate_to_given();
            }
            Ok(false)
        }
    }
}

/// The highest seq of a survey's samples (`None` without any), from the
/// primary key alone (a `COUNT(*)` walks every row).
fn last_seq(conn: &rusqlite::Connection, survey_id: i64) -> anyhow::Result<Option<i64>> {
    Ok(conn.query_row("SELECT MAX(seq) FROM samples WHERE survey_id = ?1", [survey_id], |r| r.get(0))?)
}

/// Room for the samples up to seq `last`: as many as a survey has when its
/// seqs run from 0 without a gap (as a survey stores them). A capacity hint:
/// a stray huge seq reserves no more than [`MAX_RESERVED`].
fn capacity(last: Option<i64>) -> usize {
    last.and_then(|s| usize::try_from(s).ok()).map_or(0, |s| s.saturating_add(1)).min(MAX_RESERVED)
}

/// The most samples a reader reserves room for up front (the vector grows
/// beyond it as it must).
const MAX_RESERVED: usize = 1 << 26;

/// The samples of a survey in seq order from its rows, appended to `out`,
/// telling `each` every sample's index, seq and (with `smr_too`) the SMR
/// position behind it: the samples and the SMR rows each read in one pass in
/// seq order, merged (no join).
fn read_rows(
    conn: &rusqlite::Connection,
    survey_id: i64,
    smr_too: bool,
    mut out: Vec<Sample>,
    mut each: impl FnMut(usize, i64, Option<[f64; 3]>),
) -> anyhow::Result<Vec<Sample>> {
    let mut smr_stmt = match smr_too {
        true => Some(conn.prepare(
            "SELECT seq, smr_x_mm, smr_y_mm, smr_z_mm FROM raw_readings \
             WHERE survey_id = ?1 AND kind = 'smr' ORDER BY seq",
        )?),
        false => None,
    };
    let mut smr_rows = match &mut smr_stmt {
        Some(stmt) => Some(stmt.query([survey_id])?),
        None => None,
    };
    let mut next_smr = || -> anyhow::Result<Option<(i64, [f64; 3])>> {
        let Some(row) = smr_rows.as_mut().map(|r| r.next()).transpose()?.flatten() else { return Ok(None) };
        let xyz = |i: usize| -> rusqlite::Result<f64> { Ok(row.get::<_, Option<f64>>(i)?.unwrap_or(f64::NAN)) };
        Ok(Some((row.get(0)?, [xyz(1)?, xyz(2)?, xyz(3)?])))
    };
    let mut pending = next_smr()?;
    let mut stmt = conn.prepare(
        "SELECT seq, run, direction, target_deg, readout_deg, actual_deg, timestamp_s \
         FROM samples WHERE survey_id = ?1 ORDER BY seq",
    )?;
    let mut rows = stmt.query([survey_id])?;
    while let Some(row) = rows.next()? {
        let seq: i64 = row.get(0)?;
        let direction = match row.get_ref(2)?.as_str()? {
            "forward" => Direction::Forward,
            "reverse" => Direction::Reverse,
            other => bail!("sample seq {seq}: direction '{other}'"),
        };
        let run: i64 = row.get(1)?;
        // Both in seq order: a raw reading belongs to the sample of its seq.
        let mut smr = None;
        while let Some((raw_seq, xyz)) = pending {
            if raw_seq > seq {
                break;
            }
            if raw_seq == seq {
                smr = Some(xyz);
            }
            pending = next_smr()?;
        }
        each(out.len(), seq, smr);
        out.push(Sample {
            run: u32::try_from(run).with_context(|| format!("sample seq {seq}: bad run {run}"))?,
            direction,
            target_deg: row.get(3)?,
            readout_deg: row.get(4)?,
            actual_deg: row.get(5)?,
            timestamp_s: row.get(6)?,
        });
    }
    Ok(out)
}
