//! What the check surveys of the recalibration loop decided (`checks`,
//! migration 5): one row per check survey, written when its comparison is
//! made and completed when a recalibration follows.

use serde::Serialize;
use sqlx::Row;

use super::tx::WriteTx;
use super::{Store, on_pool};

/// A check survey's decision.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckDecision {
    /// The check survey (this database's id).
    pub survey_id: i64,
    /// The calibration whose table was in force, compared with.
    pub against_uid: String,
    /// `unchanged` or `changed`.
    pub verdict: String,
    /// Whether that table still held on the check's data.
    pub table_holds: bool,
    /// Whether a recalibration was called for.
    pub recalibrate: bool,
    /// Why, in words.
    pub reason: String,
    /// The full survey made because of it, once made.
    pub recalibration_uid: Option<String>,
    /// The table file written for that survey (then the one in force).
    pub table_file: Option<String>,
    /// The largest residual the table in force left on the check's data, degrees.
    pub residual_peak_deg: Option<f64>,
    /// The `U` that table was held to, degrees.
    pub stated_u_deg: Option<f64>,
    /// The cells where the error moved by more than that `U`.
    pub cells_outside: Option<i64>,
    /// The most cells that may while the table holds.
    pub allowed_outside: Option<i64>,
}

impl Store {
    /// Store a check survey's decision (before any recalibration).
    pub async fn record_check(&self, d: &CheckDecision) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        sqlx::query(
            "INSERT INTO checks (survey_id, against_uid, verdict, table_holds, recalibrate, reason, \
             recalibration_uid, table_file, residual_peak_deg, stated_u_deg, cells_outside, allowed_outside) \
             VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(d.survey_id)
        .bind(&d.against_uid)
        .bind(&d.verdict)
        .bind(d.table_holds)
        .bind(d.recalibrate)
        .bind(&d.reason)
        .bind(&d.recalibration_uid)
        .bind(&d.table_file)
        .bind(d.residual_peak_deg)
        .bind(d.stated_u_deg)
        .bind(d.cells_outside)
        .bind(d.allowed_outside)
        .execute(tx.conn())
        .await
        .map_err(|e| self.fk_to_not_found(d.survey_id, e))?;
        tx.commit().await?;
        Ok(())
    }

    /// Record the recalibration a check called for: the new survey and its table file.
    pub async fn set_recalibration(&self, check_id: i64, uid: &str, table_file: Option<&str>) -> anyhow::Result<()> {
        let mut tx = WriteTx::begin(self.sqlite()?).await?;
        let done = sqlx::query("UPDATE checks SET recalibration_uid = ?, table_file = ? WHERE survey_id = ?")
            .bind(uid)
            .bind(table_file)
            .bind(check_id)
            .execute(tx.conn())
            .await?;
        if done.rows_affected() == 0 {
            tx.abort().await;
            return Err(self.no_survey(check_id).into());
        }
        tx.commit().await?;
        Ok(())
    }

