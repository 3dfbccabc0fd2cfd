//! `survey report --out DIR`: the survey's report as one HTML page.

use super::support::{emit, load_survey};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// The folder to write index.html into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

pub async fn report(db: &Path, args: ReportArgs) -> anyhow::Result<()> {
    let progress = crate::progress::Progress::spinner("writing the report", crate::progress::visible(false));
    let (survey, samples) = load_survey(db, args.survey).await?;
    let html = crate::report::html(&survey, &samples)?;
    let path = crate::report::write(&args.out, &html)?;
    drop(progress);
    emit(&format!("{}\n", path.display()));
    Ok(())
}
