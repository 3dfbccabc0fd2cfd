//! The history's cache (migration 8): per survey its measured summary, per
//! pair of consecutive surveys of an asset the comparison, each as bytes
//! the lab encodes (`survey_lab::life::cache`) and keyed by the program
//! version that made them. The store only keeps and finds them: what they
//! hold and when they are made is the lab's. Read on either backend;
//! written on a store opened to write (a station's file by a command that
//! writes, the lab store by `survey push`), each entry in a transaction of
//! its own, an entry already there left as it is.

use std::collections::HashMap;

use sqlx::Row as _;

use super::tx::WriteTx;
use super::{Backend, Store, on_pool};

/// Why an entry is not written.
fn read_only(store: &Store) -> anyhow::Error {
    anyhow::anyhow!(
        "{} was opened read-only: the history's cache is written by the commands that write",
        store.path.display()
    )
}

impl Store {
    /// Whether the history's cache tables are there (an SQLite file of
    /// schema 7, or a lab store of schema 6, read as it is, has none: every
    /// entry is then computed on read).
    pub fn has_history_cache(&self) -> bool {
        self.cache
    }

    /// The summaries of `version` of the surveys of `asset`, by survey id.
    pub async fn cached_summaries(&self, asset: &str, version: &str) -> anyhow::Result<HashMap<i64, Vec<u8>>> {
        if !self.cache {
            return Ok(HashMap::new());
        }
        let rows = on_pool!(self, |pool| {
            let rows = sqlx::query(
                "SELECT c.survey_id, c.data FROM survey_summaries AS c JOIN surveys AS s ON s.id = c.survey_id \
                 WHERE s.asset = $1 AND c.version = $2",
            )
            .bind(asset)
            .bind(version)
            .fetch_all(pool)
            .await?;
            rows.iter()
                .map(|r| Ok((r.try_get(0)?, r.try_get(1)?)))
                .collect::<Result<Vec<(i64, Vec<u8>)>, sqlx::Error>>()?
        });
        Ok(rows.into_iter().collect())
    }

    /// The summary of `version` of survey `id`, when there is one.
    pub async fn cached_summary(&self, id: i64, version: &str) -> anyhow::Result<Option<Vec<u8>>> {
        if !self.cache {
            return Ok(None);
        }
        Ok(on_pool!(self, |pool| {
            sqlx::query_scalar("SELECT data FROM survey_summaries WHERE survey_id = $1 AND version = $2")
                .bind(id)
                .bind(version)
                .fetch_optional(pool)
                .await?
        }))
    }

    /// The comparisons of `version` whose later survey is of `asset`, by
    /// `(the later survey's id, the earlier's uid)`.
    pub async fn cached_changes(&self, asset: &str, version: &str) -> anyhow::Result<HashMap<(i64, String), Vec<u8>>> {
        if !self.cache {
            return Ok(HashMap::new());
        }
        let rows = on_pool!(self, |pool| {
            let rows = sqlx::query(
                "SELECT c.survey_id, c.from_uid, c.data FROM survey_changes AS c JOIN surveys AS s \
                 ON s.id = c.survey_id WHERE s.asset = $1 AND c.version = $2",
            )
            .bind(asset)
            .bind(version)
            .fetch_all(pool)
            .await?;
            rows.iter()
                .map(|r| Ok(((r.try_get(0)?, r.try_get(1)?), r.try_get(2)?)))
                .collect::<Result<Vec<((i64, String), Vec<u8>)>, sqlx::Error>>()?
        });
        Ok(rows.into_iter().collect())
    }

    /// Keep the summary `data` of survey `id` made by `version`.
    pub async fn keep_summary(&self, id: i64, version: &str, data: &[u8]) -> anyhow::Result<()> {
        self.keep(
            "INSERT INTO survey_summaries (survey_id, version, data) VALUES ($1, $2, $3) ON CONFLICT DO NOTHING",
            id,
            &[version],
            data,
        )
        .await
    }

    /// Keep the comparison `data` of survey `from_uid` with the later survey
    /// `id` made by `version`.
    pub async fn keep_change(&self, id: i64, from_uid: &str, version: &str, data: &[u8]) -> anyhow::Result<()> {
        self.keep(
            "INSERT INTO survey_changes (survey_id, from_uid, version, data) VALUES ($1, $2, $3, $4) \
             ON CONFLICT DO NOTHING",
            id,
            &[from_uid, version],
            data,
        )
        .await
    }

    /// Run the insert `sql` of survey `id`, its text keys and its data, in a
    /// transaction of its own.
    async fn keep(&self, sql: &'static str, id: i64, keys: &[&str], data: &[u8]) -> anyhow::Result<()> {
        if !self.writable {
            return Err(read_only(self));
        }
        if !self.cache {
            return Ok(());
        }
        let what = || format!("cannot keep the history of survey {id} in {}", self.path.display());
        macro_rules! insert {
            ($pool:expr) => {{
                let mut tx = WriteTx::begin($pool).await?;
                let mut q = sqlx::query(sql).bind(id);
                for k in keys {
                    q = q.bind(*k);
                }
                match q.bind(data).execute(&mut *tx.conn()).await {
                    Ok(_) => tx.commit().await.map_err(|e| anyhow::Error::from(e).context(what()))?,
                    Err(e) => {
                        tx.abort().await;
                        return Err(self.fk_to_not_found(id, e).context(what()));
                    }
                }
            }};
        }
        match &self.backend {
            Backend::Sqlite(pool) => insert!(pool),
            Backend::Lab(pool) => insert!(pool),
        }
        Ok(())
    }
}
