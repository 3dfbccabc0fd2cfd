//! `survey compare A B [--json]`: has the positioner changed from survey A
//! to survey B beyond what their repeatability allows, does A's table still
//! hold on B, and should it be recalibrated ([`crate::life`]), read-only.

use super::support::{emit, open_read_only};
use crate::survey::SurveyRef;
use clap::Args;
use std::path::Path;

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
        let a = crate::life::measure(&store, args.a).await?;
        let b = crate::life::measure(&store, args.b).await?;
        anyhow::Ok((a, b))
    }
    .await;
    store.close().await;
    let (a, b) = measured?;
    let c = crate::life::compared(&a, &b)?;
    emit(&if args.json { format!("{}\n", c.json(&a, &b)) } else { c.text(&a, &b) });
    Ok(())
}
