//! The certificates issued (migration 11): a survey's first `survey report`
//! issues its certificate (number, issue date, the page and the DCC as
//! issued), every later report reproduces it from here, and an amendment is
//! a new certificate of the same survey naming the one it replaces and why.
//! What a certificate holds is the report's; the store keeps it, finds it,
//! and refuses a number issued before (the table's key). Read on either
//! backend (a store of an older schema has none); written on a station's
//! file opened to write, and by `survey push` into the lab store.

use anyhow::Context as _;
use sqlx::Row as _;

use super::tx::WriteTx;
use super::{NotFound, Store, on_pool};

/// One certificate as issued.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Issued {
    /// Its number, unique in the store.
    pub number: String,
    /// The survey it certifies.
    pub survey_id: i64,
    /// 1 for the first issue, 2 for its first amendment, ...
    pub seq: i64,
    /// When it was issued, UTC, RFC 3339 to the second.
    pub issued_at: String,
    /// The number of the certificate it replaces (an amendment).
    pub replaces: Option<String>,
    /// Why it replaces it.
    pub reason: Option<String>,
    /// The page (`index.html`) as issued.
    pub page: String,
    /// The DCC (`dcc.xml`) as issued.
    pub dcc: String,
}

const SELECT: &str = "SELECT number, survey_id, seq, issued_at, replaces, reason, page, dcc FROM certificates \
                      WHERE survey_id = $1 ORDER BY seq";
const INSERT: &str = "INSERT INTO certificates (number, survey_id, seq, issued_at, replaces, reason, page, dcc) \
                      VALUES ($1, $2, $3, $4, $5, $6, $7, $8)";

impl Store {
    /// The next certificate number of `year` in the laboratory's sequence
    /// (`certificate_numbers`, migration 13): 1 for the year's first, one
    /// more than the last drawn otherwise, in one statement (two stations
    /// drawing at once get two numbers). Drawn from the lab store (`survey
    /// report --lab URL`, opened to write as a push opens it); a number drawn
    /// for a certificate that is then not issued is a gap, never reused.
    pub async fn draw_certificate_number(&self, year: i32) -> anyhow::Result<i64> {
        const DRAW: &str = "INSERT INTO certificate_numbers (year, last) VALUES ($1, 1) \
                            ON CONFLICT (year) DO UPDATE SET last = certificate_numbers.last + 1 RETURNING last";
        let n: i64 = on_pool!(self, |pool| sqlx::query_scalar(DRAW).bind(i64::from(year)).fetch_one(pool).await?);
        Ok(n)
    }

    /// Whether this store keeps certificates (schema 11 on; a file or a lab
    /// store of an older schema read as it is has none).
    pub fn keeps_certificates(&self) -> bool {
        self.certificates
    }

    /// The certificates of survey `id`, the first issued first.
    pub async fn certificates(&self, id: i64) -> anyhow::Result<Vec<Issued>> {
        if !self.certificates {
            return Ok(Vec::new());
        }
        let rows = on_pool!(self, |pool| {
            let rows = sqlx::query(SELECT).bind(id).fetch_all(pool).await?;
            rows.iter()
                .map(|r| {
                    Ok(Issued {
                        number: r.try_get(0)?,
                        survey_id: r.try_get(1)?,
                        seq: r.try_get(2)?,
                        issued_at: r.try_get(3)?,
                        replaces: r.try_get(4)?,
                        reason: r.try_get(5)?,
                        page: r.try_get(6)?,
                        dcc: r.try_get(7)?,
                    })
                })
                .collect::<Result<Vec<Issued>, sqlx::Error>>()?
        });
        Ok(rows)
    }

    /// The survey the certificate `number` was issued for, if it was.
    pub async fn certificate_number_issued(&self, number: &str) -> anyhow::Result<Option<i64>> {
        if !self.certificates {
            return Ok(None);
        }
        Ok(on_pool!(self, |pool| {
            sqlx::query_scalar("SELECT survey_id FROM certificates WHERE number = $1")
                .bind(number)
                .fetch_optional(pool)
                .await?
        }))
    }

    /// Keep the certificate `c` as issued, in a transaction of its own. A
    /// number issued before, or a certificate of the survey already at its
    /// `seq` (another report issued it meanwhile), is refused ([`NotFound`],
    /// bad input) and nothing is written.
    pub async fn issue(&self, c: &Issued) -> anyhow::Result<()> {
        if !self.writable || !self.certificates {
            return Err(NotFound(format!(
                "{} was opened read-only: a certificate is issued at the station (its survey file), then pushed",
                self.path.display()
            ))
            .into());
        }
        let what =
            || format!("cannot keep certificate {} of survey {} in {}", c.number, c.survey_id, self.path.display());
        if let Some(other) = self.certificate_number_issued(&c.number).await? {
            return Err(NotFound(format!(
                "certificate number {} is issued already (to survey {other} in {}): a number is issued once",
                c.number,
                self.path.display()
            ))
            .into());
        }
        macro_rules! insert {
            ($pool:expr) => {{
                let mut tx = WriteTx::begin($pool).await.with_context(what)?;
                let q = sqlx::query(INSERT)
                    .bind(&c.number)
                    .bind(c.survey_id)
                    .bind(c.seq)
                    .bind(&c.issued_at)
                    .bind(&c.replaces)
                    .bind(&c.reason)
                    .bind(&c.page)
                    .bind(&c.dcc);
                match q.execute(&mut *tx.conn()).await {
                    Ok(_) => tx.commit().await.with_context(what)?,
                    Err(e) => {
                        tx.abort().await;
                        if e.as_database_error().is_some_and(|d| d.is_unique_violation()) {
                            return Err(NotFound(format!(
                                "survey {} was issued certificate {} meanwhile (another report): read it with \
                                 `survey report`",
                                c.survey_id, c.seq
                            ))
                            .into());
                        }
                        return Err(self.fk_to_not_found(c.survey_id, e).context(what()));
                    }
                }
            }};
        }
        match &self.backend {
            super::Backend::Sqlite(pool) => insert!(pool),
            super::Backend::Lab(pool) => insert!(pool),
        }
        Ok(())
    }
}
