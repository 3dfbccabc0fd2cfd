//! `survey history [--asset ID] [--json]`: an asset's surveys in time order
//! and what changed from each complete survey to the next
//! ([`survey_lab::life::history`]), read-only.

use super::support::{emit, open_read_only};
use clap::Args;
use std::path::Path;

#[derive(Debug, Args)]
pub struct HistoryArgs {
    /// The asset [default: the latest survey's].
    #[arg(long, value_name = "ID", value_parser = survey_store::asset::asset_id)]
    pub asset: Option<String>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn history(db: &Path, args: HistoryArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let made = async {
        let asset = match args.asset {
            Some(a) => a,
            None => store.resolve(None).await?.asset,
        };
        survey_lab::life::history::history(&store, &asset, None).await
    }
    .await;
    store.close().await;
    let h = made?;
    emit(&if args.json { format!("{}\n", h.json()) } else { h.text() });
    Ok(())
}
