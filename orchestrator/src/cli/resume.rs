//! `survey resume`: continue an interrupted survey from its first missing step.

use super::support::{emit, open_existing};
use crate::bench::Bench;
use crate::conclude::{ConcludeOptions, conclude};
use crate::error::bad_input;
use crate::session::{AcquireOptions, acquire};
use crate::survey::{SurveySource, SurveyStatus};
use clap::Args;
use std::path::Path;
use std::time::Duration;

#[derive(Debug, Args)]
pub struct ResumeArgs {
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Print the summary as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn resume(db: &Path, args: ResumeArgs) -> anyhow::Result<()> {
    let store = open_existing(db).await?;
    let record = store.resolve(args.survey).await?;
    let id = record.id;
    match record.status {
        SurveyStatus::Interrupted | SurveyStatus::Running | SurveyStatus::Failed => {}
        SurveyStatus::Complete => {
            return Err(bad_input(format!("survey {id} is complete: there is nothing to resume")));
        }
        SurveyStatus::Imported => {
            return Err(bad_input(format!("survey {id} was imported, not acquired: it cannot be resumed")));
        }
    }
    let stored = record.sample_count;
    let next = store.last_seq(id).await?.map_or(0, |s| s + 1);
    if next != stored {
        return Err(anyhow::anyhow!(
            "survey {id}: {stored} samples stored but the last step is {next}: the survey is not a dense prefix of its plan"
        ));
    }
    // Instrument time goes on from where the survey stopped (drift continues).
    let last_time = store.last_sample_time(id).await?.unwrap_or(0.0).max(record.started_at_s.unwrap_or(0.0));
    let mut bench = Bench::resume(&record, Duration::from_secs_f64(last_time.max(0.0)), next)?;
    let plan = bench.plan.clone();
    if next >= plan.total_steps() {
        store.set_status(id, SurveyStatus::Complete, None).await?;
        return Err(bad_input(format!("survey {id} already holds all {next} samples: marked complete")));
    }
    if record.source == SurveySource::Verification {
        let table = record.verification.as_ref().and_then(|v| v.correction.as_ref()).ok_or_else(|| {
            bad_input(format!("survey {id} verifies a table that was not stored with it: it cannot be resumed"))
        })?;
        crate::verify::apply_correction(&mut bench.engine, table).await?;
    }
    store.set_status(id, SurveyStatus::Running, None).await?;
    let message = format!("resumed at step {next} of {}", plan.total_steps());
    store.log_event(id, last_time, "info", &message).await?;
    eprintln!("survey {id}: {message}");
    let options = AcquireOptions { progress: !args.json, crash_after: None };
    let acquired = acquire(&store, id, &mut bench.engine, &plan, next, options).await?;
    let finish = ConcludeOptions { recipe: None, verify: false, acquire: options };
    let concluded = conclude(&store, id, &mut bench.engine, &plan, &acquired, db, finish).await;
    store.close().await;
    let concluded = concluded?;
    emit(&concluded.output.render(args.json));
    concluded.result
}
