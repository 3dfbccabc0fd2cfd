//! The reference measurements of drift control ([`crate::drift`]), stored
//! in `drift_points` (migration 2) in measurement order.

use super::Store;
use super::tx::WriteTx;
use crate::drift::{DriftMeasurement, DriftPoint, drift_points};
use sqlx::Row;

impl Store {
    /// Store one measurement of the reference target after those stored.
    pub async fn add_drift_measurement(&self, id: i64, m: &DriftMeasurement) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(&self.pool).await?;
        sqlx::query(
            "INSERT INTO drift_points (survey_id, idx, before_seq, at_s, reference_deg, readout_deg, actual_deg) \
             SELECT ?, COALESCE(MAX(idx) + 1, 0), ?, ?, ?, ?, ? FROM drift_points WHERE survey_id = ?",
        )
        .bind(id)
        .bind(m.before_seq as i64)
        .bind(m.at_s)
        .bind(m.reference_deg)
        .bind(m.readout_deg)
        .bind(m.actual_deg)
        .bind(id)
        .execute(tx.conn())
        .await
        .map_err(|e| self.fk_to_not_found(id, e).context(format!("cannot store a drift measurement of survey {id}")))?;
        tx.commit().await?;
        Ok(())
    }

    /// The reference measurements of survey `id`, in measurement order.
    pub async fn drift_measurements(&self, id: i64) -> anyhow::Result<Vec<DriftMeasurement>> {
        let rows = sqlx::query(
            "SELECT before_seq, at_s, reference_deg, readout_deg, actual_deg FROM drift_points \
             WHERE survey_id = ? ORDER BY idx",
        )
        .bind(id)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| -> anyhow::Result<DriftMeasurement> {
                Ok(DriftMeasurement {
                    before_seq: u64::try_from(r.try_get::<i64, _>("before_seq")?)?,
                    at_s: r.try_get("at_s")?,
                    reference_deg: r.try_get("reference_deg")?,
                    readout_deg: r.try_get("readout_deg")?,
                    actual_deg: r.try_get("actual_deg")?,
                })
            })
            .collect()
    }

    /// The drift over time of survey `id`: `(time, drift)` points for a plot
    /// (empty without drift control).
    pub async fn drift_points(&self, id: i64) -> anyhow::Result<Vec<DriftPoint>> {
        Ok(drift_points(&self.drift_measurements(id).await?))
    }
}
