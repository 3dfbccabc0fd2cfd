//! What `/` shows: every asset with its calibration in force and its state,
//! and the surveys being acquired now with their progress (`/api/assets`,
//! `/api/live`). Read from the store each time it is asked, nothing kept.

use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::time::SystemTime;
use survey_lab::life::cache::{Figures, kept_summary};
use survey_lab::load::{Axis, load};
use survey_processing::iso230::iso230_2;
use survey_store::survey::{SurveyRecord, SurveyRef};
use survey_store::{CheckDecision, Store};

/// An asset's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    /// Its calibration (and table) is in force and its last check (if any)
    /// found it unchanged. Not "in tolerance": no tolerance is judged here.
    InForce,
    /// Its last check found the positioner changed, its table still holding.
    Changed,
    /// It needs a calibration: none yet, the last is older than the lab's
    /// interval, or a check called for one that was not made.
    Due,
    /// Not an asset: the surveys made without one (`unassigned`), which no
    /// calibration or check follows.
    Unassigned,
}

impl State {
    /// `in force`, `changed`, `due` or `not an asset`.
    pub fn as_str(self) -> &'static str {
        match self {
            State::InForce => "in force",
            State::Changed => "changed",
            State::Due => "due",
            State::Unassigned => "not an asset",
        }
    }
}

/// One asset on `/`.
#[derive(Debug)]
pub struct Asset {
    /// Its id.
    pub asset: String,
    /// How many surveys it has.
    pub surveys: usize,
    /// Its calibration in force (its last complete calibration) and that survey's ISO 230-2 figures.
    pub calibration: Option<(SurveyRecord, Option<Figures>)>,
    /// Its state, and why.
    pub state: (State, String),
}

/// Days from `created_at` (UTC, RFC 3339) to `now`, when it parses.
fn age_days(created_at: &str, now: SystemTime) -> Option<f64> {
    let at = humantime::parse_rfc3339(created_at).ok()?;
    Some(now.duration_since(at).unwrap_or_default().as_secs_f64() / 86_400.0)
}

/// The state of an asset whose calibration in force is `calibration`, with
/// the decisions of its check surveys (oldest first).
fn state(
    calibration: Option<&SurveyRecord>,
    checks: &[CheckDecision],
    due_after_days: f64,
    now: SystemTime,
) -> (State, String) {
    let Some(cal) = calibration else { return (State::Due, "no complete calibration yet".into()) };
    let last_check = checks.iter().rev().find(|c| c.against_uid == cal.uid);
    if let Some(c) = last_check.filter(|c| c.recalibrate && c.recalibration_uid.is_none()) {
        return (State::Due, format!("check survey {} called for a recalibration: {}", c.survey_id, c.reason));
    }
    if let Some(days) = age_days(&cal.created_at, now).filter(|&d| d > due_after_days) {
        return (State::Due, format!("calibrated {days:.0} days ago (the interval is {due_after_days} days)"));
    }
    match last_check {
        Some(c) if c.verdict == "changed" => (State::Changed, format!("check survey {}: {}", c.survey_id, c.reason)),
        Some(c) => (State::InForce, format!("check survey {}: {}", c.survey_id, c.verdict)),
        None => (State::InForce, format!("calibrated by survey {}, not checked since", cal.id)),
    }
}

/// Why the asset's next check is due by its interval's method
/// ([`survey_lab::life::due`]), when it is.
async fn overdue(store: &Store, asset: &str, now: SystemTime) -> anyhow::Result<Option<String>> {
    let due = survey_lab::life::due::due(store, Some(asset), now).await?;
    Ok(due.into_iter().find(|d| d.due.overdue).map(|d| {
        format!("its next check was due at {} ({})", survey_lab::life::due::date_of(d.due.next_due_days), d.due.reason)
    }))
}

/// Every asset of `store`, by id.
pub async fn assets(store: &Store, due_after_days: f64) -> anyhow::Result<Vec<Asset>> {
    let mut by_asset: BTreeMap<String, Vec<SurveyRecord>> = BTreeMap::new();
    // A survey's check points being measured are that survey's, not one of their own.
    for r in store.list_uncounted().await?.into_iter().filter(|r| r.resolves.is_none()) {
        by_asset.entry(r.asset.clone()).or_default().push(r);
    }
    let now = SystemTime::now();
    let mut out = Vec::with_capacity(by_asset.len());
    for (asset, mut records) in by_asset {
        records.sort_by(|a, b| (&a.created_at, a.id).cmp(&(&b.created_at, b.id)));
        let in_force = records.iter().rev().find(|r| r.is_complete() && r.is_calibration()).cloned();
        let checks = store.checks_of_asset(&asset).await?;
        let state = if asset == survey_store::asset::UNASSIGNED {
            let why = "surveys made without an asset ([asset] id or --asset): no calibration or check follows them";
            (State::Unassigned, why.to_string())
        } else {
            let st = state(in_force.as_ref(), &checks, due_after_days, now);
            match (st.0, &in_force) {
                // Its interval's method (`survey due`) may say its next check is due.
                (State::InForce | State::Changed, Some(_)) => {
                    overdue(store, &asset, now).await?.map_or(st, |why| (State::Due, why))
                }
                _ => st,
            }
        };
        let calibration = match in_force {
            Some(r) => {
                let iso = in_force_figures(store, &r).await?;
                Some((r, iso))
            }
            None => None,
        };
        out.push(Asset { asset, surveys: records.len(), calibration, state });
    }
    Ok(out)
}

