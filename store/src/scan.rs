//! Instrument time by component, and the passes of continuous scans with
//! their raw streams (migration 2).

use anyhow::{Context, bail};
use sqlx::Row;
use survey_processing::Direction;

use super::samples::insert_samples;
use super::tx::WriteTx;
use super::{Store, real};
use survey_acquire::ScanPassRecord;
use survey_plan::budget::{Component, Spent};
use survey_plan::pairing::Latency;

/// Records per stored chunk of a stream.
const CHUNK_RECORDS: usize = 16_384;

/// A stored pass, as read back.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredPass {
    pub pass: u32,
    pub run: u32,
    pub direction: Direction,
    pub velocity_deg_s: f64,
    pub latency: Latency,
    pub readout_captured: bool,
    /// Records of each stream: readouts, readout reads, tracker points, tracker reads.
    pub records: [u64; 4],
}

const STREAMS: [(&str, usize); 4] = [("readout", 2), ("readout_reads", 2), ("tracker", 5), ("tracker_reads", 2)];

fn encode(records: &[f64]) -> Vec<u8> {
    records.iter().flat_map(|v| v.to_le_bytes()).collect()
}

impl Store {
    /// Store a pass of a continuous scan with its samples and raw streams in
    /// one transaction: all of it or, on any error, none.
    pub async fn append_pass(&self, survey_id: i64, p: &ScanPassRecord) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await.with_context(|| {
            format!("cannot store pass {} of survey {survey_id} in {}", p.pass, self.path.display())
        })?;
        let written = async {
            insert_samples(tx.conn(), survey_id, &p.samples).await?;
            sqlx::query(
                "INSERT INTO scan_passes (survey_id, pass, run, direction, velocity_deg_s, latency_s, latency_se_s, \
                 readout_captured, readout_offset_s, readout_rate, tracker_offset_s, tracker_rate, started_at_s, \
                 ended_at_s) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            )
            .bind(survey_id)
            .bind(i64::from(p.pass))
            .bind(i64::from(p.run))
            .bind(p.direction.as_str())
            .bind(p.velocity_deg_s)
            .bind(p.latency_s)
            .bind(p.latency_se_s)
            .bind(p.readout_captured)
            .bind(p.readout_clock.0)
            .bind(p.readout_clock.1)
            .bind(p.tracker_clock.0)
            .bind(p.tracker_clock.1)
            .bind(p.started_at_s)
            .bind(p.ended_at_s)
            .execute(&mut *tx.conn())
            .await?;
            let flat2 = |v: &[[f64; 2]]| v.iter().flatten().copied().collect::<Vec<f64>>();
            let streams: [(&str, usize, Vec<f64>); 4] = [
                ("readout", 2, flat2(&p.readouts)),
                ("readout_reads", 2, flat2(&p.readout_fetches)),
                ("tracker", 5, p.points.iter().flatten().copied().collect()),
                ("tracker_reads", 2, flat2(&p.point_fetches)),
            ];
            for (stream, width, values) in streams {
                for (chunk, part) in values.chunks(CHUNK_RECORDS * width).enumerate() {
                    sqlx::query(
                        "INSERT INTO scan_streams (survey_id, pass, stream, chunk, records, data) \
                         VALUES (?, ?, ?, ?, ?, ?)",
                    )
                    .bind(survey_id)
                    .bind(i64::from(p.pass))
                    .bind(stream)
                    .bind(chunk as i64)
                    .bind((part.len() / width) as i64)
                    .bind(encode(part))
                    .execute(&mut *tx.conn())
                    .await?;
                }
            }
            anyhow::Ok(())
        }
        .await;
        if let Err(e) = written {
            tx.abort().await;
            return Err(e.context(format!(
                "cannot store pass {} of survey {survey_id} in {}",
                p.pass,
                self.path.display()
            )));
        }
        tx.commit().await.with_context(|| {
            format!("cannot commit pass {} of survey {survey_id} in {}", p.pass, self.path.display())
        })?;
        Ok(())
    }

