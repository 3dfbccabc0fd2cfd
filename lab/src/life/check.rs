//! The unattended recalibration loop (`survey run --check`): a short check
//! survey (a few dozen targets, both ways, two runs) compared with the
//! calibration whose table is in force (the asset's last complete
//! calibration); a full survey, with the calibration's plan, only when the
//! check says so. The check survey names the calibration it was compared
//! with, its decision is stored (`checks`), and a recalibration is recorded
//! against it with the table file it wrote, which is then the table in force.
//!
//! What happened is the exit status ([`Recalibrated`]): 0 in tolerance (the
//! table in force holds and nothing changed), 3 when a full survey was made
//! (a recalibration, or the asset's first calibration), 1 for a failure, 2
//! for bad input.

use super::{compared, measure};
use crate::conclude::{ConcludeOptions, conclude};
use crate::error::{Recalibrated, bad_input};
use serde_json::{Value, json};
use std::path::Path;
use survey_acquire::stop::Stop;
use survey_bench::Bench;
use survey_bench::output::Output;
use survey_bench::session::{AcquireOptions, acquire};
use survey_plan::SurveyPlan;
use survey_store::asset::UNASSIGNED;
use survey_store::survey::{NewSurvey, SurveyRecord, SurveyRef};
use survey_store::{CheckDecision, Store};

/// The size of a plan to acquire: targets, runs, both ways.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlanSize {
    /// Targets (`--points`); `None`: as the configuration says.
    pub points: Option<u32>,
    /// Runs.
    pub runs: Option<u32>,
    /// Both ways.
    pub bidirectional: bool,
}

/// Runs of a check survey: two, the fewest that measure repeatability.
pub const CHECK_RUNS: u32 = 2;

/// What the loop is told by the command line.
#[derive(Debug, Clone)]
pub struct CheckRequest {
    /// The asset (`--asset`, else the bench's: `[asset] id`, `sim-<preset>`).
    pub asset: String,
    /// The reference is an autocollimator: the check measures every face.
    pub polygon: bool,
    /// The command line's plan: its targets are the check's (else a few
    /// dozen of the calibration's); the whole plan is the first calibration's
    /// when the asset has none.
    pub size: PlanSize,
    /// The JSON document instead of text.
    pub json: bool,
    /// Process the recalibration with this recipe.
    pub recipe: Option<std::path::PathBuf>,
    /// The unit of the errors in the text.
    pub units: survey_bench::output::Units,
}

/// A few dozen of the calibration's targets: the number of targets nearest
/// 36 that divides the calibration's full circle (so every check target is a
/// calibration target and the mean error maps compare cell by cell); 36 when
/// none does (a partial range: the lines are still compared); every face of
/// an autocollimator's polygon (the faces are the targets).
pub fn check_points(plan: &SurveyPlan, polygon: bool) -> u32 {
    let n = plan.targets_deg.len() as u32;
    if polygon {
        return n;
    }
    let full_circle = n >= 2 && plan.targets_deg[0] == 0.0 && (plan.targets_deg[1] * f64::from(n) - 360.0).abs() < 1e-9;
    if !full_circle {
        return 36;
    }
    (24..=60).filter(|d| n.is_multiple_of(*d)).min_by_key(|d| d.abs_diff(36)).unwrap_or(36.min(n))
}

/// The asset's calibration whose table is in force: its last complete calibration.
pub async fn in_force(store: &Store, asset: &str) -> anyhow::Result<Option<SurveyRecord>> {
    let all = store.surveys_of_asset(asset).await?;
    Ok(all.into_iter().rev().find(|r| r.is_complete() && r.is_calibration()))
}

/// What the loop did: what to print, and why a full survey was made (when
/// one was: the command then exits with [`Recalibrated`]'s status).
#[derive(Debug)]
pub struct CheckOutcome {
    /// The document and the text.
    pub output: Output,
    /// Why a full survey was made.
    pub recalibrated: Option<String>,
}

