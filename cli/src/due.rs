//! `survey due [--asset ID] [--json] [--at TIME]`: what is due, when, by
//! which method and why ([`survey_lab::life::due`]), read-only.

use super::support::{emit, open_read_only};
use clap::Args;
use std::path::Path;
use std::time::SystemTime;

#[derive(Debug, Args)]
pub struct DueArgs {
    /// The asset [default: every asset of the database].
    #[arg(long, value_name = "ID", value_parser = survey_store::asset::asset_id)]
    pub asset: Option<String>,
    /// As of this UTC time (2026-03-01 or 2026-03-01T12:00:00Z): what will be due by then [default: now].
    #[arg(long, value_name = "TIME", value_parser = survey_lab::life::due::parse_at)]
    pub at: Option<SystemTime>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn due(db: &Path, args: DueArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let now = args.at.unwrap_or_else(SystemTime::now);
    let made = async {
        if let Some(a) = &args.asset
            && store.surveys_of_asset_uncounted(a).await?.is_empty()
        {
            return Err(
                survey_store::NotFound(format!("no survey of the asset {a} in {}", store.path().display())).into()
            );
        }
        survey_lab::life::due::due(&store, args.asset.as_deref(), now).await
    }
    .await;
    store.close().await;
    let all = made?;
    let lab = survey_lab::life::due::json(&all);
    emit(&if args.json { format!("{lab}\n") } else { survey_lab::life::due::text(&all, now) });
    Ok(())
}
