//! Check points (`survey_lab::resolving`): a survey's samples between its
//! targets, measured after its runs, stored with it (`check_points`).

use super::tx::WriteTx;
use super::{Store, on_pool};
use anyhow::{Context as _, anyhow};
use sqlx::Row as _;
use std::str::FromStr as _;
use survey_processing::{Direction, Sample};

/// The tables a survey's rows live in, children first.
const SURVEY_TABLES: &[&str] = &[
    "survey_summaries",
    "survey_changes",
    "sample_packs",
    "smr_readings",
    "raw_readings",
    "samples",
    "events",
    "locate_points",
    "drift_points",
    "survey_time",
    "scan_streams",
    "scan_passes",
    "check_points",
];

impl Store {
    /// Fold the samples of survey `from` (check points acquired to their own
    /// plan) into the check points of survey `into`, replacing any it had,
    /// and remove survey `from` with everything of it but its events, which
    /// `into` keeps ("check points: ..."): one transaction.
    /// Returns how many check points `into` now holds.
    pub async fn fold_check_points(&self, from: i64, into: i64) -> anyhow::Result<u64> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let folded = async {
            sqlx::query("DELETE FROM check_points WHERE survey_id = ?").bind(into).execute(tx.conn()).await?;
            // What the history kept of `into` was measured without them.
            sqlx::query("DELETE FROM survey_summaries WHERE survey_id = ?").bind(into).execute(tx.conn()).await?;
            sqlx::query(
                "DELETE FROM survey_changes WHERE survey_id = ? OR from_uid = (SELECT uid FROM surveys WHERE id = ?)",
            )
            .bind(into)
            .bind(into)
            .execute(tx.conn())
            .await?;
            let n = sqlx::query(
                "INSERT INTO check_points (survey_id, seq, run, direction, target_deg, readout_deg, actual_deg, \
                 timestamp_s) SELECT ?, seq, run, direction, target_deg, readout_deg, actual_deg, timestamp_s \
                 FROM samples WHERE survey_id = ?",
            )
            .bind(into)
            .bind(from)
            .execute(tx.conn())
            .await?
            .rows_affected();
            // What happened while they were measured (every fault met, each
            // asked again) stays in the survey's log, said to be theirs.
            sqlx::query(
                "INSERT INTO events (survey_id, at_s, level, message) SELECT ?, at_s, level, \
                 'check points: ' || message FROM events WHERE survey_id = ? ORDER BY id",
            )
            .bind(into)
            .bind(from)
            .execute(tx.conn())
            .await?;
            for table in SURVEY_TABLES {
                sqlx::query(sqlx::AssertSqlSafe(format!("DELETE FROM {table} WHERE survey_id = ?")))
                    .bind(from)
                    .execute(tx.conn())
                    .await?;
            }
            sqlx::query("DELETE FROM surveys WHERE id = ?").bind(from).execute(tx.conn()).await?;
            anyhow::Ok(n)
        }
        .await;
        match folded {
            Ok(n) => {
                tx.commit().await?;
                Ok(n)
            }
            Err(e) => {
                tx.abort().await;
                Err(e.context(format!("cannot fold the check points of survey {from} into survey {into}")))
            }
        }
    }

    /// The check points of survey `id`, in acquisition order (none: empty).
    pub async fn check_points(&self, id: i64) -> anyhow::Result<Vec<Sample>> {
        on_pool!(self, |pool| {
            let rows = sqlx::query(
                "SELECT seq, run, direction, target_deg, readout_deg, actual_deg, timestamp_s FROM check_points \
                 WHERE survey_id = $1 ORDER BY seq",
            )
            .bind(id)
            .fetch_all(pool)
            .await
            .with_context(|| format!("cannot read the check points of survey {id}"))?;
            rows.iter()
                .map(|row| {
                    let seq: i64 = row.try_get("seq")?;
                    let run: i64 = row.try_get("run")?;
                    let direction: String = row.try_get("direction")?;
                    Ok(Sample {
                        run: u32::try_from(run).with_context(|| format!("check point {seq}: bad run {run}"))?,
                        direction: Direction::from_str(&direction).map_err(|e| anyhow!("check point {seq}: {e}"))?,
                        target_deg: row.try_get("target_deg")?,
                        readout_deg: row.try_get("readout_deg")?,
                        actual_deg: row.try_get("actual_deg")?,
                        timestamp_s: row.try_get("timestamp_s")?,
                    })
                })
                .collect()
        })
    }
}
