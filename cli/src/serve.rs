//! `survey serve [--listen ADDR] [--auth FILE | --no-auth] [--tls-cert FILE
//! --tls-key FILE]`: the lab's pages, read-only ([`survey_serve`]), until
//! SIGINT or SIGTERM; `survey serve --hash-password`: the hash of a password
//! read from stdin, for the auth file.

use super::support::emit;
use anyhow::Context as _;
use clap::Args;
use serde_json::json;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;
use survey_lab::error::bad_input;
use survey_serve::{Door, Limits, ServeOptions, Tls, Users, connection_bound, on_signals, serve as serve_on};

#[derive(Debug, Args)]
pub struct ServeArgs {
    /// The address to listen on (port 0: any free port; the ready line gives it).
    /// Any address but loopback needs --auth (or --no-auth, on purpose).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,
    /// Only the users of this file may read the pages (TOML: [[user]] name, password_hash from --hash-password):
    /// a browser logs in through a form, a program sends HTTP Basic credentials.
    #[arg(long, value_name = "FILE", conflicts_with = "no_auth")]
    pub auth: Option<PathBuf>,
    /// Serve an address other than loopback without authentication, on purpose (behind a reverse proxy that does it).
    #[arg(long)]
    pub no_auth: bool,
    /// Serve HTTPS with this PEM certificate chain (the server's certificate first); needs --tls-key.
    #[arg(long, value_name = "FILE", requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// The PEM private key of --tls-cert.
    #[arg(long, value_name = "FILE", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// A login's session ends after this many seconds without a request (and 24 h after the login whatever its use).
    #[arg(long, value_name = "S", default_value_t = 28_800.0, value_parser = limit_seconds)]
    pub session_idle: f64,
    /// Read a password (one line) from stdin, print its argon2id hash for the --auth file, and exit.
    #[arg(long, exclusive = true)]
    pub hash_password: bool,
    /// A calibration older than this many days is due.
    #[arg(long, value_name = "DAYS", default_value_t = 365.0, value_parser = positive_days)]
    pub due_after: f64,
    /// How often `/` refreshes the surveys being acquired, seconds.
    #[arg(long, value_name = "S", default_value_t = 1.0, value_parser = refresh_seconds)]
    pub refresh: f64,
    /// A request's head must arrive whole within this many seconds (a kept-alive connection idle as long is closed).
    #[arg(long, value_name = "S", default_value_t = 10.0, value_parser = limit_seconds)]
    pub header_timeout: f64,
    /// Connections open at once (at most the open-file limit less 64); beyond, the oldest idle one is closed.
    #[arg(long, value_name = "N", default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub max_connections: u32,
    /// Pages and documents made at once [default: the number of cores].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub pages_at_once: Option<u32>,
    /// Pages and documents waiting their turn beyond those; more are answered 503 with Retry-After [default: 8 per core].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=100_000))]
    pub pages_queued: Option<u32>,
    /// On SIGINT or SIGTERM, connections still open after this many seconds are dropped.
    #[arg(long, value_name = "S", default_value_t = 10.0, value_parser = limit_seconds)]
    pub stop_within: f64,
}

/// For tests only: every page or document holds its turn this many milliseconds longer.
const HOLD_MS: &str = "SURVEY_TEST_SERVE_HOLD_MS";

fn limit_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(t) if t.is_finite() && (0.05..=86_400.0).contains(&t) => Ok(t),
        _ => Err(format!("'{s}' is not a number of seconds from 0.05 to 86400")),
    }
}

/// The bounds `args` set, the others' defaults.
fn limits(args: &ServeArgs) -> Limits {
    let mut limits = Limits {
        header_timeout: Duration::from_secs_f64(args.header_timeout),
        max_connections: args.max_connections as usize,
        stop_within: Duration::from_secs_f64(args.stop_within),
        ..Limits::default()
    };
    if let Some(n) = args.pages_at_once {
        limits.heavy_at_once = n as usize;
    }
    if let Some(n) = args.pages_queued {
        limits.heavy_queue = n as usize;
    }
    if let Some(ms) = std::env::var(HOLD_MS).ok().and_then(|v| v.parse().ok()) {
        limits.hold = Duration::from_millis(ms);
    }
    limits
}

fn positive_days(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(d) if d.is_finite() && d > 0.0 => Ok(d),
        _ => Err(format!("'{s}' is not a number of days above 0")),
    }
}