impl CheckOutcome {
    /// `Ok` in tolerance, [`Recalibrated`] when a full survey was made.
    pub fn result(self) -> anyhow::Result<()> {
        match self.recalibrated {
            Some(why) => Err(Recalibrated(why).into()),
            None => Ok(()),
        }
    }
}

/// Run the loop on the database at `db` with benches made by `bench` (see
/// the module documentation).
pub async fn run_check(
    db: &Path,
    req: &CheckRequest,
    bench: &dyn Fn(PlanSize) -> anyhow::Result<Bench>,
) -> anyhow::Result<CheckOutcome> {
    let asset = &req.asset;
    if asset == UNASSIGNED {
        return Err(bad_input(
            "--check compares with the asset's calibration in force: name the asset ([asset] id in the \
             configuration, or --asset ID)",
        ));
    }
    // A database is made only for a survey that can be made: without one,
    // the first calibration's bench is checked before the file is created.
    if !db.exists() {
        drop(bench(req.size)?);
    }
    let stop = Stop::on_signals();
    let store = Store::open(db).await?;
    let done = check_with(&store, db, req, asset, bench, &stop).await;
    store.close().await;
    let (doc, text, recalibrated) = done?;
    Ok(CheckOutcome { output: Output { doc, text }, recalibrated })
}

/// The loop on an open store: the document, the text, and why a full survey
/// was made (when one was).
async fn check_with(
    store: &Store,
    db: &Path,
    req: &CheckRequest,
    asset: &str,
    bench: &dyn Fn(PlanSize) -> anyhow::Result<Bench>,
    stop: &Stop,
) -> anyhow::Result<(Value, String, Option<String>)> {
    let Some(cal) = in_force(store, asset).await? else {
        let why = format!("no calibration of the asset {asset} is in force: a full survey calibrates it");
        eprintln!("{why}");
        let (full, text) = full_survey(store, db, req, asset, bench(req.size)?, stop).await?;
        let doc = json!({"asset": asset, "outcome": "calibrated", "reason": why, "check": null,
            "recalibration": full["run"], "table_in_force": full["table_in_force"]});
        return Ok((doc, format!("{why}\n{text}"), Some(why)));
    };
    let cal_plan = cal.plan().cloned();
    let points = req.size.points.or_else(|| cal_plan.as_ref().map(|p| check_points(p, req.polygon)));
    let mut b = bench(PlanSize { points, runs: Some(CHECK_RUNS), bidirectional: true })?;
    let new = NewSurvey { asset: asset.to_string(), check_of: Some(cal.uid.clone()), ..b.new_survey() };
    let (id, lock) = store.create_acquired_survey(&new).await?;
    store.set_started(id, b.clock.now().as_secs_f64()).await?;
    b.engine.set_stop(stop.clone());
    eprintln!(
        "survey {id}: a check of {} targets x {} runs both ways, against the table of survey {} ({})",
        b.plan.targets_deg.len(),
        b.plan.runs,
        cal.id,
        cal.uid
    );
    let options = AcquireOptions { progress: !req.json, plan_progress: b.plan_progress.clone(), ..Default::default() };
    acquire(store, id, &mut b.engine, &b.plan, 0, options).await?;
    drop(lock);
    drop(b);
    let (a, c) = (measure(store, SurveyRef::Id(cal.id)).await?, measure(store, SurveyRef::Id(id)).await?);
    let cmp = compared(&a, &c)?;
    let decision = CheckDecision {
        survey_id: id,
        against_uid: cal.uid.clone(),
        verdict: cmp.comparison.verdict.as_str().into(),
        table_holds: cmp.table_of_a_on_b.as_ref().is_some_and(|t| t.holds),
        recalibrate: cmp.decision.recalibrate,
        reason: cmp.decision.reason.clone(),
        recalibration_uid: None,
        table_file: None,
    };
    store.record_check(&decision).await?;
    // A check has no outputs of its own: its decision is what completes it.
    store.set_status(id, survey_store::survey::SurveyStatus::Complete, None).await?;
    let mut check_doc = cmp.json(&a, &c);
    check_doc["survey_id"] = id.into();
    check_doc["uid"] = c.survey.uid.clone().into();
    let mut text = cmp.text(&a, &c);
    let table_of = |r: &SurveyRecord| json!({"survey_id": r.id, "uid": r.uid});
    if !cmp.decision.recalibrate {
        text += &format!("in tolerance: the table of survey {} stays in force\n", cal.id);
        let doc = json!({"asset": asset, "outcome": "in tolerance", "recalibrate": false,
            "reason": cmp.decision.reason, "check": check_doc, "recalibration": null, "table_in_force": table_of(&cal)});
        return Ok((doc, text, None));
    }
    text += &format!("recalibrating: {}\n", cmp.decision.reason);
    eprintln!("survey {id}: recalibrating: {}", cmp.decision.reason);
    let size = PlanSize { points: cal.points, runs: cal.runs, bidirectional: cal.bidirectional };
    let (full, full_text) = full_survey(store, db, req, asset, bench(size)?, stop).await?;
    let new_uid = full["table_in_force"]["uid"].as_str().unwrap_or_default().to_string();
    store.set_recalibration(id, &new_uid, full["table_in_force"]["table"].as_str()).await?;
    text += &full_text;
    let doc = json!({"asset": asset, "outcome": "recalibrated", "recalibrate": true, "reason": cmp.decision.reason,
        "check": check_doc, "recalibration": full["run"], "table_in_force": full["table_in_force"]});
    Ok((doc, text, Some(cmp.decision.reason)))
}