    /// The passes stored for a survey, in order.
    pub async fn scan_passes(&self, survey_id: i64) -> anyhow::Result<Vec<StoredPass>> {
        let rows = sqlx::query(
            "SELECT p.pass, p.run, p.direction, p.velocity_deg_s, p.latency_s, p.latency_se_s, p.readout_captured, \
             (SELECT COALESCE(SUM(records), 0) FROM scan_streams s WHERE s.survey_id = p.survey_id AND s.pass = p.pass \
              AND s.stream = 'readout') AS n0, \
             (SELECT COALESCE(SUM(records), 0) FROM scan_streams s WHERE s.survey_id = p.survey_id AND s.pass = p.pass \
              AND s.stream = 'readout_reads') AS n1, \
             (SELECT COALESCE(SUM(records), 0) FROM scan_streams s WHERE s.survey_id = p.survey_id AND s.pass = p.pass \
              AND s.stream = 'tracker') AS n2, \
             (SELECT COALESCE(SUM(records), 0) FROM scan_streams s WHERE s.survey_id = p.survey_id AND s.pass = p.pass \
              AND s.stream = 'tracker_reads') AS n3 \
             FROM scan_passes p WHERE p.survey_id = ? ORDER BY p.pass",
        )
        .bind(survey_id)
        .fetch_all(self.sqlite()?)
        .await?;
        rows.iter()
            .map(|r| {
                let pass: i64 = r.try_get("pass")?;
                let run: i64 = r.try_get("run")?;
                let direction: String = r.try_get("direction")?;
                let n = |c: &str| r.try_get::<i64, _>(c).map(|v| u64::try_from(v).unwrap_or(0));
                Ok(StoredPass {
                    pass: u32::try_from(pass).context("bad pass")?,
                    run: u32::try_from(run).context("bad run")?,
                    direction: direction.parse().map_err(|e| anyhow::anyhow!("pass {pass}: {e}"))?,
                    velocity_deg_s: r.try_get("velocity_deg_s")?,
                    latency: Latency { delta_s: r.try_get("latency_s")?, se_s: real(r, "latency_se_s")? },
                    readout_captured: r.try_get("readout_captured")?,
                    records: [n("n0")?, n("n1")?, n("n2")?, n("n3")?],
                })
            })
            .collect::<anyhow::Result<Vec<_>>>()
            .with_context(|| format!("survey {survey_id} in {} holds a bad scan pass", self.path.display()))
    }

    /// One raw stream of a stored pass, as records of its width (see the migration).
    pub async fn scan_stream(&self, survey_id: i64, pass: u32, stream: &str) -> anyhow::Result<Vec<Vec<f64>>> {
        let Some(&(_, width)) = STREAMS.iter().find(|(s, _)| *s == stream) else { bail!("no stream '{stream}'") };
        let rows = sqlx::query(
            "SELECT records, data FROM scan_streams WHERE survey_id = ? AND pass = ? AND stream = ? ORDER BY chunk",
        )
        .bind(survey_id)
        .bind(i64::from(pass))
        .bind(stream)
        .fetch_all(self.sqlite()?)
        .await?;
        let mut out = Vec::new();
        for r in rows {
            let records: i64 = r.try_get("records")?;
            let data: Vec<u8> = r.try_get("data")?;
            if data.len() != records as usize * width * 8 {
                bail!(
                    "survey {survey_id} pass {pass}: the {stream} chunk holds {} bytes for {records} records",
                    data.len()
                );
            }
            let values: Vec<f64> =
                data.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes"))).collect();
            out.extend(values.chunks_exact(width).map(<[f64]>::to_vec));
        }
        Ok(out)
    }

    /// The latency removed from a survey's continuous passes (the last stored), if any.
    pub async fn scan_latency(&self, survey_id: i64) -> anyhow::Result<Option<Latency>> {
        Ok(self.scan_passes(survey_id).await?.last().map(|p| p.latency))
    }

    /// Add an acquisition's instrument time by component.
    pub async fn add_survey_time(&self, survey_id: i64, spent: &Spent) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let written = async {
            for (c, s) in spent.entries() {
                sqlx::query(
                    "INSERT INTO survey_time (survey_id, component, seconds) VALUES (?, ?, ?) \
                     ON CONFLICT (survey_id, component) DO UPDATE SET seconds = seconds + excluded.seconds",
                )
                .bind(survey_id)
                .bind(c.as_str())
                .bind(s)
                .execute(&mut *tx.conn())
                .await?;
            }
            anyhow::Ok(())
        }
        .await;
        if let Err(e) = written {
            tx.abort().await;
            return Err(e.context(format!("cannot store the instrument time of survey {survey_id}")));
        }
        tx.commit().await?;
        Ok(())
    }

    /// A survey's instrument time by component, as stored.
    pub async fn survey_time(&self, survey_id: i64) -> anyhow::Result<Spent> {
        let rows = sqlx::query("SELECT component, seconds FROM survey_time WHERE survey_id = ?")
            .bind(survey_id)
            .fetch_all(self.sqlite()?)
            .await?;
        let mut spent = Spent::default();
        for r in rows {
            let name: String = r.try_get("component")?;
            let c = Component::from_name(&name)
                .with_context(|| format!("survey {survey_id}: unknown time component '{name}'"))?;
            spent.add(c, r.try_get("seconds")?);
        }
        Ok(spent)
    }
}
