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

use super::{Compared, Measured, compared_placing, control, measure};
use crate::conclude::{ConcludeOptions, conclude};
use crate::correction::{self, Before, Choice};
use crate::error::{Recalibrated, bad_input};
use serde_json::{Value, json};
use std::path::Path;
use std::time::SystemTime;
use survey_acquire::stop::Stop;
use survey_bench::Bench;
use survey_bench::output::Output;
use survey_bench::session::{AcquireOptions, acquire};
use survey_modelgap::compare::seen::{Blind, CalibrationGrid, CheckDesign, Unseen, design_check_avoiding};
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
    /// What the asset's first calibration does when the positioner applies
    /// a correction (`--correction`; a recalibration after a check that found
    /// the correction on switches it off: the table in force is replaced).
    pub correction: Choice,
    /// Only when the asset's next check is due (`--due`: [`super::due`]);
    /// otherwise nothing is measured and the outcome is `not due`.
    pub only_due: bool,
    /// The time the loop runs at: `None`, the system clock's (the command
    /// line); given, a virtual clock's (a simulated year of weekly checks):
    /// what is due is judged at it, and the surveys the loop makes are
    /// dated at it (their `created_at`, which the intervals read).
    pub at: Option<SystemTime>,
}

/// The grid a check is designed on: the calibration's targets (a full
/// circle, or the arc they span), or a polygon's faces.
pub fn grid_of(plan: &SurveyPlan, polygon: bool) -> CalibrationGrid {
    let t = &plan.targets_deg;
    let n = t.len() as u32;
    let full_circle = n >= 2 && t[0] == 0.0 && (t[1] * f64::from(n) - 360.0).abs() < 1e-9;
    let arc_deg = (!full_circle && n >= 2).then(|| t[t.len() - 1] - t[0]);
    CalibrationGrid { points: n, arc_deg, polygon }
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
    /// What the check could not see of the table in force, when it found
    /// no change in what it could: no "in tolerance" is then said (exit 1).
    pub unseen: Option<String>,
}

