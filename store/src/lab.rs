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
//! A URL that cannot be parsed, credentials the server refuses, a database
//! that does not exist or a role without the privilege to push are bad
//! input (exit status 2, naming what, and for a privilege what to grant); a
//! server that cannot be reached, refuses the connection or goes away is a
//! run-time failure (exit status 1, naming the host): each said in words
//! once ([`explained`]), never as the driver's or the server's internals.
//!
//! TLS is rustls (sqlx's `tls-rustls-ring-native-roots`): the URL's
//! `sslmode` (`require`, `verify-ca`, `verify-full`) and `sslrootcert` (a
//! CA's PEM file; the system's roots otherwise) as libpq reads them.

mod push;
mod schema;

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
    (10, "smr readings", include_str!("../../migrations/postgres/0010_smr_readings.sql")),
    (11, "certificates", include_str!("../../migrations/postgres/0011_certificates.sql")),
    (12, "intervals", include_str!("../../migrations/postgres/0012_intervals.sql")),
    (13, "certificate numbers", include_str!("../../migrations/postgres/0013_certificate_numbers.sql")),
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
    root_certificate_readable(url, &shown)?;
    // One connection first, on its own: the pool retries a refused one until
    // its timeout, where a refusal is said at once.
    match tokio::time::timeout(CONNECT_TIMEOUT, sqlx::ConnectOptions::connect(&options)).await {
        Ok(Ok(first)) => {
            let _ = sqlx::Connection::close(first).await;
        }
        Ok(Err(e)) => return Err(connect_error(&e, &shown, &host, port, &user)),
        Err(_) => return Err(connect_error(&sqlx::Error::PoolTimedOut, &shown, &host, port, &user)),
    }
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
        control: setup,
        certificates: setup,
    };
    let ready = if setup {
        set_up(&pool, &shown).await.map(|()| MIGRATIONS.last().map_or(0, |m| m.0))
    } else {
        check_schema(&pool, &shown).await.inspect(|&version| {
            store.cache = version >= super::CACHE_SCHEMA;
            store.environment = version >= super::ENVIRONMENT_SCHEMA;
            store.control = version >= super::CONTROL_SCHEMA;
            store.certificates = version >= super::CERTIFICATE_SCHEMA;
        })
    };
    // Every table, column and index of that version there, and the role's
    // privileges on them (`schema`).
    let ready = match ready {
        Ok(version) => schema::check(&pool, &shown, &user, version, setup).await,
        Err(e) => Err(e),
    };
    let at = Server { host, port, user };
    let ready = ready.map_err(|e| explained(e, &at, if setup { PUSHING } else { "reading its schema" }));
    if let Err(e) = ready {
        store.close().await;
        return Err(e);
    }
    Ok(store)
}

/// Set the lab store's schema up or bring it up to date; one already
/// current is left as it is (so a role that may write the tables but not
/// create any pushes into a store set up before).
async fn set_up(pool: &sqlx::PgPool, shown: &str) -> anyhow::Result<()> {
    let known = MIGRATIONS.last().map_or(0, |m| m.0);
    if matches!(check_schema(pool, shown).await, Ok(v) if v == known) {
        return Ok(());
    }
    migrator()
        .run(pool)
        .await
        .map_err(|e| anyhow::Error::new(e).context(format!("cannot set up the lab store {shown}")))
}

/// Where the lab store is and who connects: what its messages name.
#[derive(Debug, Clone)]
pub struct Server {
    host: String,
    port: u16,
    user: String,
}

impl Server {
    /// The server of the lab store `url` (`None`: not a PostgreSQL URL).
    pub fn of(url: &str) -> Option<Server> {
        let o = PgConnectOptions::from_str(url).ok()?;
        Some(Server { host: o.get_host().to_string(), port: o.get_port(), user: o.get_username().to_string() })
    }
}

/// What [`explained`] is told while pushing (a missing privilege is then one to write).
pub const PUSHING: &str = "pushing";