fn refresh_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(t) if t.is_finite() && (0.1..=3600.0).contains(&t) => Ok(t),
        _ => Err(format!("'{s}' is not a number of seconds from 0.1 to 3600")),
    }
}

/// `--hash-password`: one line of stdin (its line end dropped), hashed.
fn hash_password() -> anyhow::Result<()> {
    use std::io::{BufRead as _, IsTerminal as _};
    if std::io::stdin().is_terminal() {
        survey_bench::say!("password (one line; it is shown as you type):");
    }
    let mut line = String::new();
    std::io::stdin().lock().read_line(&mut line).context("reading the password from stdin")?;
    let password = line.strip_suffix('\n').unwrap_or(&line);
    let password = password.strip_suffix('\r').unwrap_or(password);
    if password.is_empty() {
        return Err(bad_input("--hash-password: no password on stdin (one line, not empty)"));
    }
    emit(&format!("{}\n", survey_serve::hash_password(password)?));
    Ok(())
}

/// The door `args` ask for, or why the server must not start: an address
/// other than loopback needs `--auth` or `--no-auth`.
fn door(args: &ServeArgs, tls: bool) -> anyhow::Result<Option<Door>> {
    let Some(file) = &args.auth else {
        if !args.listen.ip().is_loopback() && !args.no_auth {
            return Err(bad_input(format!(
                "--listen {}: not loopback, so whoever reaches it would read every customer's surveys; give --auth \
                 FILE (users made with `survey serve --hash-password`), or --no-auth when a reverse proxy in front \
                 does the authentication",
                args.listen
            )));
        }
        return Ok(None);
    };
    let users = Users::read(file).map_err(|e| bad_input(e.to_string()))?;
    warn_if_readable(file);
    Ok(Some(Door { users, session_idle: Duration::from_secs_f64(args.session_idle), tls }))
}

/// A warning when every user of the machine may read the auth file.
fn warn_if_readable(file: &Path) {
    use std::os::unix::fs::PermissionsExt as _;
    if let Ok(meta) = std::fs::metadata(file)
        && meta.permissions().mode() & 0o004 != 0
    {
        survey_bench::say!(
            "warning: {}: every user of this machine can read the password hashes: chmod 600 it",
            file.display()
        );
    }
}

pub async fn serve(db: &Path, args: ServeArgs) -> anyhow::Result<()> {
    if args.hash_password {
        return hash_password();
    }
    let tls = match (&args.tls_cert, &args.tls_key) {
        (Some(cert), Some(key)) => Some(Tls::from_pem_files(cert, key).map_err(|e| bad_input(e.to_string()))?),
        _ => None,
    };
    let door = door(&args, tls.is_some())?;
    let listener = tokio::net::TcpListener::bind(args.listen)
        .await
        .with_context(|| format!("cannot listen on {}", args.listen))?;
    let at = listener.local_addr().context("the address listened on")?;
    if !at.ip().is_loopback() && door.is_none() {
        survey_bench::say!(
            "warning: serving on {at} without authentication (--no-auth): whoever can reach this address reads \
             every survey unless the reverse proxy in front stops them"
        );
    }
    // Said once at the start; every request opens the store again and
    // answers 503 with the reason while it cannot be read.
    match survey_store::Store::open_read_only(db).await {
        Ok(store) => store.close().await,
        Err(e) => survey_bench::say!("warning: {e:#}: the pages answer 503 until it can be read"),
    }
    let limits = limits(&args);
    let bound = connection_bound(limits.max_connections);
    if bound < limits.max_connections {
        survey_bench::say!(
            "warning: at most {bound} connections at once, not {}: the open-file limit (ulimit -n) leaves no more",
            limits.max_connections
        );
    }
    let options = ServeOptions {
        db: db.to_path_buf(),
        due_after_days: args.due_after,
        refresh_ms: (args.refresh * 1000.0).round() as u64,
        limits,
        door,
        tls,
    };
    let scheme = if options.tls.is_some() { "https" } else { "http" };
    let signalled = on_signals().context("cannot listen for SIGINT and SIGTERM")?;
    emit(&format!("{}\n", json!({"listening": format!("{scheme}://{at}")})));
    serve_on(listener, options, signalled).await.context("serving the pages")?;
    Ok(())
}
