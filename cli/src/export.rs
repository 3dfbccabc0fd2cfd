//! `survey export --csv FILE`: write a survey in the import format.
//!
//! The actual angles written are those every command's figures are of
//! ([`survey_lab::load`] with `Axis::Refitted`): around the refitted axis of a
//! tracker survey, so `survey stats` of the file imported gives the figures
//! `survey stats` gives of the survey (as measured otherwise; never
//! corrected for drift: the file holds what was measured).

use crate::progress::{self, Progress};
use anyhow::Context as _;
use clap::Args;
use std::path::{Path, PathBuf};
use survey_lab::csvio::write_survey_csv;
use survey_lab::error::path_error;
use survey_lab::load::{Axis, load_read_only};

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Where to write the CSV.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub csv: PathBuf,
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
}

pub async fn export(db: &Path, args: ExportArgs) -> anyhow::Result<()> {
    let progress = Progress::spinner("loading the survey", progress::visible(false));
    let loaded = load_read_only(db, args.survey, Axis::Refitted).await?;
    let (survey, samples) = (&loaded.survey, &loaded.samples);
    progress.stage(format!("writing {} samples to {}", samples.len(), args.csv.display()));
    let out =
        std::fs::File::create(&args.csv).map_err(|e| path_error(e, format!("cannot create {}", args.csv.display())))?;
    write_survey_csv(std::io::BufWriter::new(out), samples)
        .with_context(|| format!("cannot write {}", args.csv.display()))?;
    drop(progress);
    survey_bench::say!("wrote {} samples of survey {} to {}", samples.len(), survey.id, args.csv.display());
    Ok(())
}
