//! The reference measurements of drift control ([`survey_plan::drift`]), stored
//! in `drift_points` (migration 2) in measurement order.

use super::tx::WriteTx;
use super::{Store, on_pool};
use sqlx::Row;
use survey_plan::drift::{DriftMeasurement, DriftPoint, drift_points};

impl Store {
    /// Store one measurement of the reference target after those stored.
    pub async fn add_drift_measurement(&self, id: i64, m: &DriftMeasurement) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
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
        on_pool!(self, |pool| {
            let rows = sqlx::query(
                "SELECT before_seq, at_s, reference_deg, readout_deg, actual_deg FROM drift_points \
                 WHERE survey_id = $1 ORDER BY idx",
            )
            .bind(id)
            .fetch_all(pool)
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
        })
    }

    /// The drift over time of survey `id`: `(time, drift)` points for a plot
    /// (empty without drift control).
    pub async fn drift_points(&self, id: i64) -> anyhow::Result<Vec<DriftPoint>> {
        Ok(drift_points(&self.drift_measurements(id).await?))
    }
}

#[cfg(test)]
mod tests {
    use super::super::{MIGRATIONS, Store, single_connection_pool};
    use sqlx::migrate::{Migration, MigrationType, Migrator};
    use sqlx::sqlite::SqliteConnectOptions;
    use sqlx::{Row, SqlSafeStr};
    use std::borrow::Cow;
    use survey_plan::drift::DriftMeasurement;

    /// A database of the first schema, as the previous version wrote it, with one survey.
    async fn schema_1_database(path: &std::path::Path) {
        let options = SqliteConnectOptions::new().filename(path).create_if_missing(true);
        let pool = single_connection_pool().connect_with(options).await.unwrap();
        let (version, description, sql) = MIGRATIONS[0];
        let first =
            Migration::new(version, Cow::Borrowed(description), MigrationType::Simple, sql.into_sql_str(), false);
        Migrator::with_migrations(vec![first]).run(&pool).await.unwrap();
        sqlx::query("INSERT INTO surveys (status, source) VALUES ('interrupted', 'simulated')")
            .execute(&pool)
            .await
            .unwrap();
        pool.close().await;
    }

    #[tokio::test]
    async fn a_database_of_schema_1_opens_upgraded_to_the_latest_with_its_surveys_and_stores_drift() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.db");
        schema_1_database(&path).await;
        // Read-only commands say it needs an upgrade, and leave it as it is.
        let e = Store::open_read_only(&path).await.unwrap_err();
        assert!(
            format!("{e:#}")
                .contains(&format!("older schema (1; this version reads {})", MIGRATIONS.last().unwrap().0)),
            "{e:#}"
        );
        // A command that writes upgrades it; the survey is still there.
        let store = Store::open(&path).await.unwrap();
        let versions: Vec<i64> = sqlx::query("SELECT version FROM _sqlx_migrations ORDER BY version")
            .fetch_all(store.sqlite().unwrap())
            .await
            .unwrap()
            .iter()
            .map(|r| r.get(0))
            .collect();
        assert_eq!(versions, MIGRATIONS.iter().map(|m| m.0).collect::<Vec<_>>());
        assert_eq!(store.survey(1).await.unwrap().id, 1);
        assert!(store.drift_points(1).await.unwrap().is_empty());
        let m = |seq, at_s, actual_deg| DriftMeasurement {
            before_seq: seq,
            at_s,
            reference_deg: 0.0,
            readout_deg: 0.0,
            actual_deg,
        };
        store.add_drift_measurement(1, &m(0, 10.0, -0.001)).await.unwrap();
        store.add_drift_measurement(1, &m(6, 70.0, -0.004)).await.unwrap();
        assert_eq!(store.drift_measurements(1).await.unwrap(), [m(0, 10.0, -0.001), m(6, 70.0, -0.004)]);
        let points = store.drift_points(1).await.unwrap();
        assert_eq!(points.len(), 2);
        assert!((points[1].drift_deg - 0.003).abs() < 1e-15 && points[1].at_s == 70.0);
        // A drift point of a survey that does not exist is refused.
        assert!(store.add_drift_measurement(9, &m(0, 1.0, 0.0)).await.is_err());
        store.close().await;
        // Now read-only commands read it.
        let reader = Store::open_read_only(&path).await.unwrap();
        assert_eq!(reader.drift_points(1).await.unwrap(), points);
        reader.close().await;
    }
}