    /// The decisions of the check surveys of `asset`, oldest first.
    /// A file of an older schema read as it is has no control figures: NULL.
    pub async fn checks_of_asset(&self, asset: &str) -> anyhow::Result<Vec<CheckDecision>> {
        let figures = match self.control {
            true => "c.residual_peak_deg, c.stated_u_deg, c.cells_outside, c.allowed_outside",
            false => {
                "CAST(NULL AS DOUBLE PRECISION) AS residual_peak_deg, CAST(NULL AS DOUBLE PRECISION) AS stated_u_deg, \
                 CAST(NULL AS BIGINT) AS cells_outside, CAST(NULL AS BIGINT) AS allowed_outside"
            }
        };
        let sql = format!(
            "SELECT c.survey_id, c.against_uid, c.verdict, c.table_holds, c.recalibrate, c.reason, \
             c.recalibration_uid, c.table_file, {figures} FROM checks AS c JOIN surveys AS s ON s.id = c.survey_id \
             WHERE s.asset = $1 ORDER BY c.survey_id"
        );
        on_pool!(self, |pool| {
            let rows = sqlx::query(sqlx::AssertSqlSafe(sql.clone())).bind(asset).fetch_all(pool).await?;
            rows.iter()
                .map(|r| -> anyhow::Result<CheckDecision> {
                    Ok(CheckDecision {
                        survey_id: r.try_get("survey_id")?,
                        against_uid: r.try_get("against_uid")?,
                        verdict: r.try_get("verdict")?,
                        table_holds: r.try_get("table_holds")?,
                        recalibrate: r.try_get("recalibrate")?,
                        reason: r.try_get("reason")?,
                        recalibration_uid: r.try_get("recalibration_uid")?,
                        table_file: r.try_get("table_file")?,
                        residual_peak_deg: r.try_get("residual_peak_deg")?,
                        stated_u_deg: r.try_get("stated_u_deg")?,
                        cells_outside: r.try_get("cells_outside")?,
                        allowed_outside: r.try_get("allowed_outside")?,
                    })
                })
                .collect()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::{MIGRATIONS, Store, single_connection_pool};
    use super::CheckDecision;
    use crate::survey::{NewSurvey, is_uid};
    use sqlx::migrate::{Migration, MigrationType, Migrator};
    use sqlx::sqlite::SqliteConnectOptions;
    use sqlx::{Row, SqlSafeStr};
    use std::borrow::Cow;

    /// A database of schema 3 (before assets), as the previous version wrote it.
    async fn schema_3_database(path: &std::path::Path) {
        let options = SqliteConnectOptions::new().filename(path).create_if_missing(true);
        let pool = single_connection_pool().connect_with(options).await.unwrap();
        let three = MIGRATIONS[..3]
            .iter()
            .map(|&(v, d, sql)| Migration::new(v, Cow::Borrowed(d), MigrationType::Simple, sql.into_sql_str(), false))
            .collect();
        Migrator::with_migrations(three).run(&pool).await.unwrap();
        for (source, config, instruments) in [
            ("simulated", r#"{"preset": "fig4"}"#, "{}"),
            ("import:a.csv", r#"{"imported_from": "a.csv"}"#, "{}"),
            ("instruments", r#"{"config": {"positioner": {}}}"#, "{}"),
            ("instruments", r#"{"config": {"asset": {"id": "bay-2/az"}}}"#, "{}"),
            ("verification", r#"{"config": {}}"#, r#"{"verifies_survey": 4}"#),
        ] {
            sqlx::query(
                "INSERT INTO surveys (status, source, config_json, instruments_json) VALUES ('complete', ?, ?, ?)",
            )
            .bind(source)
            .bind(config)
            .bind(instruments)
            .execute(&pool)
            .await
            .unwrap();
        }
        pool.close().await;
    }

    #[tokio::test]
    async fn surveys_stored_before_assets_get_uids_and_their_bench_s_asset_and_checks_are_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.db");
        schema_3_database(&path).await;
        let e = Store::open_read_only(&path).await.unwrap_err();
        assert!(
            format!("{e:#}")
                .contains(&format!("older schema (3; this version reads {})", MIGRATIONS.last().unwrap().0)),
            "{e:#}"
        );
        let store = Store::open(&path).await.unwrap();
        // (The setups above are cut short: read the columns themselves.)
        let rows =
            sqlx::query("SELECT uid, asset FROM surveys ORDER BY id").fetch_all(store.sqlite().unwrap()).await.unwrap();
        let (all_uids, assets): (Vec<String>, Vec<String>) =
            rows.iter().map(|r| (r.get::<String, _>(0), r.get::<String, _>(1))).unzip();
        assert_eq!(assets, ["sim-fig4", "unassigned", "unassigned", "bay-2/az", "bay-2/az"]);
        assert!(all_uids.iter().all(|u| is_uid(u) && u.as_bytes()[14] == b'4'), "{all_uids:?}");
        let mut uids: Vec<&str> = all_uids.iter().map(String::as_str).collect();
        uids.sort_unstable();
        uids.dedup();
        assert_eq!(uids.len(), 5);
        let import = store.survey_by_uid(&all_uids[1].to_uppercase()).await.unwrap();
        assert_eq!((import.id, import.asset.as_str(), import.uid.as_str()), (2, "unassigned", all_uids[1].as_str()));
        assert_eq!(store.resolve(Some(crate::survey::SurveyRef::Uid(all_uids[1].clone()))).await.unwrap().id, 2);
        let e = store.survey_by_uid("00000000-0000-4000-8000-000000000000").await.unwrap_err();
        assert!(super::super::is_not_found(&e), "{e:#}");
        // A new survey gets a uid of its own; the uid is unique.
        let id = store.create_survey(&NewSurvey { asset: "lab/new".into(), ..NewSurvey::default() }).await.unwrap();
        let new = store.survey(id).await.unwrap();
        assert!(is_uid(&new.uid) && !uids.contains(&new.uid.as_str()));
        let dup = sqlx::query("UPDATE surveys SET uid = ? WHERE id = 1")
            .bind(&new.uid)
            .execute(store.sqlite().unwrap())
            .await;
        assert!(dup.is_err(), "two surveys with one uid");
        assert_eq!(store.surveys_of_asset("lab/new").await.unwrap().iter().map(|r| r.id).collect::<Vec<_>>(), [id]);
        // A check's decision, then its recalibration.
        let d = CheckDecision {
            survey_id: id,
            against_uid: all_uids[3].clone(),
            verdict: "changed".into(),
            table_holds: false,
            recalibrate: true,
            reason: "the 20 cycles/rev line grew".into(),
            recalibration_uid: None,
            table_file: None,
            residual_peak_deg: Some(0.0012),
            stated_u_deg: Some(0.003),
            cells_outside: Some(3),
            allowed_outside: Some(9),
        };
        store.record_check(&d).await.unwrap();
        store.set_recalibration(id, &all_uids[4], Some("t.csv")).await.unwrap();
        let read = store.checks_of_asset("lab/new").await.unwrap();
        let done =
            CheckDecision { recalibration_uid: Some(all_uids[4].clone()), table_file: Some("t.csv".into()), ..d };
        assert_eq!(read, [done]);
        assert!(store.checks_of_asset("sim-fig4").await.unwrap().is_empty());
        let e = store.record_check(&CheckDecision { survey_id: 99, ..read[0].clone() }).await.unwrap_err();
        assert!(super::super::is_not_found(&e), "{e:#}");
        store.close().await;
    }
}
