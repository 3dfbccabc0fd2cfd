//! The lab store: a laboratory's surveys in one PostgreSQL database
//! (`--db postgres://user:password@host:port/database`), copied there from
//! the stations' SQLite files by `survey push` ([`push`]), each exactly once
//! by its uid. Every read command reads it as it reads a station's file
//! (the same queries where the dialects agree: [`super::on_pool`]); nothing
//! else writes it, and acquisition stays on the station's file, so a network
//! outage during an overnight survey loses nothing.
//!
//! The schema is `migrations/postgres/`, kept in step with the SQLite one
//! migration by migration (a test compares the two); `survey push` sets it
//! up, a read command refuses a database without it.
//!
//! A password in the URL never leaves this module: messages, logs and the
//! store's name ([`Store::path`]) show the URL without it ([`redacted`]).
//! A URL that cannot be parsed, credentials the server refuses or a
//! database that does not exist are bad input (exit status 2, naming what);
//! a server that cannot be reached is a run-time failure (exit status 1,
//! naming the host).

mod push;

pub use push::{PushReport, Which, push};

use super::{Backend, NotFound, Store};
use crate::error::bad_input;
use sqlx::postgres::{PgConnectOptions, PgPoolOptions};
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Duration;

/// How long connecting to the lab store may take before it is called unreachable.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// The lab store's migrations, embedded (`migrations/postgres/`), the same
/// versions and descriptions as the SQLite ones.
pub(super) const MIGRATIONS: &[(i64, &str, &str)] = &[
    (1, "init", include_str!("../../migrations/postgres/0001_init.sql")),
    (2, "drift", include_str!("../../migrations/postgres/0002_drift.sql")),
    (3, "instrument time", include_str!("../../migrations/postgres/0003_instrument_time.sql")),
    (4, "check points", include_str!("../../migrations/postgres/0004_check_points.sql")),
    (5, "assets", include_str!("../../migrations/postgres/0005_assets.sql")),
    (6, "processing", include_str!("../../migrations/postgres/0006_processing.sql")),
    (8, "history cache", include_str!("../../migrations/postgres/0008_history_cache.sql")),
    (9, "environment", include_str!("../../migrations/postgres/0009_environment.sql")),
];

/// The oldest lab store schema a read command reads as it is (migration 8
/// adds only the history's cache; there is no migration 7 here).
const READS_FROM: i64 = 6;

fn migrator() -> sqlx::migrate::Migrator {
    use sqlx::SqlSafeStr as _;
    use sqlx::migrate::{Migration, MigrationType, Migrator};
    Migrator::with_migrations(
        MIGRATIONS
            .iter()
            .map(|&(v, d, sql)| Migration::new(v, Cow::Borrowed(d), MigrationType::Simple, sql.into_sql_str(), false))
            .collect(),
    )
}

/// The URL of `db`, when it names a lab store (`postgres://` or `postgresql://`).
pub fn url_of(db: &Path) -> Option<&str> {
    db.to_str().filter(|s| s.starts_with("postgres://") || s.starts_with("postgresql://"))
}

/// `url` without its password (and without its query, which may hold one):
/// `postgres://user@host:port/database`.
pub fn redacted(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else { return "the lab store".into() };
    let rest = rest.split(['?', '#']).next().unwrap_or_default();
    let (authority, path) = rest.split_once('/').map_or((rest, ""), |(a, p)| (a, p));
    let authority = match authority.rsplit_once('@') {
        Some((user, host)) => format!("{}@{host}", user.split(':').next().unwrap_or_default()),
        None => authority.to_string(),
    };
    format!("{scheme}://{authority}{}", if path.is_empty() { String::new() } else { format!("/{path}") })
}

/// How `--db` is shown: a file as it is, a lab store's URL without its password.
pub fn display(db: &Path) -> String {
    match url_of(db) {
        Some(url) => redacted(url),
        None => db.display().to_string(),
    }
}

/// A command that writes (`run`, `resume`, `import`) refuses a lab store:
/// acquisition stays on the station's SQLite file (bad input).
pub(super) fn refuse_writes(db: &Path) -> anyhow::Result<()> {
    match url_of(db) {
        Some(url) => Err(bad_input(format!(
            "{}: the lab store is read here and written only by `survey push --to URL`; surveys are acquired and \
             imported into a station's SQLite file (--db PATH)",
            redacted(url)
        ))),
        None => Ok(()),
    }
}

/// The error of a write attempted on the lab store.
pub(super) fn written_by_push(path: &Path) -> anyhow::Error {
    bad_input(format!("{}: the lab store is written only by `survey push`", path.display()))
}

