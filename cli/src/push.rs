//! `survey push --to URL [--survey ID | --all] [--json]`: copy complete
//! surveys from the station's SQLite file (`--db`) to the lab store, each
//! exactly once by its uid ([`survey_store::lab::push`]). Prints
//! `{"pushed": [uids], "already": [uids], "not_complete": [uids]}` with
//! `--json`.

use super::support::{emit, open_read_only};
use clap::Args;
use std::fmt::Write as _;
use std::path::Path;
use survey_store::lab::{self, Which};
use survey_store::survey::SurveyRef;

#[derive(Debug, Args)]
pub struct PushArgs {
    /// The lab store: postgres://USER:PASSWORD@HOST:PORT/DATABASE (or the environment's SURVEY_LAB).
    #[arg(long, value_name = "URL", env = "SURVEY_LAB", hide_env_values = true)]
    pub to: String,
    /// The survey to push, an id or a uid [default: the latest].
    #[arg(long, value_name = "ID", conflicts_with = "all")]
    pub survey: Option<SurveyRef>,
    /// Push every complete survey (those in the lab store already are left as they are).
    #[arg(long)]
    pub all: bool,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// What the lab store's history lacks of the assets of the surveys pushed
/// (or found there already), made there and kept (each survey's own entries
/// came with it; a pair of surveys from two stations, or entries of another
/// version, are made here): [`survey_lab::life::cache`].
async fn keep_history(lab_store: &survey_store::Store, report: &lab::PushReport) {
    let mut assets: Vec<(String, i64)> = Vec::new();
    for uid in report.pushed.iter().chain(&report.already) {
        match lab_store.resolve_uncounted(Some(SurveyRef::Uid(uid.clone()))).await {
            Ok(r) if !assets.iter().any(|a| a.0 == r.asset) => assets.push((r.asset, r.id)),
            Ok(_) => {}
            Err(e) => tracing::warn!("survey {uid}: its asset's history could not be kept ({e:#})"),
        }
    }
    for (asset, id) in assets {
        survey_lab::life::cache::fill_after(lab_store, &asset, id).await;
    }
}

pub async fn push(db: &Path, args: PushArgs) -> anyhow::Result<()> {
    let Some(url) = lab::url_of(Path::new(&args.to)) else {
        return Err(survey_lab::error::bad_input(format!(
            "--to {}: the lab store is a postgres:// URL",
            lab::display(Path::new(&args.to))
        )));
    };
    if lab::url_of(db).is_some() {
        return Err(survey_lab::error::bad_input(format!(
            "--db {}: push copies from a station's SQLite file (--db PATH) to the lab store (--to URL)",
            lab::display(db)
        )));
    }
    let which = match (args.all, args.survey) {
        (true, _) => Which::All,
        (false, Some(r)) => Which::One(r),
        (false, None) => Which::Latest,
    };
    let station = open_read_only(db).await?;
    let pushed = async {
        let lab_store = lab::open(url, true).await?;
        let report = lab::push(&station, &lab_store, which).await;
        if let Ok(r) = &report {
            keep_history(&lab_store, r).await;
        }
        lab_store.close().await;
        report
    }
    .await;
    station.close().await;
    let report = match lab::Server::of(url) {
        Some(at) => pushed.map_err(|e| lab::explained(e, &at, lab::PUSHING))?,
        None => pushed?,
    };
    if args.json {
        emit(&format!("{}\n", serde_json::to_value(&report)?));
        return Ok(());
    }
    let mut s = String::new();
    let to = lab::redacted(url);
    let _ = writeln!(s, "{} pushed to {to}, {} there already", report.pushed.len(), report.already.len());
    for uid in &report.pushed {
        let _ = writeln!(s, "  pushed   {uid}");
    }
    for uid in &report.already {
        let _ = writeln!(s, "  already  {uid}");
    }
    for uid in &report.not_complete {
        let _ = writeln!(s, "  not complete, not pushed  {uid}");
    }
    emit(&s);
    Ok(())
}
