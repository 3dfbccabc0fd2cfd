//! The survey resolves its own doubts, unattended: when the processing of a
//! tracker survey leaves a line in doubt (two design harmonics at its bin,
//! or an unknown design's line that may be an alias:
//! [`survey_processing::correction::left`]), `survey run` measures check
//! points between the targets where the candidates differ most
//! ([`survey_processing::correction::resolve::plan_checks`]), within the same
//! run, and processes the survey again with them: a line decided is
//! relocated and corrected, the rest stays in `U`.
//!
//! The check points are part of the survey: acquired to a plan of their own
//! (two runs, both directions when the survey has them) as a survey of
//! source `resolving` linked to it (`resolves_survey`), so a kill leaves them
//! resumable like any acquisition (`survey resume` finishes them), and once
//! complete folded into the survey's `check_points` and that survey removed
//! ([`crate::store::Store::fold_check_points`]): survey ids stay those of
//! the surveys asked for. `survey show` lists them; every later processing
//! of the survey (`survey process`, `survey report`) takes them in
//! ([`checks_of`]). An autocollimator measures only at its polygon's faces:
//! there the processing says what a second orientation of the polygon would
//! resolve ([`second_orientation`]) instead.

use crate::acquire::{Engine, ReferenceKind};
use crate::output::Output;
use crate::process::ProcessOutcome;
use crate::session::{AcquireOptions, acquire};
use crate::store::Store;
use crate::survey::{NewSurvey, Setup, SurveyRecord, SurveySource, SurveyStatus};
use survey_processing::Sample;
use survey_processing::analysis::alias;
use survey_processing::correction::left::{Left, LeftKind};
use survey_processing::correction::resolve::plan_checks;
use survey_processing::plan::SurveyPlan;

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
            instruments: serde_json::json!({"resolves_survey": native.id, "doubts": doubts}),
            planned_samples: Some(checks.total_steps()),
            ..NewSurvey::default()
        })
        .await?;
    eprintln!(
        "survey {id}: {} check points between the targets of survey {} decide {} line(s) its analysis left in doubt",
        checks.targets_deg.len(),
        native.id,
        doubts.len()
    );
    if let Some(progress) = &options.plan_progress {
        progress.continue_with(checks.targets_deg.len() as u64 * checks.directions().len() as u64);
    }
    acquire(store, id, engine, checks, 0, options).await?;
    store.set_status(id, SurveyStatus::Complete, None).await?;
    fold(store, id, native.id).await?;
    store.check_points(native.id).await
}

/// Fold the complete check points of survey `from` into survey `into`.
pub async fn fold(store: &Store, from: i64, into: i64) -> anyhow::Result<()> {
    let n = store.fold_check_points(from, into).await?;
    eprintln!("survey {into}: {n} check points stored with it");
    Ok(())
}

/// The check points stored with `survey` (empty when it has none).
pub async fn checks_of(store: &Store, survey: &SurveyRecord) -> anyhow::Result<Vec<Sample>> {
    store.check_points(survey.id).await
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

/// The reference instrument a survey was measured with, when recorded.
pub fn reference_of(survey: &SurveyRecord) -> Option<ReferenceKind> {
    match &survey.setup {
        Setup::Simulated(s) => Some(s.reference),
        Setup::Configured(c) => Some(c.config.reference()),
        _ => None,
    }
}

/// What a second orientation of an autocollimator's polygon would resolve
/// (`None` when nothing is in doubt): turned by half a face on the table,
/// its faces fall half way between the first ones, and both orientations
/// together sample the circle at `2N` points per revolution. A line in doubt
/// is resolved by that when its candidate frequencies land on distinct bins
/// at `2N` points; else even that does not separate them.
pub fn second_orientation(left: &Left) -> Option<String> {
    let n2 = 2.0 * left.points as f64;
    let (resolved, unresolved): (Vec<_>, Vec<_>) =
        left.lines.iter().filter(|l| l.candidates.len() > 1).partition(|l| {
            let mut bins: Vec<f64> = l.candidates.iter().map(|&c| alias(c, n2).observed).collect();
            bins.sort_by(f64::total_cmp);
            bins.windows(2).all(|w| (w[1] - w[0]).abs() > 0.5)
        });
    if resolved.is_empty() && !unresolved.is_empty() {
        let c: Vec<String> = unresolved.iter().map(|l| describe(l)).collect();
        return Some(format!(
            "the polygon's faces fix where this survey measured; a second orientation (the polygon turned by half a \
             face) would not separate {}: their candidates land on one bin at {} points per revolution too",
            c.join(", "),
            n2
        ));
    }
    (!resolved.is_empty()).then(|| {
        let r: Vec<String> = resolved.iter().map(|l| describe(l)).collect();
        let rest = if unresolved.is_empty() {
            String::new()
        } else {
            let c: Vec<String> = unresolved.iter().map(|l| describe(l)).collect();
            format!("; it would not separate {}", c.join(", "))
        };
        format!(
            "the polygon's faces fix where this survey measured: measured again with the polygon turned by half a \
             face on the table, the faces fall half way between these, and both orientations together ({n2} points \
             per revolution) would resolve {}{rest}",
            r.join(", ")
        )
    })
}

fn describe(l: &survey_processing::correction::left::LeftLine) -> String {
    let c: Vec<String> = l.candidates.iter().map(|c| format!("{c}")).collect();
    let what = match l.kind {
        LeftKind::NotCarried => "not carried",
        LeftKind::MaybeAlias => "kept where it is seen",
    };
    format!("the line at bin {} ({} cycles/rev, {what})", l.observed_cycles, c.join(" or "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_processing::correction::left::LeftLine;

    fn left(points: usize, lines: &[(f64, &[f64], LeftKind)]) -> Left {
        Left {
            lines: lines
                .iter()
                .map(|&(bin, c, kind)| LeftLine {
                    observed_cycles: bin,
                    amplitude_deg: 0.01,
                    phase_deg: 0.0,
                    noise_sd_deg: 0.0,
                    kind,
                    candidates: c.to_vec(),
                    why: String::new(),
                })
                .collect(),
            points,
            start_deg: 0.0,
            worst: None,
            second_order_deg: 0.0,
        }
    }

    #[test]
    fn a_second_orientation_says_what_twice_the_faces_resolve() {
        // 24 faces, Figure 8's design: bin 4 holds 20 and 100, bin 8 holds 40
        // and 80. At 48 points they land on 20, 4, 8 and 16: all resolved.
        let l = left(24, &[(4.0, &[20.0, 100.0], LeftKind::NotCarried), (8.0, &[40.0, 80.0], LeftKind::NotCarried)]);
        let t = second_orientation(&l).unwrap();
        assert!(t.contains("would resolve the line at bin 4") && t.contains("bin 8"), "{t}");
        assert!(!t.contains("not separate"), "{t}");
        // An unknown design at 36 faces: 16 may be 20 or 52, which land on one
        // bin (20) at 72 points too.
        let l = left(36, &[(16.0, &[16.0, 20.0, 52.0], LeftKind::MaybeAlias)]);
        let t = second_orientation(&l).unwrap();
        assert!(t.contains("would not separate the line at bin 16"), "{t}");
        assert_eq!(second_orientation(&left(24, &[])), None);
    }
}