/// Open the lab store at `url`: to read (`setup` false: its schema must be
/// there and current) or to push into (`setup` true: the schema is set up
/// or brought up to date).
pub async fn open(url: &str, setup: bool) -> anyhow::Result<Store> {
    let shown = redacted(url);
    let options = PgConnectOptions::from_str(url)
        .map_err(|e| bad_input(format!("--db {shown}: not a PostgreSQL URL ({})", reason(&e))))?;
    let (host, port) = (options.get_host().to_string(), options.get_port());
    let user = options.get_username().to_string();
    // No maintenance task (see `single_connection_pool`): one connection,
    // no idle timeout, no maximum lifetime, no minimum.
    let pool = PgPoolOptions::new()
        .max_connections(1)
        .min_connections(0)
        .idle_timeout(None)
        .max_lifetime(None)
        .acquire_timeout(CONNECT_TIMEOUT)
        .connect_with(options)
        .await
        .map_err(|e| connect_error(&e, &shown, &host, port, &user))?;
    let mut store = Store {
        backend: Backend::Lab(pool.clone()),
        path: PathBuf::from(&shown),
        immutable: false,
        writable: setup,
        cache: setup,
        environment: setup,
    };
    let ready = if setup {
        migrator().run(&pool).await.map_err(|e| anyhow::anyhow!("cannot set up the lab store {shown}: {e}"))
    } else {
        check_schema(&pool, &shown).await.map(|version| {
            store.cache = version >= super::CACHE_SCHEMA;
            store.environment = version >= super::ENVIRONMENT_SCHEMA;
        })
    };
    if let Err(e) = ready {
        store.close().await;
        return Err(e);
    }
    Ok(store)
}

/// The lab store's schema is there and one this version reads (its own,
/// or one from [`READS_FROM`] on, which lacks only the history's cache; a
/// read command never sets it up): its version.
async fn check_schema(pool: &sqlx::PgPool, shown: &str) -> anyhow::Result<i64> {
    let set_up: bool = sqlx::query_scalar("SELECT to_regclass('_sqlx_migrations') IS NOT NULL").fetch_one(pool).await?;
    let version: Option<i64> = if set_up {
        sqlx::query_scalar("SELECT MAX(version) FROM _sqlx_migrations WHERE success").fetch_one(pool).await?
    } else {
        None
    };
    let known = MIGRATIONS.last().map_or(0, |m| m.0);
    match version {
        None => Err(NotFound(format!(
            "{shown} is not a survey lab store yet (no survey tables): `survey push --to URL` sets it up"
        ))
        .into()),
        Some(v) if v > known => Err(NotFound(format!(
            "{shown} was set up by a newer version of survey (schema {v}; this version reads up to {known})"
        ))
        .into()),
        Some(v) if v < READS_FROM => Err(NotFound(format!(
            "{shown} has an older schema ({v}; this version reads {known}): `survey push --to URL` upgrades it"
        ))
        .into()),
        Some(v) => Ok(v),
    }
}

/// What a configuration error says, without its debug form (which would
/// show the options, the password among them).
fn reason(e: &sqlx::Error) -> String {
    match e {
        sqlx::Error::Configuration(inner) => inner.to_string(),
        other => other.to_string(),
    }
}

/// A connection that failed: refused credentials or a database that does
/// not exist are the user's (bad input), anything else (no route, refused,
/// timed out) a run-time failure; every message names the host.
fn connect_error(e: &sqlx::Error, shown: &str, host: &str, port: u16, user: &str) -> anyhow::Error {
    if let Some(db) = e.as_database_error() {
        let code = db.code().unwrap_or_default();
        // 28000 invalid authorization, 28P01 invalid password, 3D000 no such database.
        if code.starts_with("28") || code == "3D000" {
            return bad_input(format!(
                "the lab store at {host}:{port} refused the connection of {user} ({shown}): {}",
                db.message()
            ));
        }
        return anyhow::anyhow!("the lab store at {host}:{port} ({shown}) failed: {}", db.message());
    }
    let why = match e {
        sqlx::Error::PoolTimedOut => format!("no answer within {} s", CONNECT_TIMEOUT.as_secs()),
        sqlx::Error::Io(io) => io.to_string(),
        sqlx::Error::Tls(t) => format!("TLS: {t}"),
        other => reason(other),
    };
    anyhow::anyhow!("cannot reach the lab store at {host}:{port} ({shown}): {why}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_url_is_shown_without_its_password() {
        let shown = redacted("postgres://lab:s3cret@db.example:5433/surveys?sslmode=require&password=s3cret");
        assert_eq!(shown, "postgres://lab@db.example:5433/surveys");
        assert_eq!(redacted("postgresql://db.example/x"), "postgresql://db.example/x");
        assert_eq!(redacted("postgres://u:p:q@h"), "postgres://u@h");
        assert_eq!(display(Path::new("postgres://u:pw@h/d")), "postgres://u@h/d");
        assert_eq!(display(Path::new("station.db")), "station.db");
        assert!(url_of(Path::new("postgres.db")).is_none() && url_of(Path::new("postgres://h/d")).is_some());
    }

    #[tokio::test]
    async fn a_bad_url_is_bad_input_naming_it_and_a_write_is_refused() {
        let e = open("postgres://lab:s3cret@db.example:99999/x", false).await.unwrap_err();
        let text = format!("{e:#}");
        assert!(e.chain().any(|c| c.is::<crate::error::BadInput>()) && text.contains("not a PostgreSQL URL"), "{text}");
        assert!(text.contains("postgres://lab@db.example:99999/x") && !text.contains("s3cret"), "{text}");
        let e = Store::open(Path::new("postgres://lab:s3cret@h/x")).await.unwrap_err();
        let text = format!("{e:#}");
        assert!(
            e.chain().any(|c| c.is::<crate::error::BadInput>()) && text.contains("written only by `survey push"),
            "{text}"
        );
        assert!(!text.contains("s3cret"), "{text}");
    }
}
