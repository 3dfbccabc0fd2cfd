//! `survey process`: the paper's DSP processing of a stored survey.

use super::support::{emit, load_survey};
use crate::process::{ProcessOptions, default_table_path, process_survey};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct ProcessArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Positioner model file (TOML) whose [design] names the lines [default: the survey's stored model].
    #[arg(long, value_name = "FILE")]
    pub design: Option<PathBuf>,
    /// Replay this processing recipe (TOML) instead of deriving one from the survey.
    #[arg(long, value_name = "FILE")]
    pub recipe: Option<PathBuf>,
    /// The correction table CSV [default: table-<ID>.csv]; the LinuxCNC files
    /// (<stem>.comp0, <stem>.comp1), the binary table (<stem>.bin) and the recipe
    /// used (<stem>.recipe.toml) go beside it.
    #[arg(long, value_name = "FILE")]
    pub table_out: Option<PathBuf>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn process(db: &Path, args: ProcessArgs) -> anyhow::Result<()> {
    let (survey, samples) = load_survey(db, args.survey).await?;
    let table_out = args.table_out.unwrap_or_else(|| default_table_path(db, survey.id));
    let opts = ProcessOptions { design: args.design, recipe: args.recipe, table_out: Some(table_out) };
    let outcome = process_survey(&survey, &samples, opts)?;
    emit(&if args.json { format!("{}\n", outcome.json()) } else { outcome.text() });
    Ok(())
}
