//! `survey process`: the paper's DSP processing of a stored survey.

use super::support::{emit, open_read_only};
use crate::process::{ProcessOptions, default_table_path, process_survey};
use crate::refit::refit_survey;
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
    /// Process the actual angles as stored, around the axis located before the
    /// runs, instead of around the axis fitted again from every SMR position
    /// (tracker surveys; for comparison).
    #[arg(long)]
    pub located_axis: bool,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn process(db: &Path, args: ProcessArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let loaded = async {
        let survey = store.resolve(args.survey).await?;
        let refit = if args.located_axis { None } else { refit_survey(&store, &survey).await? };
        let samples = match &refit {
            Some(_) => Vec::new(),
            None => store.samples(survey.id).await?,
        };
        // Corrected for the drift when the survey asked for it.
        let drift = store.drift_points(survey.id).await?;
        let samples = crate::drift::for_analysis(&survey, samples, &drift);
        let refit = refit.map(|(s, r)| (crate::drift::for_analysis(&survey, s, &drift), r));
        anyhow::Ok((survey, samples, refit))
    }
    .await;
    store.close().await;
    let (survey, samples, refit) = loaded?;
    let table_out = args.table_out.unwrap_or_else(|| default_table_path(db, survey.id));
    let opts = ProcessOptions { design: args.design, recipe: args.recipe, table_out: Some(table_out) };
    let to_process = refit.as_ref().map_or(&samples, |(s, _)| s);
    let outcome = process_survey(&survey, to_process, opts)?;
    let out = match &refit {
        Some((_, r)) if args.json => {
            let mut doc = outcome.json();
            doc["axis_refit"] = serde_json::to_value(r).unwrap_or_default();
            format!("{doc}\n")
        }
        Some((_, r)) => format!("{}{}", r.text(), outcome.text()),
        None if args.json => format!("{}\n", outcome.json()),
        None => outcome.text(),
    };
    emit(&out);
    Ok(())
}