impl CheckOutcome {
    /// `Ok` in tolerance, [`Recalibrated`] when a full survey was made, a
    /// run-time failure naming what the check could not see when it could
    /// not decide.
    pub fn result(self) -> anyhow::Result<()> {
        match (self.recalibrated, self.unseen) {
            (Some(why), _) => Err(Recalibrated(why).into()),
            (None, Some(unseen)) => Err(anyhow::anyhow!("the check cannot say the asset is in tolerance: {unseen}")),
            (None, None) => Ok(()),
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
    let (doc, text, recalibrated, unseen) = done?;
    Ok(CheckOutcome { output: Output { doc, text }, recalibrated, unseen })
}

/// The loop on an open store: the document, the text, why a full survey
/// was made (when one was), and what the check could not see (when it
/// could not decide).
async fn check_with(
    store: &Store,
    db: &Path,
    req: &CheckRequest,
    asset: &str,
    bench: &dyn Fn(PlanSize) -> anyhow::Result<Bench>,
    stop: &Stop,
) -> anyhow::Result<(Value, String, Option<String>, Option<String>)> {
    if req.only_due
        && let Some((doc, text)) = not_due(store, asset, req.at.unwrap_or_else(SystemTime::now)).await?
    {
        return Ok((doc, text, None, None));
    }
    let Some(cal) = in_force(store, asset).await? else {
        let why = format!("no calibration of the asset {asset} is in force: a full survey calibrates it");
        survey_bench::say!("{why}");
        let (full, text) = full_survey(store, db, req, asset, (bench(req.size)?, req.correction), stop).await?;
        let doc = json!({"asset": asset, "outcome": "calibrated", "reason": why, "check": null,
            "recalibration": full["run"], "table_in_force": full["table_in_force"]});
        return Ok((doc, format!("{why}\n{text}"), Some(why), None));
    };
    // The table in force first: the check is designed to see its lines.
    let a = measure(store, SurveyRef::Id(cal.id)).await?;
    // Lines the calibration's own targets cannot place (aliases in doubt) show
    // elsewhere on the check's grid: the table's check judges what they leave.
    let doubt: Vec<f64> = a.lines_in_doubt().iter().map(|(bin, _)| *bin).collect();
    let mut lines: Vec<f64> = std::iter::once(1.0)
        .chain(a.main_lines().iter().map(|l| l.cycles_per_rev))
        .filter(|k| !doubt.contains(k))
        .collect();
    // And every line the asset's history has seen (its kept summaries).
    for k in super::lines_seen(store, asset).await? {
        if !lines.contains(&k) && !doubt.contains(&k) {
            lines.push(k);
        }
    }
    // Successive checks see different bins: the last check's grid (any
    // check of the asset, decided or not).
    let checks = store.surveys_of_asset(asset).await?;
    let previous =
        checks.iter().rev().find(|r| r.check_of.is_some()).and_then(|r| r.plan()).map(|p| p.targets_deg.len() as u32);
    let avoid = &a.design_frequencies;
    // A check that could not decide (a line it could not see or place) is
    // followed by one on the calibration's own targets, which placed every
    // line the calibration corrected: the loop measures more rather than
    // stay undecided check after check.
    let decided: Vec<i64> = store.checks_of_asset(asset).await?.iter().map(|d| d.survey_id).collect();
    let last_undecided = undecided_before(&cal, &checks, &decided);
    let requested = req.size.points.or(last_undecided.and(cal.plan().map(|p| p.targets_deg.len() as u32)));
    let design = cal.plan().map(|p| {
        let d = design_check_avoiding(grid_of(p, req.polygon), &lines, avoid, requested, previous);
        match last_undecided.filter(|_| req.size.points.is_none() && !req.polygon) {
            Some(id) => CheckDesign {
                why: format!(
                    "{} targets, the calibration's own: the last check of this table (survey {id}) could not decide",
                    d.points
                ),
                ..d
            },
            None => d,
        }
    });
    let points = design.as_ref().map(|d| d.points).or(req.size.points);
    let mut b = bench(PlanSize { points, runs: Some(CHECK_RUNS), bidirectional: true })?;
    // The check measures the axis as it finds it, and leaves it so.
    let found = match correction::read(&mut b.engine).await {
        Ok(Some(true)) => Before::On,
        Ok(Some(false)) => Before::Off,
        Ok(None) => {
            Before::Unknown(format!("{} cannot report whether it applies a correction", b.engine.positioner_name()))
        }
        // Not answering now: the acquisition survives it or stops the check.
        Err(e) => Before::Unknown(format!("it could not be read: {e:#}")),
    };
    let mut new = NewSurvey { asset: asset.to_string(), check_of: Some(cal.uid.clone()), ..b.new_survey() };
    new.instruments["correction"] = found.as_str().into();
    new.instruments["identified"] = crate::identify::read(&mut b.engine).await;
    let (id, lock) = store.create_acquired_survey(&new).await?;
    dated(store, id, req).await?;
    store.set_started(id, b.clock.now().as_secs_f64()).await?;
    b.engine.set_stop(stop.clone());
    survey_bench::say!(
        "survey {id}: a check of {} targets x {} runs both ways, against the table of survey {} ({})",
        b.plan.targets_deg.len(),
        b.plan.runs,
        cal.id,
        cal.uid
    );
    if let Some(d) = &design {
        survey_bench::say!("survey {id}: {}", d.why);
        for u in &d.unseen {
            survey_bench::say!("survey {id}: cannot see the {} cycles/rev line: {}", u.cycles_per_rev, u.why);
        }
    }
    let options = AcquireOptions { progress: !req.json, plan_progress: b.plan_progress.clone(), ..Default::default() };
    acquire(store, id, &mut b.engine, &b.plan, 0, options).await?;
    drop(lock);
    drop(b);
    let mut c = measure(store, SurveyRef::Id(id)).await?;
    let corrected = found == Before::On;
    if corrected {
        as_native(&mut c, &a)?;
    }
    // A line the check's targets cannot place may be placed by the last
    // decided check of this table on the calibration's own targets (the
    // one after a check left undecided): later checks then decide too.
    let placing = match placing_check(&cal, &checks, &decided) {
        Some(id) => vec![measure(store, SurveyRef::Id(id)).await?],
        None => Vec::new(),
    };
    let cmp = compared_placing(&a, &c, &placing)?;
    // What of the table in force the check could not see: by its design, or
    // by the comparison (a line not estimable at its targets).
    let mut unseen: Vec<Unseen> = design.as_ref().map_or_else(Vec::new, |d| d.unseen.clone());
    for u in &cmp.comparison.not_estimable {
        if lines.contains(&u.cycles_per_rev) && !unseen.iter().any(|v| v.cycles_per_rev == u.cycles_per_rev) {
            unseen.push(u.clone());
        }
    }
    // Out of control on the asset's chart, a check decides even what it
    // could not see line by line: the table in force no longer behaves.
    let (point, recalibrate, reason) = charted(store, asset, &cal, &cmp).await?;
    if !recalibrate && !unseen.is_empty() {
        return undecided(store, id, &cal, &a, &c, &cmp, design.as_ref(), &unseen).await;
    }
    let held = cmp.table_of_a_on_b.as_ref();
    let decision = CheckDecision {
        survey_id: id,
        against_uid: cal.uid.clone(),
        verdict: cmp.comparison.verdict.as_str().into(),
        table_holds: held.is_some_and(|t| t.holds),
        recalibrate,
        reason: reason.clone(),
        recalibration_uid: None,
        table_file: None,
        residual_peak_deg: held.map(|t| t.residual_peak_deg),
        stated_u_deg: held.map(|t| t.stated_u_deg),
        cells_outside: held.map(|t| t.cells_outside as i64),
        allowed_outside: held.map(|t| t.allowed_outside as i64),
    };
    store.record_check(&decision).await?;
    // A check has no outputs of its own: its decision is what completes it.
    store.set_status(id, survey_store::survey::SurveyStatus::Complete, None).await?;
    keep_history(store, &a, &c, asset, id).await;
    let mut check_doc = check_json(&cmp, &a, &c, design.as_ref());
    check_doc["correction"] = found.as_str().into();
    check_doc["control"] = point.json();
    let mut text = design_text(design.as_ref()) + &measured_text(&found) + &cmp.text(&a, &c);
    let table_of = |r: &SurveyRecord| json!({"survey_id": r.id, "uid": r.uid});
    if !recalibrate {
        let outcome = if cmp.decision.changed { "changed, the table holds" } else { "in tolerance" };
        text += &format!("{outcome}: the table of survey {} stays in force\n", cal.id);
        let blind = design.as_ref().map(|d| blind_text(d, asset)).unwrap_or_default();
        text += &blind;
        let doc = json!({"asset": asset, "outcome": outcome, "recalibrate": false,
            "reason": reason, "check": check_doc, "recalibration": null, "table_in_force": table_of(&cal),
            "blind": blind.trim_end()});
        return Ok((doc, text, None, None));
    }
    text += &format!("recalibrating: {reason}\n");
    survey_bench::say!("survey {id}: recalibrating: {reason}");
    let size = PlanSize { points: cal.points, runs: cal.runs, bidirectional: cal.bidirectional };
    // A correction found on is the table being replaced: off for the calibration.
    let choice = if corrected { Choice::Off } else { req.correction };
    let (full, full_text) = full_survey(store, db, req, asset, (bench(size)?, choice), stop).await?;
    let new_uid = full["table_in_force"]["uid"].as_str().unwrap_or_default().to_string();
    store.set_recalibration(id, &new_uid, full["table_in_force"]["table"].as_str()).await?;
    text += &full_text;
    let doc = json!({"asset": asset, "outcome": "recalibrated", "recalibrate": true, "reason": reason,
        "check": check_doc, "recalibration": full["run"], "table_in_force": full["table_in_force"]});
    Ok((doc, text, Some(reason), None))
}

/// A survey the loop made on a virtual clock ([`CheckRequest::at`]) dated
/// at its time; on the system clock the store dates it.
async fn dated(store: &Store, id: i64, req: &CheckRequest) -> anyhow::Result<()> {
    match req.at {
        Some(at) => store.set_created_at(id, at).await,
        None => Ok(()),
    }
}

/// With `--due`: the document and text saying the asset is not due yet
/// at `now` (nothing measured), or `None` when it is due.
async fn not_due(store: &Store, asset: &str, now: SystemTime) -> anyhow::Result<Option<(Value, String)>> {
    let due = super::due::due(store, Some(asset), now).await?;
    let Some(d) = due.first().filter(|d| !d.due.overdue) else { return Ok(None) };
    let why = format!(
        "not due: the next check of {asset} is due at {} ({})",
        super::due::date_of(d.due.next_due_days),
        d.due.reason
    );
    let doc = json!({"asset": asset, "outcome": "not due", "recalibrate": false, "reason": why,
        "due": d.json(), "check": null, "recalibration": null});
    Ok(Some((doc, format!("{why}: nothing measured\n"))))
}

/// The check `cmp` against the calibration in force `cal` on the asset's
/// control chart, and what to do: recalibrate (by the comparison, or out
/// of control even inside tolerance) and why.
async fn charted(
    store: &Store,
    asset: &str,
    cal: &SurveyRecord,
    cmp: &Compared,
) -> anyhow::Result<(control::Point, bool, String)> {
    let held = cmp.table_of_a_on_b.as_ref();
    let statistic = held.map(|t| control::statistic(t.cells_outside, t.allowed_outside));
    let earlier: Vec<control::Check> = store.checks_of_asset(asset).await?.iter().map(control::Check::of).collect();
    let now = control::Check {
        statistic,
        calibration: cal.uid.clone(),
        out_of_tolerance: false,
        step: held.map(|t| 1.0 / (t.allowed_outside as f64 + 1.0)),
    };
    let point = control::next(&earlier, &control::chart(&earlier), &now);
    if cmp.decision.recalibrate || !point.out_of_control() {
        return Ok((point, cmp.decision.recalibrate, cmp.decision.reason.clone()));
    }
    let reason = format!(
        "{} ({}): the table holds, but this check is unlike the asset's earlier ones (statistic {:.3}, limits {} \
         to {}): recalibrating",
        control::OUT_OF_CONTROL,
        point.rules.join(", "),
        point.statistic.unwrap_or(f64::NAN),
        point.lower().map_or("-".into(), |v| format!("{v:.3}")),
        point.upper().map_or("-".into(), |v| format!("{v:.3}")),
    );
    Ok((point, true, reason))
}

/// A check measured with the correction on: its samples with the table in
/// force (the calibration's, as processed now) added back to their errors,
/// the native axis as the controller's correction leaves it to be seen (the
/// table the controller applies is taken to be the table in force; its
/// second-order effect, the table's slope times the error, is below the
/// noise). Then the lines, the backlash and the map compare with the
/// calibration as for a native check, and the table's check is the
/// corrected axis against the table's predicted residual and its U.
fn as_native(check: &mut Measured, cal: &Measured) -> anyhow::Result<()> {
    let table = match &cal.table {
        Ok(table) => table,
        Err(why) => {
            return Err(anyhow::anyhow!(
                "the check measured the corrected axis, and the table in force (survey {}) cannot be made again to \
                 judge it: {why}",
                cal.survey.id
            ));
        }
    };
    for s in &mut check.samples {
        s.readout_deg += table.error_at(s.readout_deg, s.direction);
    }
    Ok(())
}

/// What the check measured, by the correction it found: the lines of the text.
fn measured_text(found: &Before) -> String {
    match found {
        Before::On => "the correction at the positioner was on: the check measured the corrected axis, judged with \
                       the table in force added back (against the calibration) and as it is (against the table's \
                       predicted residual and U); the check leaves it on\n"
            .into(),
        Before::Unknown(why) => {
            format!("correction at the positioner: unknown ({why}): the check takes the axis as native\n")
        }
        _ => String::new(),
    }
}

/// Keep the history of the check `c` (survey `id`) compared with the
/// calibration in force `a`, and what else its asset's history lacks: a
/// failure is said, not returned (the check is decided and stored).
async fn keep_history(store: &Store, a: &Measured, c: &Measured, asset: &str, id: i64) {
    if let Err(e) = super::cache::keep_compared(store, a, c).await {
        tracing::warn!("survey {id}: its comparison could not be kept in the history of {asset} ({e:#})");
    }
    super::cache::fill_after(store, asset, id).await;
}

/// The check's document: the comparison, its survey and its design.
fn check_json(cmp: &Compared, a: &Measured, c: &Measured, design: Option<&CheckDesign>) -> Value {
    let mut doc = cmp.json(a, c);
    doc["survey_id"] = c.survey.id.into();
    doc["uid"] = c.survey.uid.clone().into();
    doc["design"] = match design {
        Some(d) => {
            // The lines asked for that it could not see, then the bins where
            // a new line would hide.
            let kind = |kind: &'static str| move |u: &Unseen| json!({"cycles_per_rev": u.cycles_per_rev, "why": u.why, "kind": kind});
            let unseen: Vec<Value> = d
                .unseen
                .iter()
                .map(kind("in force"))
                .chain(d.blind.iter().map(|(_, u)| u).map(kind("new line")))
                .collect();
            json!({"points": d.points, "why": d.why, "unseen": unseen, "up_to_cycles_per_rev": d.up_to,
                "previous_points": d.previous})
        }
        None => Value::Null,
    };
    doc
}

/// What a check's targets could not see of a new line, qualifying its "the
/// table holds": the bins by kind, and that the next check looks elsewhere.
fn blind_text(d: &CheckDesign, asset: &str) -> String {
    if d.blind.is_empty() {
        return format!(
            "its {} targets see every line up to {} cycles/rev apart from the mean and the Nyquist bin; above it \
             (the calibration's own Nyquist bin) it answers for no line, as the calibration could not place one\n",
            d.points, d.up_to
        );
    }
    let of = |kind: Blind| {
        let ks: Vec<String> =
            d.blind.iter().filter(|(b, _)| *b == kind).map(|(_, u)| format!("{}", u.cycles_per_rev)).collect();
        ks.join(", ")
    };
    let mut parts = Vec::new();
    for (kind, said) in
        [(Blind::Mean, "the mean"), (Blind::Nyquist, "the Nyquist bin"), (Blind::LineInForce, "a line in force's bin")]
    {
        let ks = of(kind);
        if !ks.is_empty() {
            parts.push(format!("{ks} cycles/rev ({said})"));
        }
    }
    format!(
        "as far as its {} targets see: a new line at {} would not be seen (each listed in unseen, up to {} cycles/rev, \
         the calibration's own Nyquist bin: above it the check answers for no line, as the calibration could not \
         place one); the next check of {asset} chooses targets blind elsewhere\n",
        d.points,
        parts.join("; "),
        d.up_to
    )
}

/// The asset's last check survey (of `surveys`, the asset's), when it was
/// of the table in force (`cal`), complete and left without a decision
/// ([`undecided`]; `decided`: the surveys with one).
fn undecided_before(cal: &SurveyRecord, surveys: &[SurveyRecord], decided: &[i64]) -> Option<i64> {
    let last = surveys.iter().rev().find(|r| r.check_of.is_some())?;
    let of_cal = last.check_of.as_deref() == Some(cal.uid.as_str());
    (of_cal && last.is_complete() && !decided.contains(&last.id)).then_some(last.id)
}

/// The asset's last decided check of the table in force (`cal`) made on
/// the calibration's own targets, when there is one.
fn placing_check(cal: &SurveyRecord, surveys: &[SurveyRecord], decided: &[i64]) -> Option<i64> {
    let n = cal.plan()?.targets_deg.len();
    surveys
        .iter()
        .rev()
        .filter(|r| r.check_of.as_deref() == Some(cal.uid.as_str()) && decided.contains(&r.id))
        .find(|r| r.plan().is_some_and(|p| p.targets_deg.len() == n))
        .map(|r| r.id)
}

/// The design's lines of the text (none without one).
fn design_text(design: Option<&CheckDesign>) -> String {
    design.map_or_else(String::new, |d| format!("check design: {}\n", d.why))
}

/// The check found no change in what it could see, but could not see part
/// of the table in force: no decision is stored and nothing is said to be
/// in tolerance (the command exits 1 naming what it could not see).
#[allow(clippy::too_many_arguments)]
async fn undecided(
    store: &Store,
    id: i64,
    cal: &SurveyRecord,
    a: &Measured,
    c: &Measured,
    cmp: &Compared,
    design: Option<&CheckDesign>,
    unseen: &[Unseen],
) -> anyhow::Result<(Value, String, Option<String>, Option<String>)> {
    store.set_status(id, survey_store::survey::SurveyStatus::Complete, None).await?;
    keep_history(store, a, c, &cal.asset, id).await;
    let what: Vec<String> =
        unseen.iter().map(|u| format!("the {} cycles/rev line ({})", u.cycles_per_rev, u.why)).collect();
    let why = format!(
        "no change in what it could see, but it could not see {}: measure a check with more targets (--points) or \
         recalibrate",
        what.join("; ")
    );
    let mut text = design_text(design) + &cmp.text(a, c);
    text += &format!("not decided: {why}\n");
    let doc = json!({"asset": cal.asset, "outcome": "not decided", "recalibrate": false, "reason": why,
        "check": check_json(cmp, a, c, design), "recalibration": null,
        "table_in_force": {"survey_id": cal.id, "uid": cal.uid}});
    Ok((doc, text, None, Some(why)))
}

/// A full survey of `asset` on `bench`, concluded as `survey run` concludes
/// one (statistics, processing, the table written): `{"run": the run's
/// document, "table_in_force": {"survey_id", "uid", "table"}}` and its text.
async fn full_survey(
    store: &Store,
    db: &Path,
    req: &CheckRequest,
    asset: &str,
    (mut b, choice): (Bench, Choice),
    stop: &Stop,
) -> anyhow::Result<(Value, String)> {
    let before = correction::before_calibration(&mut b.engine, choice).await?;
    let mut new = NewSurvey { asset: asset.to_string(), ..b.new_survey() };
    new.instruments["correction"] = before.as_str().into();
    new.instruments["identified"] = crate::identify::read(&mut b.engine).await;
    let (id, lock) = store.create_acquired_survey(&new).await?;
    dated(store, id, req).await?;
    store.set_started(id, b.clock.now().as_secs_f64()).await?;
    if before == Before::SwitchedOff {
        let at = b.clock.now().as_secs_f64();
        store.log_event(id, at, "info", "the positioner applied a correction: switched off before the survey").await?;
    }
    b.engine.set_stop(stop.clone());
    survey_bench::say!("survey {id}: a full survey, {} targets x {} runs", b.plan.targets_deg.len(), b.plan.runs);
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
    super::cache::fill_after(store, asset, id).await;
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
    fn the_grid_of_a_calibration_is_its_circle_its_arc_or_its_faces() {
        let circle = SurveyPlan::full_circle(120, 2, true).unwrap();
        assert_eq!(grid_of(&circle, false), CalibrationGrid { points: 120, arc_deg: None, polygon: false });
        let arc = SurveyPlan::within_travel(-10.0, 90.0, 101, 2, true).unwrap();
        let span = arc.targets_deg[100] - arc.targets_deg[0];
        assert_eq!(grid_of(&arc, false), CalibrationGrid { points: 101, arc_deg: Some(span), polygon: false });
        assert!(span > 90.0 && span <= 100.0, "{span}");
        assert!(grid_of(&SurveyPlan::full_circle(24, 2, true).unwrap(), true).polygon);
    }
}
