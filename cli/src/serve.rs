//! `survey serve [--listen ADDR]`: the lab's pages, read-only
//! ([`survey_serve`]), until SIGINT or SIGTERM.

use super::support::emit;
use anyhow::Context as _;
use clap::Args;
use serde_json::json;
use std::net::SocketAddr;
use std::path::Path;
use survey_serve::{ServeOptions, on_signals, serve as serve_on};

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
    let options = ServeOptions {
        db: db.to_path_buf(),
        due_after_days: args.due_after,
        refresh_ms: (args.refresh * 1000.0).round() as u64,
    };
    let signalled = on_signals().context("cannot listen for SIGINT and SIGTERM")?;
    emit(&format!("{}\n", json!({"listening": format!("http://{at}")})));
    serve_on(listener, options, signalled).await.context("serving the pages")?;
    Ok(())
}
