//! The `--json` documents of the read commands that `survey serve` serves
//! too (`/api/...`): `list`, `show` and `stats`, built here once so that a
//! page and a command never disagree. (`history` and `compare` have theirs in
//! [`crate::life`].)

use crate::load::Loaded;
use anyhow::Context as _;
use serde_json::{Value, json};
use std::borrow::Cow;
use survey_bench::output::iso_json;
use survey_plan::drift::DriftPoint;
use survey_processing::Sample;
use survey_processing::iso230::{Iso230, iso230_2};
use survey_store::survey::{SurveyRecord, SurveyRef, SurveyStatus};
use survey_store::{EventRow, Store};

/// One survey as a line of `list`.
pub fn summary(r: &SurveyRecord) -> Value {
    json!({
        "id": r.id,
        "uid": r.uid,
        "asset": r.asset,
        "status": r.status.as_str(),
        "source": r.source.to_column(),
        "points": r.points,
        "runs": r.runs,
        "bidirectional": r.bidirectional,
        "samples": r.sample_count,
        "planned_samples": r.planned_samples,
        "created_at": r.created_at,
        "updated_at": r.updated_at,
    })
}

/// `survey list --json`: every survey of the store `db` (as shown), oldest first.
pub fn list_json(db: &str, surveys: &[SurveyRecord]) -> Value {
    json!({"db": db, "surveys": surveys.iter().map(summary).collect::<Vec<_>>()})
}

/// What `survey show` shows of one survey.
#[derive(Debug)]
pub struct Shown {
    /// The survey.
    pub survey: SurveyRecord,
    /// Its event log.
    pub events: Vec<EventRow>,
    /// Its drift-control measurements.
    pub drift: Vec<DriftPoint>,
    /// Its check points between the targets (issue 20), when it has them.
    pub checks: Vec<Sample>,
    /// The air measured with its samples, or stated.
    pub environment: crate::environment::Environment,
}

/// Read what `survey show` shows of survey `r` (the latest when `None`).
pub async fn shown(store: &Store, r: Option<SurveyRef>) -> anyhow::Result<Shown> {
    let survey = store.resolve(r).await?;
    let events = store.events(survey.id).await?;
    let drift = store.drift_points(survey.id).await?;
    let checks = store.check_points(survey.id).await?;
    let environment = crate::environment::Environment::of(store, &survey).await?;
    Ok(Shown { survey, events, drift, checks, environment })
}

impl Shown {
    /// `survey show --json`.
    pub fn json(&self) -> Value {
        let r = &self.survey;
        let mut doc = summary(r);
        doc["plan"] = json!(r.setup.plan().map(|p| json!({
            "targets_deg": [p.targets_deg.first(), p.targets_deg.last()],
            "targets": p.targets_deg.len(),
            "runs": p.runs,
            "bidirectional": p.bidirectional,
            "overrun_deg": p.overrun_deg,
        })));
        doc["instruments"] = r.instruments.clone();
        doc["started_at_s"] = json!(r.started_at_s);
        doc["ended_at_s"] = json!(r.ended_at_s);
        doc["axis"] = json!(r.axis.as_ref().map(|a| json!({
            "center_mm": a.center_mm,
            "normal": a.normal,
            "radius_mm": a.radius_mm,
            "plane_rms_mm": a.plane_rms_mm,
        })));
        doc["model"] = json!(r.model.as_ref().map(|m| m.to_toml()));
        doc["verifies_survey"] = json!(r.verification.as_ref().map(|v| v.verifies_survey));
        doc["check_of"] = json!(r.check_of);
        doc["environment"] = self.environment.json();
        doc["events"] = json!(
            self.events
                .iter()
                .map(|e| json!({"at_s": e.at_s, "level": e.level, "message": e.message}))
                .collect::<Vec<_>>()
        );
        doc["drift"] = crate::drift::json(r, &self.drift);
        // Check points measured between the targets (issue 20): their angles, as many times as measured.
        doc["check_points"] = json!({"samples": self.checks.len(), "targets_deg": self.check_angles()});
        doc["resolves_survey"] = json!(r.resolves);
        doc
    }

    /// The angles of the check points, each once, in order.
    pub fn check_angles(&self) -> Vec<f64> {
        let mut at: Vec<f64> = self.checks.iter().map(|c| c.target_deg).collect();
        at.sort_by(f64::total_cmp);
        at.dedup();
        at
    }
}

/// How much of an acquired survey's plan is stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Completion {
    /// Every planned sample is stored and the survey says so.
    pub complete: bool,
    /// The runs whose every step is stored.
    pub complete_runs: Vec<u32>,
    /// Runs in the plan.
    pub runs_planned: u32,
}

impl Completion {
    /// How many runs are complete.
    pub fn runs_complete(&self) -> usize {
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

/// `survey stats`: the ISO 230-2 figures of a survey. A survey still being
/// acquired, or stopped before its end, is incomplete, and its figures are
/// those of its complete runs only: a run cut short would weigh its targets
/// unevenly.
#[derive(Debug)]
pub struct Stats {
    /// The figures.
    pub iso: Iso230,
    /// What is stored of the plan (`None`: no plan, an import).
    pub completion: Option<Completion>,
}

impl Stats {
    /// The figures of `loaded`, or why it cannot give them.
    pub fn of(loaded: &Loaded) -> anyhow::Result<Stats> {
        let survey = &loaded.survey;
        let samples = loaded.analysed();
        let completion = completion(survey, &samples);
        let incomplete = completion.as_ref().filter(|c| !c.complete);
        let used: Cow<[Sample]> = match incomplete {
            Some(c) => samples.iter().filter(|s| c.complete_runs.contains(&s.run)).copied().collect(),
            None => samples,
        };
        let iso = iso230_2(&used).with_context(|| {
            let what = incomplete.map_or(String::new(), |c| {
                format!(
                    " (it is {}: {} of {} runs complete)",
                    survey.status.as_str(),
                    c.runs_complete(),
                    c.runs_planned
                )
            });
            format!("survey {} cannot give ISO 230-2 statistics{what}", survey.id)
        })?;
        Ok(Stats { iso, completion })
    }

    /// The runs that are not all there, when the survey is incomplete.
    pub fn incomplete(&self) -> Option<&Completion> {
        self.completion.as_ref().filter(|c| !c.complete)
    }

    /// `survey stats --json`.
    pub fn json(&self, loaded: &Loaded) -> Value {
        let survey = &loaded.survey;
        let mut doc = iso_json(survey.id, &self.iso);
        doc["axis"] = loaded.axis_used().as_str().into();
        doc["complete"] = self.completion.as_ref().is_none_or(|c| c.complete).into();
        doc["status"] = survey.status.as_str().into();
        if let Some(c) = &self.completion {
            doc["runs_complete"] = c.runs_complete().into();
            doc["runs_planned"] = c.runs_planned.into();
        }
        if !loaded.drift.is_empty() {
            doc["drift"] = crate::drift::json(survey, &loaded.drift);
        }
        doc
    }
}
