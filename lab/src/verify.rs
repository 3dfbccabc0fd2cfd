//! The closed loop of `survey run --verify`: load the correction table into
//! the positioner through the driver trait, apply it in the feedback path,
//! and measure the corrected accuracy with a new survey (source
//! `verification`; it stores the table it applied and its own plan, so an
//! interrupted verification resumes with the same table at the same targets).
//!
//! The verification measures *between* the calibration targets
//! ([`SurveyPlan::between_targets`]): half a step from each by default, or
//! `--verify-points N` targets evenly over the same span. At the calibration
//! targets themselves the table holds what was measured there, so the error
//! it makes interpolating between them would never show. With an
//! autocollimator the only angles measured are the polygon's faces: the
//! verification stays at the faces and says so.
//!
//! It ends with a verdict ([`survey_processing::verification::judge`]): the
//! prediction is confirmed, or not (the measured corrected peak exceeds the
//! prediction by more than the table's `U`, or is not better than native).

use crate::error::bad_input;
use crate::process::ProcessOutcome;
use anyhow::Context as _;
use survey_acquire::{Engine, ReferenceKind, Timing};
use survey_bench::output::{Output, Units, iso_figures_json, iso_text};
use survey_bench::session::{AcquireOptions, acquire};
use survey_drivers::clock::with_timeout;
use survey_plan::SurveyPlan;
use survey_processing::Sample;
use survey_processing::iso230::iso230_2;
use survey_processing::table::CorrectionTable;
use survey_processing::verification::{Judged, Verdict, judge, offset_deg, peak_deg, systematic_peak_deg};
use survey_store::Store;
use survey_store::survey::{NewSurvey, Setup, SurveyRecord, SurveySource, SurveyStatus, VerificationOf};

/// Where a verification measures, decided before the calibration survey
/// starts (a bad `--verify-points` is refused before hours of measuring).
#[derive(Debug, Clone, PartialEq)]
pub struct VerifyPlan {
    /// The verification's plan.
    pub plan: SurveyPlan,
    /// Whether its targets lie between the calibration targets (`false`: at
    /// them, the polygon's faces).
    pub between: bool,
    /// The smallest distance from a verification target to a calibration
    /// target, degrees (0 at the faces).
    pub offset_deg: f64,
}

impl VerifyPlan {
    /// The verification of a survey of `plan` measured with `reference`:
    /// half a step from the targets (`points = None`) or `points` targets
    /// between them; at the faces with an autocollimator (where `points` is
    /// refused, a bad-input error).
    pub fn new(plan: &SurveyPlan, reference: ReferenceKind, points: Option<u32>) -> anyhow::Result<Self> {
        if reference == ReferenceKind::Autocollimator {
            if let Some(n) = points {
                return Err(bad_input(format!(
                    "--verify-points {n}: an autocollimator measures only at the polygon's faces, so the verification \
                     measures at the faces (leave --verify-points out)"
                )));
            }
            return Ok(VerifyPlan { plan: plan.clone(), between: false, offset_deg: 0.0 });
        }
        let verification = plan.between_targets(points)?;
        let offset_deg = offset_deg(&verification.targets_deg, &plan.targets_deg);
        Ok(VerifyPlan { plan: verification, between: true, offset_deg })
    }
}

/// Load `table` into the engine's positioner and apply it in the feedback path.
pub async fn apply_correction(engine: &mut Engine, table: &CorrectionTable) -> anyhow::Result<()> {
    let clock = engine.clock().clone();
    let name = engine.positioner_name().to_string();
    let timing = Timing::default();
    let p = engine.positioner_mut();
    with_timeout(&*clock, timing.call_timeout * 30, &name, "load correction table", p.load_correction_table(table))
        .await?;
    with_timeout(&*clock, timing.call_timeout, &name, "enable correction", p.enable_correction(true)).await?;
    Ok(())
}

/// A verification's output and its verdict.
#[derive(Debug)]
pub struct Verified {
    /// What to print (the `verify` document and its text).
    pub output: Output,
    /// The verification survey.
    pub id: i64,
    /// Confirmed or not, and why.
    pub judged: Judged,
}

impl Verified {
    /// Whether the prediction was confirmed.
    pub fn confirmed(&self) -> bool {
        self.judged.verdict == Verdict::Confirmed
    }
}

