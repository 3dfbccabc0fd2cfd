//! What every command shares: logging, printing, opening the database.

use std::path::Path;
use survey_acquire::Engine;
use survey_bench::session::{Acquired, stopped_doc};
use survey_lab::conclude::{ConcludeOptions, conclude};
use survey_store::Store;

/// Logs go to stderr through `tracing`: warnings, and more for each
/// `-v` (info, debug, then trace, sqlx's statements too); `RUST_LOG`, when
/// set, decides instead. A line says its level and message; the time and
/// the module it came from are for debugging (`-vv`, or `RUST_LOG`).
pub fn init_logging(verbose: u8) {
    let from_env = tracing_subscriber::EnvFilter::try_from_default_env().ok();
    let debugging = from_env.is_some() || verbose >= 2;
    let filter = from_env.unwrap_or_else(|| {
        tracing_subscriber::EnvFilter::new(match verbose {
            0 => "warn,sqlx=error",
            1 => "info,sqlx=error",
            2 => "debug,sqlx=error",
            _ => "trace",
        })
    });
    use std::io::IsTerminal as _;
    let logs = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        // A stderr that went away loses the line; the default would report
        // that with `eprintln!`, which panics on the same closed pipe.
        .log_internal_errors(false)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(debugging);
    let _ = if debugging { logs.try_init() } else { logs.without_time().try_init() };
}

/// Write command output to stdout. A closed pipe (`survey stats | head`) is
/// not an error worth a panic: the reader has what it wanted. Any other
/// failure (a full disk behind `> file`, `/dev/full`) loses the output: it
/// is kept for [`output_lost`], which makes the command's exit status 1
/// with the reason in words, never a silent 0.
pub fn emit(text: &str) {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush())
        && e.kind() != std::io::ErrorKind::BrokenPipe
    {
        let mut lost = LOST.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        lost.get_or_insert_with(|| e.to_string());
    }
}

/// The first failure to write the output, other than a closed pipe.
static LOST: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// Why the command's output could not be written, when it could not.
pub fn output_lost() -> Option<String> {
    LOST.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone()
}

/// Open an existing database for a command that writes to it (`resume`): a
/// missing file is bad input.
pub async fn open_existing(db: &Path) -> anyhow::Result<Store> {
    Store::open_existing(db).await
}

/// Open an existing database for a command that only reads: never written
/// ([`Store::open_read_only`]).
pub async fn open_read_only(db: &Path) -> anyhow::Result<Store> {
    Store::open_read_only(db).await
}

/// What `run` and `resume` do after acquiring (or failing to): on a stopped
/// or failed acquisition, print the `--json` document of what is stored and
/// return the error; else the statistics, processing and verification, then
/// the output. The store is closed either way.
pub async fn conclude_and_print(
    store: Store,
    id: i64,
    engine: &mut Engine,
    acquired: anyhow::Result<Acquired>,
    finish: (ConcludeOptions, &Path, bool),
) -> anyhow::Result<()> {
    let (options, db, json) = finish;
    let acquired = match acquired {
        Ok(a) => a,
        Err(e) => {
            if json {
                emit(&format!("{}\n", stopped_doc(&store, id, &e).await));
            }
            store.close().await;
            return Err(e);
        }
    };
    let stop = options.stop.clone();
    let concluded = match conclude(&store, id, engine, &acquired, db, options).await {
        Ok(c) => c,
        Err(e) => {
            store.close().await;
            return Err(e);
        }
    };
    emit(&concluded.output.render(json));
    // The history of the survey's asset kept, unless a signal asked to stop.
    if stop.check().is_ok() {
        keep_history(&store, id).await;
    }
    store.close().await;
    concluded.result
}

/// After a command that completed survey `id` of `store`: what the history
/// of its asset lacks is made and kept ([`survey_lab::life::cache`]); a
/// failure is said on stderr, the command's work is done.
pub async fn keep_history(store: &Store, id: i64) {
    match store.resolve_uncounted(Some(id.into())).await {
        Ok(r) => survey_lab::life::cache::fill_after(store, &r.asset, id).await,
        Err(e) => tracing::warn!("survey {id}: its asset's history could not be kept ({e:#})"),
    }
}