/// A full survey of `asset` on `bench`, concluded as `survey run` concludes
/// one (statistics, processing, the table written): `{"run": the run's
/// document, "table_in_force": {"survey_id", "uid", "table"}}` and its text.
async fn full_survey(
    store: &Store,
    db: &Path,
    req: &CheckRequest,
    asset: &str,
    mut b: Bench,
    stop: &Stop,
) -> anyhow::Result<(Value, String)> {
    let new = NewSurvey { asset: asset.to_string(), ..b.new_survey() };
    let (id, lock) = store.create_acquired_survey(&new).await?;
    store.set_started(id, b.clock.now().as_secs_f64()).await?;
    b.engine.set_stop(stop.clone());
    eprintln!("survey {id}: a full survey, {} targets x {} runs", b.plan.targets_deg.len(), b.plan.runs);
    let options = AcquireOptions { progress: !req.json, plan_progress: b.plan_progress.clone(), ..Default::default() };
    let acquired = acquire(store, id, &mut b.engine, &b.plan, 0, options.clone()).await?;
    let finish = ConcludeOptions {
        recipe: req.recipe.clone(),
        verify: None,
        acquire: options,
        stop: stop.clone(),
        crash_when_staged: false,
        units: req.units,
    };
    let concluded = conclude(store, id, &mut b.engine, &acquired, db, finish).await?;
    drop(lock);
    concluded.result?;
    let output = concluded.output;
    let record = store.survey(id).await?;
    let table = output.doc["process"]["table"]["path"].clone();
    let doc = json!({"run": output.doc, "table_in_force": {"survey_id": id, "uid": record.uid, "table": table}});
    Ok((doc, output.text))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_check_measures_a_few_dozen_of_the_calibration_s_targets() {
        let circle = |n| SurveyPlan::full_circle(n, 5, true).unwrap();
        let points = |n| check_points(&circle(n), false);
        assert_eq!([points(360), points(1800), points(720), points(100), points(7)], [36, 36, 36, 25, 7]);
        // Every check target is then a calibration target.
        let (cal, check) = (circle(1800), circle(36));
        assert!(check.targets_deg.iter().all(|t| cal.targets_deg.iter().any(|c| (c - t).abs() < 1e-9)));
        // A partial range keeps no common grid; a polygon's faces are its targets.
        let arc = SurveyPlan::within_travel(-10.0, 90.0, 100, 5, true).unwrap();
        assert_eq!((check_points(&arc, false), check_points(&circle(24), true)), (36, 24));
    }
}