/// Verify the table of `processed` (made from `native` and its `native_samples`):
/// apply it, measure `verify_plan` as a new survey, and judge it; the text's
/// errors in `units`.
#[allow(clippy::too_many_arguments)] // what is verified, where, and how it shows: none derives from another
pub async fn verify(
    engine: &mut Engine,
    store: &Store,
    native: &SurveyRecord,
    native_samples: &[Sample],
    verify_plan: &VerifyPlan,
    processed: &ProcessOutcome,
    options: AcquireOptions,
    units: Units,
) -> anyhow::Result<Verified> {
    let table = &processed.processed.built.table;
    let plan = &verify_plan.plan;
    apply_correction(engine, table).await?;
    // The verification's own plan is stored with it (a resume measures it).
    let setup = match native.setup.clone() {
        Setup::Simulated(mut s) => {
            s.plan = plan.clone();
            Setup::Simulated(s)
        }
        Setup::Configured(mut c) => {
            c.plan = plan.clone();
            Setup::Configured(c)
        }
        other => other,
    };
    let (id, _lock) = store
        .create_acquired_survey(&NewSurvey {
            source: SurveySource::Verification,
            points: Some(plan.targets_deg.len() as u32),
            runs: Some(plan.runs),
            bidirectional: plan.bidirectional,
            setup,
            model: native.model.clone(),
            instruments: serde_json::json!({
                "rows": table.len(),
                "directional": table.is_directional(),
            }),
            verification: Some(VerificationOf {
                verifies_survey: native.id,
                table: processed.files.table_csv.display().to_string(),
                correction: Some(table.clone()),
            }),
            planned_samples: Some(plan.total_steps()),
            asset: native.asset.clone(),
            ..NewSurvey::default()
        })
        .await?;
    eprintln!(
        "survey {id}: verifying the correction table of survey {} in the positioner's feedback path, {}",
        native.id,
        placement(verify_plan)
    );
    if let Some(progress) = &options.plan_progress {
        // A simulated drift goes on growing through the verification.
        progress.continue_with(plan.targets_deg.len() as u64 * plan.directions().len() as u64);
    }
    acquire(store, id, engine, plan, 0, options).await?;
    // A verification writes no file: its figures are its outputs.
    store.set_status(id, SurveyStatus::Complete, None).await?;
    let corrected = store.samples(id).await?;
    let predicted = processed.processed.prediction.corrected_peak_deg;
    let mut out = figures(id, native.id, native_samples, &corrected, Some(predicted), table.is_directional(), units)?;
    let u = processed.uncertainty.table_u_deg;
    let judged = judge(predicted, u, peak_deg(&corrected), peak_deg(native_samples));
    out.doc["targets"] = plan.targets_deg.len().into();
    out.doc["between_targets"] = verify_plan.between.into();
    out.doc["offset_deg"] = verify_plan.offset_deg.into();
    out.doc["table_u_deg"] = u.into();
    out.doc["verdict"] = judged.verdict.as_str().into();
    out.doc["reason"] = judged.reason.clone().into();
    out.text = format!("{}\n{}{}\n", placement(verify_plan), out.text, units.text(&verdict_text(&judged)));
    Ok(Verified { output: out, id, judged })
}

/// The verdict for people: one line, plain words.
pub fn verdict_text(j: &Judged) -> String {
    match j.verdict {
        Verdict::Confirmed => format!("verdict: the prediction is confirmed: {}", j.reason),
        Verdict::NotConfirmed => format!(
            "verdict: NOT CONFIRMED: {}; do not use this table as a result (the survey and the table stay stored)",
            j.reason
        ),
    }
}

/// Where the verification measured, in words.
fn placement(v: &VerifyPlan) -> String {
    if v.between {
        format!(
            "at {} targets between the calibration targets (at least {:.4} deg from each)",
            v.plan.targets_deg.len(),
            v.offset_deg
        )
    } else {
        format!(
            "at the {} calibration targets (the polygon's faces: an autocollimator measures nowhere else)",
            v.plan.targets_deg.len()
        )
    }
}

/// The verification's figures: native against corrected, the text's errors in `units`.
pub fn figures(
    id: i64,
    native_id: i64,
    native: &[Sample],
    corrected: &[Sample],
    predicted: Option<f64>,
    directional: bool,
    units: Units,
) -> anyhow::Result<Output> {
    let iso = iso230_2(corrected).context("ISO 230-2 statistics of the verification")?;
    let (native_peak, corrected_peak) = (peak_deg(native), peak_deg(corrected));
    let doc = serde_json::json!({
        "survey_id": id,
        "verifies_survey": native_id,
        "native_peak_deg": native_peak,
        "corrected_peak_deg": corrected_peak,
        "predicted_corrected_peak_deg": predicted,
        "improvement": native_peak / corrected_peak,
        "native_systematic_peak_deg": systematic_peak_deg(native),
        "corrected_systematic_peak_deg": systematic_peak_deg(corrected),
        "directional": directional,
        "iso230_2": iso_figures_json(&iso),
    });
    let (e, unit) = (|deg: f64| units.fixed(deg, 5), units.symbol());
    let predicted = predicted.map(|p| format!(" (predicted +/-{})", e(p))).unwrap_or_default();
    let text = format!(
        "verification (survey {id}): measured with the table applied in the feedback path\n  \
         native peak +/-{} {unit}, corrected +/-{} {unit}{predicted}, {:.1}x better\n  \
         systematic part (mean over the runs): native +/-{} {unit}, corrected +/-{} {unit}\n{}",
        e(native_peak),
        e(corrected_peak),
        native_peak / corrected_peak,
        e(systematic_peak_deg(native)),
        e(systematic_peak_deg(corrected)),
        iso_text(id, &iso, units)
    );
    Ok(Output { doc, text })
}
