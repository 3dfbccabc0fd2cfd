//! The survey resolves its own doubts, unattended: when the processing of a
//! tracker survey leaves a line in doubt (two design harmonics at its bin,
//! or an unknown design's line that may be an alias:
//! [`survey_tables::left`]), `survey run` measures check
//! points between the targets where the candidates differ most
//! ([`survey_tables::resolve::plan_checks`]), within the same
//! run, and processes the survey again with them: a line decided is
//! relocated and corrected, the rest stays in `U`.
//!
//! The check points are part of the survey: acquired to a plan of their own
//! (two runs, both directions when the survey has them) as a survey of
//! source `resolving` linked to it (`resolves_survey`), so a kill leaves them
//! resumable like any acquisition (`survey resume` finishes them), and once
//! complete folded into the survey's `check_points` and that survey removed
//! ([`survey_store::Store::fold_check_points`]): survey ids stay those of
//! the surveys asked for. `survey show` lists them; every later processing
//! of the survey (`survey process`, `survey report`) takes them in
//! ([`survey_store::Store::check_points`]). An autocollimator measures only at its polygon's faces:
//! there the processing says what a second orientation of the polygon would
//! resolve
//! ([`survey_tables::resolve::second_orientation`]) instead.

use crate::process::ProcessOutcome;
use survey_acquire::{Engine, ReferenceKind};
use survey_bench::output::Output;
use survey_bench::session::{AcquireOptions, acquire};
use survey_plan::SurveyPlan;
use survey_processing::Sample;
use survey_store::Store;
use survey_store::survey::{NewSurvey, Setup, SurveyRecord, SurveySource, SurveyStatus};
use survey_tables::left::Left;
use survey_tables::resolve::plan_checks;

/// Runs of the check points (enough for their own noise).
const RUNS: u32 = 2;

/// The check points' plan for what `processed` leaves in doubt on a survey
/// of `plan` measured with `reference` (`None`: nothing in doubt, or a
/// reference that cannot measure between the targets, or a partial range).
pub fn checks_plan(plan: &SurveyPlan, reference: ReferenceKind, processed: &ProcessOutcome) -> Option<SurveyPlan> {
    if reference != ReferenceKind::Tracker {
        return None;
    }
    let p = &processed.processed;
    let targets = &p.analysis.error_map.targets_deg;
    let at = plan_checks(&p.left, targets);
    (!at.is_empty()).then(|| SurveyPlan { targets_deg: at, runs: RUNS, ..plan.clone() })
}

/// Measure `checks` for survey `native` (as a resolving survey, then folded
/// into `native`) and return the check points.
pub async fn measure(
    engine: &mut Engine,
    store: &Store,
    native: &SurveyRecord,
    checks: &SurveyPlan,
    left: &Left,
    options: AcquireOptions,
) -> anyhow::Result<Vec<Sample>> {
    let setup = match native.setup.clone() {
        Setup::Simulated(mut s) => {
            s.plan = checks.clone();
            Setup::Simulated(s)
        }
        Setup::Configured(mut c) => {
            c.plan = checks.clone();
            Setup::Configured(c)
        }
        other => other,
    };
    let doubts: Vec<serde_json::Value> = left
        .lines
        .iter()
        .filter(|l| l.candidates.len() > 1)
        .map(|l| serde_json::json!({"observed_cycles": l.observed_cycles, "candidates": l.candidates}))
        .collect();
    let (id, _lock) = store
        .create_acquired_survey(&NewSurvey {
            source: SurveySource::Resolving,
            points: Some(checks.targets_deg.len() as u32),
            runs: Some(checks.runs),
            bidirectional: checks.bidirectional,
            setup,
            model: native.model.clone(),
            instruments: serde_json::json!({"resolves_survey": native.id, "doubts": doubts, "folds": left.folds}),
            planned_samples: Some(checks.total_steps()),
            ..NewSurvey::default()
        })
        .await?;
    // Named by the survey they belong to: their own survey is folded into it.
    let folds = match left.folds.len() {
        0 => String::new(),
        n => format!(" and measure {n} line(s) the design does not name that fold onto the bins the table holds"),
    };
    survey_bench::say!(
        "survey {}: {} check points between its targets decide {} line(s) its analysis left in doubt{folds}",
        native.id,
        checks.targets_deg.len(),
        doubts.len()
    );
    if let Some(progress) = &options.plan_progress {
        progress.continue_with(checks.targets_deg.len() as u64 * checks.directions().len() as u64);
    }
    // A test's simulated power loss counts every sample of the run, the
    // survey's own first.
    let done = native.plan().map_or(0, SurveyPlan::total_steps);
    let options = AcquireOptions { crash_after: options.crash_after.map(|n| n.saturating_sub(done)), ..options };
    acquire(store, id, engine, checks, 0, options).await?;
    store.set_status(id, SurveyStatus::Complete, None).await?;
    fold(store, id, native.id).await?;
    store.check_points(native.id).await
}

/// Fold the complete check points of survey `from` into survey `into`.
pub async fn fold(store: &Store, from: i64, into: i64) -> anyhow::Result<()> {
    let n = store.fold_check_points(from, into).await?;
    survey_bench::say!("survey {into}: {n} check points stored with it");
    Ok(())
}

/// What the check points decided, for the output.
pub fn output(points: usize, processed: &ProcessOutcome) -> Output {
    let r = &processed.processed.resolutions;
    let doc = serde_json::json!({"check_points": points, "resolutions": r});
    let mut text = format!("check points ({points} samples between the targets):\n");
    for x in r {
        text += &format!("  {}\n", x.why);
    }
    Output { doc, text }
}