/// [`explained`] where `db` is the lab store's URL; `e` as it is otherwise
/// (a station's file).
pub fn explained_at(db: &Path, e: anyhow::Error, doing: &str) -> anyhow::Error {
    match url_of(db).and_then(Server::of) {
        Some(at) => explained(e, &at, doing),
        None => e,
    }
}

/// `e` (or what its chain holds: a migration's sqlx error) with the lab store's failure said in words, once: the server gone
/// away (shut down, restarted, the connection closed or reset), a connection
/// refused, a privilege missing (what to grant, bad input); the contexts
/// above it (`cannot push survey 3 (uid)`, `copying its samples`) kept.
/// Anything else is `e` as it was. `doing` says what was under way when
/// nothing above says it.
pub fn explained(e: anyhow::Error, at: &Server, doing: &str) -> anyhow::Error {
    let Some((depth, sqlx_error)) =
        e.chain().enumerate().find_map(|(i, c)| c.downcast_ref::<sqlx::Error>().map(|s| (i, s)))
    else {
        return e;
    };
    let Some((words, bad)) = in_words(sqlx_error, at, doing == PUSHING) else { return e };
    // A migration's error repeats the database's words: left out.
    let above: Vec<String> =
        e.chain().take(depth).filter(|c| !c.is::<sqlx::migrate::MigrateError>()).map(|c| c.to_string()).collect();
    let text = if above.is_empty() { format!("{doing}: {words}") } else { format!("{}: {words}", above.join(": ")) };
    if bad { bad_input(text) } else { anyhow::anyhow!(text) }
}

/// What PostgreSQL's code says happened to the connection, in words (`None`:
/// not the connection's end).
fn gone_in_words(code: &str) -> Option<&'static str> {
    Some(match code {
        // admin_shutdown: the server is stopping, or the backend was terminated.
        "57P01" => "the server ended the connection (it is shutting down, or an administrator terminated the session)",
        "57P02" => "the server ended the connection (it crashed and is restarting)",
        "57P03" => "the server does not take connections now (it is starting up or shutting down)",
        "57P05" => "the server ended the connection (idle for too long)",
        c if c.starts_with("08") => "the connection to the server failed",
        _ => return None,
    })
}

/// An I/O failure on the connection in words (`None`: not one of those).
fn io_in_words(kind: std::io::ErrorKind) -> Option<&'static str> {
    use std::io::ErrorKind as K;
    Some(match kind {
        K::ConnectionRefused => "the connection was refused (no server listens there, or a firewall refuses it)",
        K::UnexpectedEof | K::ConnectionReset | K::ConnectionAborted | K::BrokenPipe => {
            "the server closed the connection (it went away: stopped, restarted, or the network dropped it)"
        }
        K::TimedOut => "the connection timed out (the network or the server does not answer)",
        _ => return None,
    })
}

/// A failure of the connection to `host`:`port` itself (not the server's
/// answer) in words: I/O, a name that does not resolve, TLS, a reply that is
/// not PostgreSQL's.
fn link_in_words(e: &sqlx::Error, host: &str, port: u16) -> Option<String> {
    match e {
        sqlx::Error::Io(io) => {
            // The connection's end first: a server stopped at once under TLS
            // is rustls's "peer closed connection without sending TLS
            // close_notify: https://docs.rs/...", an unexpected end of file.
            if let Some(w) = io_in_words(io.kind()) {
                return Some(w.to_string());
            }
            let text = io.to_string();
            // The resolver's words (glibc's, or sqlx's for a name with no address).
            if ["failed to lookup address", "Name or service not known", "name resolution", "did not resolve"]
                .iter()
                .any(|w| text.contains(w))
            {
                return Some(format!("cannot find host {host} (the name has no address: check it, and the DNS)"));
            }
            if ["certificate", "TLS", "tls", "corrupt message"].iter().any(|w| text.contains(w)) {
                return Some(tls_in_words(&text, host, port));
            }
            None
        }
        sqlx::Error::Tls(t) => Some(tls_in_words(&t.to_string(), host, port)),
        // The first reply to TLS's request read as 0 bytes: the connection was closed.
        sqlx::Error::Protocol(p) if p.contains("SSLRequest") => Some(
            "the server closed the connection as soon as it was made (it went away, or is not a PostgreSQL \
             server)"
                .into(),
        ),
        _ => None,
    }
}

