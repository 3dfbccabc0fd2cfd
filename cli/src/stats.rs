//! `survey stats`: ISO 230-2 statistics across runs.
//!
//! A survey still being acquired, or stopped before its end, is said to be
//! incomplete ("N of M runs complete", `"complete": false` in the JSON), and
//! its statistics are those of its complete runs only: a run cut short would
//! weigh its targets unevenly.
//!
//! The figures are of the samples every command uses
//! ([`survey_lab::load`] with `Axis::Refitted`: around the refitted axis of a
//! tracker survey), and say which axis (`"axis"`).

use super::args::UnitsArg;
use super::support::emit;
use clap::Args;
use std::path::Path;
use survey_bench::output::iso_text;
use survey_lab::documents::Stats;
use survey_lab::load::{Axis, load_read_only};

#[derive(Debug, Args)]
pub struct StatsArgs {
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn stats(db: &Path, args: StatsArgs) -> anyhow::Result<()> {
    let loaded = load_read_only(db, args.survey, Axis::Refitted).await?;
    let (survey, drift) = (&loaded.survey, &loaded.drift);
    let axis = loaded.axis_used();
    let id = survey.id;
    let stats = Stats::of(&loaded)?;
    if args.json {
        emit(&format!("{}\n", stats.json(&loaded)));
    } else {
        let mut text = String::new();
        if let Some(c) = stats.incomplete() {
            text += &format!(
                "survey {id} is incomplete ({}): {} of {} runs complete; the statistics below are of the complete runs \
                 only (`survey resume --survey {id}` continues it)\n",
                survey.status.as_str(),
                c.runs_complete(),
                c.runs_planned
            );
        }
        let units = args.units.units();
        text += &iso_text(id, &stats.iso, units);
        text += axis.text();
        text += "\n";
        text += &survey_plan::drift::text(drift, units);
        if survey_lab::drift::correction_asked(survey) && !drift.is_empty() {
            text += "the statistics above are of the samples corrected for this drift (drift_control.correct)\n";
        }
        emit(&text);
    }
    Ok(())
}
