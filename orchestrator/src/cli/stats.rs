//! `survey stats`: ISO 230-2 statistics across runs.

use super::support::{emit, load_survey};
use crate::error::bad_input;
use crate::output::{iso_json, iso_text};
use clap::Args;
use std::path::Path;
use survey_processing::iso230::iso230_2;

#[derive(Debug, Args)]
pub struct StatsArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn stats(db: &Path, args: StatsArgs) -> anyhow::Result<()> {
    let (survey, samples) = load_survey(db, args.survey).await?;
    let iso = iso230_2(&samples)
        .map_err(|e| bad_input(format!("survey {} cannot give ISO 230-2 statistics: {e}", survey.id)))?;
    if args.json {
        emit(&format!("{}\n", iso_json(survey.id, &iso)));
    } else {
        emit(&iso_text(survey.id, &iso));
    }
    Ok(())
}