/// `e` in words naming the server, and whether it is the user's (bad input).
fn in_words(e: &sqlx::Error, at: &Server, pushing: bool) -> Option<(String, bool)> {
    let Server { host, port, user } = at;
    if let Some(db) = e.as_database_error() {
        let code = db.code().unwrap_or_default();
        if code == "42501" && !pushing {
            return Some((
                format!(
                    "the role {user} may not read the lab store at {host}:{port} ({}): docs/lab.md, \"Roles\": \
                     `GRANT USAGE ON SCHEMA public TO {user}; GRANT SELECT ON ALL TABLES IN SCHEMA public TO {user}`",
                    db.message()
                ),
                true,
            ));
        }
        if code == "42501" {
            return Some((
                format!(
                    "the role {user} may not write the lab store at {host}:{port} ({}): `survey push` needs a role that \
                     may create tables in the database for the first push (its owner: `createdb --owner {user} ...`), \
                     and SELECT, INSERT and UPDATE on its tables and USAGE on its sequences for every push (docs/lab.md, \
                     \"Roles\": `GRANT SELECT, INSERT, UPDATE ON ALL TABLES IN SCHEMA public TO {user}; GRANT USAGE ON \
                     ALL SEQUENCES IN SCHEMA public TO {user}`)",
                    db.message()
                ),
                true,
            ));
        }
        return gone_in_words(&code).map(|w| (format!("the lab store at {host}:{port}: {w}"), false));
    }
    if let Some(w) = link_in_words(e, host, *port) {
        return Some((format!("the lab store at {host}:{port}: {w}"), false));
    }
    match e {
        sqlx::Error::PoolTimedOut => Some((
            format!("the lab store at {host}:{port} gave no connection within {} s", CONNECT_TIMEOUT.as_secs()),
            false,
        )),
        sqlx::Error::PoolClosed | sqlx::Error::WorkerCrashed => {
            Some((format!("the connection to the lab store at {host}:{port} was lost"), false))
        }
        _ => None,
    }
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

/// The URL's `sslrootcert` (a CA's PEM file) named when it cannot serve:
/// missing, unreadable or not a PEM certificate, before any connection is
/// tried (the TLS library would say only "No such file or directory" or
/// "not signed by a known authority").
fn root_certificate_readable(url: &str, shown: &str) -> anyhow::Result<()> {
    let Ok(parsed) = url::Url::parse(url) else { return Ok(()) };
    let Some((_, path)) = parsed.query_pairs().find(|(k, _)| k == "sslrootcert") else { return Ok(()) };
    let text = std::fs::read(path.as_ref()).map_err(|e| {
        bad_input(format!("--db {shown}: sslrootcert={path}: cannot read the CA's certificate file: {e}"))
    })?;
    if !String::from_utf8_lossy(&text).contains("-----BEGIN CERTIFICATE-----") {
        return Err(bad_input(format!(
            "--db {shown}: sslrootcert={path} is not a PEM certificate file (no \"-----BEGIN CERTIFICATE-----\" \
             line): give the CA's certificate in PEM form"
        )));
    }
    Ok(())
}

/// What a configuration error says, without its debug form (which would
/// show the options, the password among them) and without sqlx's "error
/// with configuration:" (twice where it wraps its own error).
fn reason(e: &sqlx::Error) -> String {
    let mut text = match e {
        sqlx::Error::Configuration(inner) => inner.to_string(),
        other => other.to_string(),
    };
    while let Some(rest) = text.strip_prefix("error with configuration: ") {
        text = rest.to_string();
    }
    text
}

/// A connection that failed: refused credentials or a database that does
/// not exist are the user's (bad input), anything else (no route, refused,
/// timed out) a run-time failure; every message names the host.
fn connect_error(e: &sqlx::Error, shown: &str, host: &str, port: u16, user: &str) -> anyhow::Error {
    if let Some(db) = e.as_database_error() {
        let code = db.code().unwrap_or_default();
        // 28000 invalid authorization, 28P01 invalid password, 3D000 no such database.
        if code.starts_with("28") || code == "3D000" {
            // pg_hba.conf's `hostnossl ... reject`: a server that takes TLS only.
            let hint = if db.message().contains("no encryption") {
                ": the server takes only encrypted connections; add `?sslmode=require` to the URL (or \
                 `?sslmode=verify-full&sslrootcert=CA.pem` to check its certificate)"
            } else {
                ""
            };
            return bad_input(format!(
                "the lab store at {host}:{port} refused the connection of {user} ({shown}): {}{hint}",
                db.message()
            ));
        }
        if let Some(w) = gone_in_words(&code) {
            return anyhow::anyhow!("cannot reach the lab store at {host}:{port} ({shown}): {w}");
        }
        return anyhow::anyhow!("the lab store at {host}:{port} ({shown}) failed: {}", db.message());
    }
    let why = match e {
        sqlx::Error::PoolTimedOut => format!("no answer within {} s", CONNECT_TIMEOUT.as_secs()),
        other => match link_in_words(other, host, port) {
            Some(w) => w,
            None => reason(other),
        },
    };
    anyhow::anyhow!("cannot reach the lab store at {host}:{port} ({shown}): {why}")
}

/// A library's text without the links it adds (rustls points at its
/// manual on docs.rs): the words up to the first `http`.
fn without_links(t: &str) -> String {
    match t.find("http://").or_else(|| t.find("https://")) {
        Some(at) => {
            let t = t[..at].trim_end_matches([' ', ':', '(', '-']);
            let t = t.strip_suffix("see").unwrap_or(t);
            t.trim_end_matches([' ', ':', '(', '-', ',']).to_string()
        }
        None => t.to_string(),
    }
}

/// A TLS failure (talking to `host`:`port`) in words: what the server's
/// certificate lacks, what the URL can say.
fn tls_in_words(t: &str, host: &str, port: u16) -> String {
    let why = if t.contains("InvalidContentType") || t.contains("corrupt message") {
        // rustls's "received corrupt message of type InvalidContentType": the reply is not a TLS record.
        format!(
            "the server at {host}:{port} answered something that is not TLS (not PostgreSQL with TLS, or a proxy in \
             the way)"
        )
    } else if t.contains("UnknownIssuer") {
        "the server's certificate is not signed by a known authority: give its CA's PEM file with \
         `sslrootcert=PATH` in the URL"
            .to_string()
    } else if t.contains("NotValidForName") {
        "the server's certificate is not made out to this host name (`sslmode=verify-ca` checks the authority only)"
            .to_string()
    } else if t.contains("Expired") {
        "the server's certificate has expired".to_string()
    } else if t.contains("server does not support TLS") {
        "the server does not take encrypted connections (ssl = off): remove `sslmode` from the URL or turn TLS on \
         at the server"
            .to_string()
    } else {
        without_links(t)
    };
    format!("TLS: {why}")
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

    /// Issue 51: a missing or non-PEM `sslrootcert` is named before any
    /// connection, with the URL shown without its password; a PEM file passes.
    #[test]
    fn a_root_certificate_that_cannot_serve_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let url = |f: &str| format!("postgres://lab:s3cret@db/x?sslmode=verify-full&sslrootcert={f}");
        let missing = dir.path().join("none.pem").display().to_string();
        let e = format!("{:#}", root_certificate_readable(&url(&missing), "postgres://lab@db/x").unwrap_err());
        assert!(e.contains(&format!("sslrootcert={missing}: cannot read")) && !e.contains("s3cret"), "{e}");
        let der = dir.path().join("ca.der");
        std::fs::write(&der, [0x30u8, 0x82, 0x01, 0x0a]).unwrap();
        let e = format!("{:#}", root_certificate_readable(&url(&der.display().to_string()), "x").unwrap_err());
        assert!(e.contains("is not a PEM certificate file"), "{e}");
        let pem = dir.path().join("ca.pem");
        std::fs::write(&pem, "-----BEGIN CERTIFICATE-----\nMIIB\n-----END CERTIFICATE-----\n").unwrap();
        root_certificate_readable(&url(&pem.display().to_string()), "x").unwrap();
        root_certificate_readable("postgres://lab@db/x?sslmode=require", "x").unwrap();
    }

    #[test]
    fn a_server_going_away_is_said_in_words_once_naming_the_host() {
        let at = Server::of("postgres://lab:s3cret@db.example:5433/x").unwrap();
        let eof =
            std::io::Error::new(std::io::ErrorKind::UnexpectedEof, "expected to read 5 bytes, got 0 bytes at EOF");
        let e = anyhow::Error::new(sqlx::Error::Io(eof)).context("copying its samples").context("cannot push survey 3");
        let text = format!("{:#}", explained(e, &at, "pushing"));
        assert_eq!(
            text,
            "cannot push survey 3: copying its samples: the lab store at db.example:5433: the server closed the \
             connection (it went away: stopped, restarted, or the network dropped it)"
        );
        let e = explained(anyhow::Error::new(sqlx::Error::PoolTimedOut), &at, "listing its surveys");
        assert_eq!(
            format!("{e:#}"),
            "listing its surveys: the lab store at db.example:5433 gave no connection within 10 s"
        );
        // A server stopped at once under TLS: rustls's end of file, in words, without its link.
        let rustls = std::io::Error::new(
            std::io::ErrorKind::UnexpectedEof,
            "peer closed connection without sending TLS close_notify: \
             https://docs.rs/rustls/latest/rustls/manual/_03_howto/index.html#unexpected-eof",
        );
        let e = explained(anyhow::Error::new(sqlx::Error::Io(rustls)), &at, "listing its surveys");
        assert_eq!(
            format!("{e:#}"),
            "listing its surveys: the lab store at db.example:5433: the server closed the connection (it went away: \
             stopped, restarted, or the network dropped it)"
        );
        assert_eq!(without_links("bad record: https://docs.rs/x"), "bad record");
        assert_eq!(tls_in_words("odd (see https://docs.rs/y)", "h", 1), "TLS: odd");
        assert!(gone_in_words("57P01").unwrap().contains("shutting down") && gone_in_words("42P01").is_none());
        // Anything else is left as it was.
        let e = explained(anyhow::anyhow!("no such survey"), &at, "x");
        assert_eq!(format!("{e:#}"), "no such survey");
        assert!(!text.contains("s3cret"));
    }

    /// Issue 51: a reply that is not TLS, a host that does not resolve, a
    /// bad `sslmode`: in words, without the library's, or the password.
    #[test]
    fn a_link_that_fails_is_said_in_words() {
        let io = |kind, text: &str| sqlx::Error::Io(std::io::Error::new(kind, text.to_string()));
        let not_tls = io(std::io::ErrorKind::InvalidData, "received corrupt message of type InvalidContentType");
        assert_eq!(
            link_in_words(&not_tls, "db.example", 5432).unwrap(),
            "TLS: the server at db.example:5432 answered something that is not TLS (not PostgreSQL with TLS, or a \
             proxy in the way)"
        );
        for said in [
            "failed to lookup address information: Name or service not known",
            "failed to lookup address information: Temporary failure in name resolution",
            "Hostname did not resolve to any addresses",
        ] {
            let e = io(std::io::ErrorKind::Other, said);
            let text = link_in_words(&e, "nowhere.invalid", 5432).unwrap();
            assert!(text.starts_with("cannot find host nowhere.invalid ("), "{text}");
        }
        let e = connect_error(&not_tls, "postgres://lab@db.example/x", "db.example", 5432, "lab");
        let text = format!("{e:#}");
        assert!(text.contains("answered something that is not TLS") && !text.contains("corrupt"), "{text}");
        let bad = PgConnectOptions::from_str("postgres://lab:s3cret@db.example/x?sslmode=bogus").unwrap_err();
        let text = reason(&bad);
        assert_eq!(text, "unknown value \"bogus\" for `ssl_mode`");
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
