//! `survey stats`: ISO 230-2 statistics across runs.
//!
//! A survey still being acquired, or stopped before its end, is said to be
//! incomplete ("N of M runs complete", `"complete": false` in the JSON), and
//! its statistics are those of its complete runs only: a run cut short would
//! weigh its targets unevenly.
//!
//! The figures are of the samples every command uses
//! ([`crate::load`] with `Axis::Refitted`: around the refitted axis of a
//! tracker survey), and say which axis (`"axis"`).

use super::args::UnitsArg;
use super::support::emit;
use crate::load::{Axis, load_read_only};
use crate::output::{iso_json, iso_text};
use crate::survey::{SurveyRecord, SurveyStatus};
use anyhow::Context as _;
use clap::Args;
use std::borrow::Cow;
use std::path::Path;
use survey_processing::Sample;
use survey_processing::iso230::iso230_2;

#[derive(Debug, Args)]
pub struct StatsArgs {
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<crate::survey::SurveyRef>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// How much of an acquired survey's plan is stored.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Completion {
    /// Every planned sample is stored and the survey says so.
    complete: bool,
    /// The runs whose every step is stored.
    complete_runs: Vec<u32>,
    /// Runs in the plan.
    runs_planned: u32,
}

impl Completion {
    fn runs_complete(&self) -> usize {
        self.complete_runs.len()
    }
}

/// What is stored of `survey`'s plan, or `None` when it has no plan (imports).
fn completion(survey: &SurveyRecord, samples: &[Sample]) -> Option<Completion> {
    let (runs, points) = (survey.runs?, survey.points?);
    if survey.status == SurveyStatus::Imported {
        return None;
    }
    let per_run = u64::from(points) * if survey.bidirectional { 2 } else { 1 };
    let mut per_run_stored = vec![0u64; runs as usize + 1];
    for s in samples {
        if let Some(n) = per_run_stored.get_mut(s.run as usize) {
            *n += 1;
        }
    }
    let complete_runs = (1..=runs).filter(|&r| per_run_stored[r as usize] == per_run).collect();
    let all = survey.planned_samples.is_none_or(|p| p == samples.len() as u64);
    Some(Completion {
        complete: matches!(survey.status, SurveyStatus::Complete | SurveyStatus::Processing) && all,
        complete_runs,
        runs_planned: runs,
    })
}

pub async fn stats(db: &Path, args: StatsArgs) -> anyhow::Result<()> {
    let loaded = load_read_only(db, args.survey, Axis::Refitted).await?;
    let (survey, drift) = (&loaded.survey, &loaded.drift);
    let samples = loaded.analysed();
    let axis = loaded.axis_used();
    let id = survey.id;
    let completion = completion(survey, &samples);
    let incomplete = completion.as_ref().filter(|c| !c.complete);
    let used: Cow<[Sample]> = match incomplete {
        Some(c) => samples.iter().filter(|s| c.complete_runs.contains(&s.run)).copied().collect(),
        None => samples,
    };
    let iso = iso230_2(&used).with_context(|| {
        let what = incomplete.map_or(String::new(), |c| {
            format!(" (it is {}: {} of {} runs complete)", survey.status.as_str(), c.runs_complete(), c.runs_planned)
        });
        format!("survey {id} cannot give ISO 230-2 statistics{what}")
    })?;
    if args.json {
        let mut doc = iso_json(id, &iso);
        doc["axis"] = axis.as_str().into();
        doc["complete"] = completion.as_ref().is_none_or(|c| c.complete).into();
        doc["status"] = survey.status.as_str().into();
        if let Some(c) = &completion {
            doc["runs_complete"] = c.runs_complete().into();
            doc["runs_planned"] = c.runs_planned.into();
        }
        if !drift.is_empty() {
            doc["drift"] = crate::drift::json(survey, drift);
        }
        emit(&format!("{doc}\n"));
    } else {
        let mut text = String::new();
        if let Some(c) = incomplete {
            text += &format!(
                "survey {id} is incomplete ({}): {} of {} runs complete; the statistics below are of the complete runs \
                 only (`survey resume --survey {id}` continues it)\n",
                survey.status.as_str(),
                c.runs_complete(),
                c.runs_planned
            );
        }
        let units = args.units.units();
        text += &iso_text(id, &iso, units);
        text += axis.text();
        text += "\n";
        text += &survey_processing::drift::text(drift, units);
        if crate::drift::correction_asked(survey) && !drift.is_empty() {
            text += "the statistics above are of the samples corrected for this drift (drift_control.correct)\n";
        }
        emit(&text);
    }
    Ok(())
}
