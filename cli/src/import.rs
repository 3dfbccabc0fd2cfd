//! `survey import FILE.csv`: store measured data from another source as a new survey.

use super::support::emit;
use crate::progress::{self, Progress};
use clap::Args;
use std::path::{Path, PathBuf};
use survey_lab::csvio::read_survey_csv;
use survey_processing::iso230::iso230_2;
use survey_processing::{Direction, Sample};
use survey_store::Store;
use survey_store::survey::{NewSurvey, Setup, SurveySource, SurveyStatus};

#[derive(Debug, Args)]
pub struct ImportArgs {
    /// CSV file: run,direction,target_deg,readout_deg,actual_deg[,timestamp_s].
    #[arg(value_name = "FILE.csv", value_hint = clap::ValueHint::FilePath)]
    pub file: PathBuf,
    /// The asset (the axis measured) the survey belongs to [default: unassigned].
    #[arg(long, value_name = "ID", value_parser = survey_store::asset::asset_id)]
    pub asset: Option<String>,
}

pub async fn import(db: &Path, args: ImportArgs) -> anyhow::Result<()> {
    let name = args.file.display().to_string();
    let progress = Progress::spinner(format!("reading {name}"), progress::visible(false));
    let samples = read_survey_csv(&args.file)?;
    progress.stage(format!("storing {} samples", samples.len()));
    let runs = samples.iter().map(|s| s.run).max().unwrap_or(0);
    let bidirectional = samples.iter().any(|s| s.direction == Direction::Reverse);
    let targets = distinct_targets(&samples);
    let store = Store::open(db).await?;
    let survey = NewSurvey {
        status: SurveyStatus::Imported,
        source: SurveySource::Import { file: name.clone() },
        points: Some(targets as u32),
        runs: Some(runs),
        bidirectional,
        setup: Setup::Imported { file: name.clone() },
        planned_samples: Some(samples.len() as u64),
        asset: args.asset.clone().unwrap_or_else(|| survey_store::asset::UNASSIGNED.to_string()),
        ..NewSurvey::default()
    };
    let id = store.import(&survey, &samples).await;
    // What is said of the samples, then they go: the history of the asset
    // (kept now, [`survey_lab::life::cache`]) measures one survey at a time.
    let (count, note) = (samples.len(), iso230_2(&samples).err());
    drop(samples);
    if let Ok(id) = id {
        super::support::keep_history(&store, id).await;
    }
    store.close().await;
    drop(progress);
    let id = id?;
    emit(&format!("{id}\n"));
    if let Some(e) = note {
        survey_bench::say!("note: survey {id} cannot give ISO 230-2 statistics yet: {e}");
    }
    survey_bench::say!(
        "imported {count} samples ({targets} targets, {runs} runs) from {name} as survey {id} in {}",
        db.display()
    );
    Ok(())
}

fn distinct_targets(samples: &[Sample]) -> usize {
    let mut t: Vec<f64> = samples.iter().map(|s| s.target_deg).collect();
    t.sort_by(f64::total_cmp);
    t.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    t.len()
}
