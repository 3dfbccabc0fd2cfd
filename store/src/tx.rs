//! [`WriteTx`]: a write transaction that cannot outlive its failure.
//!
//! After a failed `COMMIT` (a full disk: `SQLITE_FULL`, `SQLITE_IOERR`)
//! SQLite may keep the transaction open; SQLite's documentation asks the
//! application to issue `ROLLBACK` itself. sqlx's `Transaction` did not on
//! that path: the next write on the same connection then ran inside the
//! transaction that never commits and reported success (seen on a full
//! tmpfs: the store claimed 4400 samples, the disk held 4300). So every
//! write transaction of the store goes through this guard: `BEGIN IMMEDIATE`
//! (the write lock is taken at once, and waited for up to the busy timeout),
//! the statements, `COMMIT`; on any failure an explicit `ROLLBACK`, and the
//! connection is closed instead of going back to the pool, so nothing of a
//! failed transaction can reach a later write. The lab store's writes
//! (`survey push`, PostgreSQL) go through the same guard (`BEGIN`).
//!
//! Each write transaction of an SQLite file is also sealed, last: the
//! header's `application_id` takes the `user_version` it found and
//! `user_version` a new random number. Page 1 then changes in every commit
//! and each of its images names the state it followed, so a write-ahead
//! log can be told to be this file's or another copy's by its first page-1
//! image (`crate::damage::file`): SQLite replays any log onto whatever file
//! it finds it beside, and in WAL mode need not count transactions in the
//! header's change counter (issue 51). Our design; SQLite leaves both
//! fields to the application (offsets 60 and 68 of the header).

use sqlx::pool::PoolConnection;
use sqlx::{Database, Executor, IntoArguments, Pool, Postgres, Sqlite};

/// A database the store writes in transactions, and how it begins one.
pub(super) trait TxDatabase: Database {
    /// The statement that opens a write transaction.
    const BEGIN: &'static str;

    /// Run last in every write transaction, before `COMMIT`.
    fn seal(conn: &mut Self::Connection) -> impl Future<Output = Result<(), sqlx::Error>> + Send;
}

impl TxDatabase for Sqlite {
    /// The write lock is taken at once (and waited for up to the busy timeout).
    const BEGIN: &'static str = "BEGIN IMMEDIATE";

    /// The file's chain: `application_id` = the `user_version` found,
    /// `user_version` = a new random number, never 0 (a file written before
    /// the chain reads 0) nor the one found.
    async fn seal(conn: &mut sqlx::SqliteConnection) -> Result<(), sqlx::Error> {
        let found: i64 = sqlx::query_scalar("PRAGMA user_version").fetch_one(&mut *conn).await?;
        let next = loop {
            use rand::TryRngCore as _;
            let mut b = [0u8; 4];
            rand::rngs::OsRng.try_fill_bytes(&mut b).map_err(|e| sqlx::Error::Io(std::io::Error::other(e)))?;
            let n = i64::from(i32::from_be_bytes(b));
            if n != 0 && n != found {
                break n;
            }
        };
        // PRAGMA takes no bound parameters: two integers, formatted.
        sqlx::query(sqlx::AssertSqlSafe(format!("PRAGMA application_id = {found}"))).execute(&mut *conn).await?;
        sqlx::query(sqlx::AssertSqlSafe(format!("PRAGMA user_version = {next}"))).execute(&mut *conn).await?;
        Ok(())
    }
}

impl TxDatabase for Postgres {
    const BEGIN: &'static str = "BEGIN";

    async fn seal(_: &mut sqlx::PgConnection) -> Result<(), sqlx::Error> {
        Ok(())
    }
}

/// An open write transaction on a connection of its own.
#[derive(Debug)]
pub(super) struct WriteTx<DB: TxDatabase = Sqlite> {
    conn: PoolConnection<DB>,
    open: bool,
}

impl<DB: TxDatabase> WriteTx<DB>
where
    for<'c> &'c mut DB::Connection: Executor<'c, Database = DB>,
    DB::Arguments: IntoArguments<DB>,
{
    /// [`TxDatabase::BEGIN`] on a connection from `pool`.
    pub(super) async fn begin(pool: &Pool<DB>) -> Result<WriteTx<DB>, sqlx::Error> {
        let mut conn = pool.acquire().await?;
        if let Err(e) = sqlx::query(DB::BEGIN).execute(&mut *conn).await {
            conn.close_on_drop();
            return Err(e);
        }
        Ok(WriteTx { conn, open: true })
    }

    /// The connection, to run the transaction's statements on.
    pub(super) fn conn(&mut self) -> &mut DB::Connection {
        &mut self.conn
    }

    /// `COMMIT`; on failure, roll back and retire the connection.
    pub(super) async fn commit(mut self) -> Result<(), sqlx::Error> {
        if let Err(e) = DB::seal(&mut self.conn).await {
            self.abort().await;
            return Err(e);
        }
        match sqlx::query("COMMIT").execute(&mut *self.conn).await {
            Ok(_) => {
                self.open = false;
                Ok(())
            }
            Err(e) => {
                self.abort().await;
                Err(e)
            }
        }
    }

    /// Roll back explicitly and retire the connection.
    pub(super) async fn abort(mut self) {
        if let Err(e) = sqlx::query("ROLLBACK").execute(&mut *self.conn).await {
            // Often SQLite rolled back already ("no transaction is active").
            tracing::debug!(%e, "ROLLBACK after a failed write failed; the connection is closed");
        }
        self.open = false;
        self.conn.close_on_drop();
    }
}

impl<DB: TxDatabase> Drop for WriteTx<DB> {
    /// Dropped open (an error path returned early, or the future was
    /// cancelled): closing the connection rolls the transaction back.
    fn drop(&mut self) {
        if self.open {
            self.conn.close_on_drop();
        }
    }
}