/// The ISO 230-2 figures of the calibration in force `r`: its history's
/// summary (kept when it completed), else computed from its samples.
async fn in_force_figures(store: &Store, r: &SurveyRecord) -> anyhow::Result<Option<Figures>> {
    if let Some(s) = kept_summary(store, r).await? {
        return Ok(s.iso);
    }
    let loaded = load(store, Some(SurveyRef::Id(r.id)), Axis::Refitted).await?;
    Ok(iso230_2(&loaded.analysed()).ok().map(|i| Figures { a: i.a, r: i.r, b: i.b }))
}

/// `/api/assets`.
pub fn assets_json(assets: &[Asset]) -> Value {
    let rows: Vec<Value> = assets
        .iter()
        .map(|a| {
            json!({
                "asset": a.asset,
                "surveys": a.surveys,
                "state": a.state.0.as_str(),
                "reason": a.state.1,
                "calibration": a.calibration.as_ref().map(|(r, iso)| json!({
                    "id": r.id,
                    "uid": r.uid,
                    "created_at": r.created_at,
                    "A_deg": iso.as_ref().map(|i| i.a),
                    "R_deg": iso.as_ref().map(|i| i.r),
                })),
            })
        })
        .collect();
    json!({"assets": rows})
}

/// A survey being acquired now.
#[derive(Debug)]
pub struct Live {
    /// The survey (its `sample_count` is what is stored now).
    pub survey: SurveyRecord,
    /// Faults met so far: the warnings and errors in its event log.
    pub faults: usize,
    /// The time left at the pace so far, instrument seconds, once a sample is stored.
    pub time_left_s: Option<f64>,
    /// When these are a survey's check points (measured after its targets
    /// to decide the lines its analysis left in doubt, stored apart until
    /// they are folded into it): that survey, which the pages name instead.
    pub check_points_of: Option<SurveyRecord>,
}

/// The surveys of `store` being acquired (status `running`), oldest first.
pub async fn live(store: &Store) -> anyhow::Result<Vec<Live>> {
    let mut out = Vec::new();
    for survey in store.running().await? {
        let faults = store.events(survey.id).await?.iter().filter(|e| e.level == "warn" || e.level == "error").count();
        let last = store.last_sample_time(survey.id).await?;
        let done = survey.sample_count;
        let time_left_s = match (survey.started_at_s, last, survey.planned_samples) {
            (Some(t0), Some(t1), Some(planned)) if done > 0 && t1 >= t0 => {
                Some((t1 - t0) / done as f64 * planned.saturating_sub(done) as f64)
            }
            _ => None,
        };
        let check_points_of = match survey.resolves {
            Some(native) => Some(store.survey(native).await?),
            None => None,
        };
        out.push(Live { survey, faults, time_left_s, check_points_of });
    }
    Ok(out)
}

/// `/api/live`.
pub fn live_json(live: &[Live]) -> Value {
    let rows: Vec<Value> = live
        .iter()
        .map(|l| {
            let s = &l.survey;
            // A survey's check points are that survey's, on its asset.
            let named = l.check_points_of.as_ref().unwrap_or(s);
            json!({
                "id": named.id,
                "uid": named.uid,
                "asset": named.asset,
                "check_points": l.check_points_of.is_some(),
                "samples": s.sample_count,
                "planned_samples": s.planned_samples,
                "time_left_s": l.time_left_s,
                "faults": l.faults,
                "updated_at": s.updated_at,
            })
        })
        .collect();
    json!({"surveys": rows})
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;
    use survey_store::survey::SurveyStatus;

    fn check(against: &str, verdict: &str, recalibrate: bool, made: Option<&str>) -> CheckDecision {
        CheckDecision {
            survey_id: 9,
            against_uid: against.into(),
            verdict: verdict.into(),
            table_holds: !recalibrate,
            recalibrate,
            reason: "the 12 cycles/rev line moved".into(),
            recalibration_uid: made.map(Into::into),
            table_file: None,
            residual_peak_deg: None,
            stated_u_deg: None,
            cells_outside: None,
            allowed_outside: None,
        }
    }

    #[test]
    fn an_asset_is_due_changed_or_in_tolerance_from_its_calibration_and_checks() {
        let now = humantime::parse_rfc3339("2026-01-31T00:00:00Z").unwrap();
        let record = |created: &str| SurveyRecord {
            id: 3,
            uid: "u-cal".into(),
            asset: "bay-2/az".into(),
            check_of: None,
            created_at: created.into(),
            updated_at: created.into(),
            status: SurveyStatus::Complete,
            source: survey_store::survey::SurveySource::Simulated,
            points: None,
            runs: None,
            bidirectional: false,
            setup: survey_store::survey::Setup::Unrecorded,
            model: None,
            axis: None,
            instruments: Value::Null,
            verification: None,
            resolves: None,
            started_at_s: None,
            ended_at_s: None,
            planned_samples: None,
            sample_count: 0,
        };
        let recent = record("2026-01-01T00:00:00Z");
        assert_eq!(state(None, &[], 365.0, now).0, State::Due);
        assert_eq!(state(Some(&recent), &[], 365.0, now).0, State::InForce);
        assert_eq!(state(Some(&recent), &[], 20.0, now).0, State::Due, "30 days old, interval 20");
        let changed = check("u-cal", "changed", false, None);
        assert_eq!(state(Some(&recent), std::slice::from_ref(&changed), 365.0, now).0, State::Changed);
        let unchanged = check("u-cal", "unchanged", false, None);
        assert_eq!(state(Some(&recent), &[changed, unchanged], 365.0, now).0, State::InForce, "the last check");
        let called = check("u-cal", "changed", true, None);
        assert_eq!(state(Some(&recent), &[called], 365.0, now).0, State::Due);
        let other = check("u-older", "changed", true, None);
        assert_eq!(state(Some(&recent), &[other], 365.0, now).0, State::InForce, "a check of another table");
        assert_eq!(age_days("2026-01-30T00:00:00Z", now + Duration::ZERO), Some(1.0));
    }
}
