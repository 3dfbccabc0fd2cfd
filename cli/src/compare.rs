//! `survey compare A B [--json]`: has the positioner changed from survey A
//! to survey B beyond what their repeatability allows, does A's table still
//! hold on B, and should it be recalibrated ([`survey_lab::life`]), read-only.

use super::support::{emit, open_read_only};
use clap::Args;
use std::path::Path;
use survey_store::survey::SurveyRef;

#[derive(Debug, Args)]
pub struct CompareArgs {
    /// The first survey (id or uid): the earlier one, or the calibration in force.
    #[arg(value_name = "A")]
    pub a: SurveyRef,
    /// The second survey (id or uid), of the same asset.
    #[arg(value_name = "B")]
    pub b: SurveyRef,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn compare(db: &Path, args: CompareArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let measured = async {
        let a = survey_lab::life::measure(&store, args.a).await?;
        let b = survey_lab::life::measure(&store, args.b).await?;
        anyhow::Ok((a, b))
    }
    .await;
    store.close().await;
    let (a, b) = measured?;
    let c = survey_lab::life::compared(&a, &b)?;
    emit(&if args.json { format!("{}\n", c.json(&a, &b)) } else { c.text(&a, &b) });
    Ok(())
}
