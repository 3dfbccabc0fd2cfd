//! `survey export --csv FILE`: write a survey in the import format.
//!
//! The actual angles written are those every command's figures are of
//! ([`crate::refit::samples_for_analysis`]): around the refitted axis of a
//! tracker survey, so `survey stats` of the file imported gives the figures
//! `survey stats` gives of the survey (as measured otherwise; never
//! corrected for drift: the file holds what was measured).

use super::support::open_read_only;
use crate::csvio::write_survey_csv;
use crate::error::path_error;
use crate::progress::{self, Progress};
use anyhow::Context as _;
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Where to write the CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: PathBuf,
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
}

pub async fn export(db: &Path, args: ExportArgs) -> anyhow::Result<()> {
    let progress = Progress::spinner("loading the survey", progress::visible(false));
    let store = open_read_only(db).await?;
    let loaded = async {
        let survey = store.resolve(args.survey).await?;
        let (samples, _) = crate::refit::samples_for_analysis(&store, &survey, &[], false).await?;
        anyhow::Ok((survey, samples))
    }
    .await;
    store.close().await;
    let (survey, samples) = loaded?;
    progress.stage(format!("writing {} samples to {}", samples.len(), args.csv.display()));
    let out =
        std::fs::File::create(&args.csv).map_err(|e| path_error(e, format!("cannot create {}", args.csv.display())))?;
    write_survey_csv(std::io::BufWriter::new(out), &samples)
        .with_context(|| format!("cannot write {}", args.csv.display()))?;
    drop(progress);
    eprintln!("wrote {} samples of survey {} to {}", samples.len(), survey.id, args.csv.display());
    Ok(())
}
