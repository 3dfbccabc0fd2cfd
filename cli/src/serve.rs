//! `survey serve [--listen ADDR]`: the lab's pages, read-only
//! ([`survey_serve`]), until SIGINT or SIGTERM.

use super::support::emit;
use anyhow::Context as _;
use clap::Args;
use serde_json::json;
use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;
use survey_serve::{Limits, ServeOptions, connection_bound, on_signals, serve as serve_on};

#[derive(Debug, Args)]
pub struct ServeArgs {
    /// The address to listen on (port 0: any free port; the ready line gives it).
    /// Anything but loopback serves every survey to whoever can reach it: put it behind the lab's reverse proxy.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,
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

pub async fn serve(db: &Path, args: ServeArgs) -> anyhow::Result<()> {
    let listener = tokio::net::TcpListener::bind(args.listen)
        .await
        .with_context(|| format!("cannot listen on {}", args.listen))?;
    let at = listener.local_addr().context("the address listened on")?;
    if !at.ip().is_loopback() {
        survey_bench::say!(
            "warning: serving on {at}, not loopback: whoever can reach this address reads every survey; put it \
             behind the lab's reverse proxy for access control"
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
    };
    let signalled = on_signals().context("cannot listen for SIGINT and SIGTERM")?;
    emit(&format!("{}\n", json!({"listening": format!("http://{at}")})));
    serve_on(listener, options, signalled).await.context("serving the pages")?;
    Ok(())
}
