//! The closed loop of `survey run --verify`: load the correction table into
//! the positioner through the driver trait, apply it in the feedback path,
//! and measure the corrected accuracy with a new survey (source
//! `verification`; it stores the table it applied and its own plan, so an
//! interrupted verification resumes with the same table at the same targets).
//!
//! The verification measures *between* the calibration targets
//! ([`SurveyPlan::between_targets`]): half a step from each by default,
//! joined by a second spacing where that alone would share the calibration's
//! alias ([`VerifyPlan::seeing`]), or `--verify-points N` targets evenly over
//! the same span. At the calibration targets themselves the table holds what
//! was measured there, so the error it makes interpolating between them
//! would never show; and a verification that could not have seen the table
//! fail ([`blind`]) confirms nothing. With an
//! autocollimator the only angles measured are the polygon's faces: the
//! verification stays at the faces and says so.
//!
//! It ends with a verdict ([`survey_tables::verification::judge`]): the
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
use survey_processing::analysis::{AnalysisOptions, design_candidates};
use survey_processing::iso230::iso230_2;
use survey_processing::table::CorrectionTable;
use survey_store::Store;
use survey_store::survey::{NewSurvey, Setup, SurveyRecord, SurveySource, SurveyStatus, VerificationOf};
use survey_tables::pipeline::Processed;
use survey_tables::recipe::LineAction;
use survey_tables::verification::{Claim, Judged, Verdict, aliases, judge, offset_deg, peak_deg, systematic_peak_deg};

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
    /// The targets were asked for (`--verify-points`): measured as asked.
    pub asked: bool,
    /// Targets of a second spacing joined to the half-step ones (0: none),
    /// so that no plausible alias of the table's lines hides between them
    /// ([`VerifyPlan::seeing`]).
    pub second: usize,
    /// The count was chosen, not one a calibration target, so that no
    /// plausible alias of the table's lines hides between the targets.
    pub resized: bool,
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
            return Ok(VerifyPlan {
                plan: plan.clone(),
                between: false,
                offset_deg: 0.0,
                asked: false,
                second: 0,
                resized: false,
            });
        }
        let verification = plan.between_targets(points)?;
        let offset_deg = offset_deg(&verification.targets_deg, &plan.targets_deg);
        Ok(VerifyPlan {
            plan: verification,
            between: true,
            offset_deg,
            asked: points.is_some(),
            second: 0,
            resized: false,
        })
    }

    /// The plan that can see the table of `processed` (made at `calibration`'s
    /// targets, of `survey`) fail: half a step from a full circle's targets
    /// is blind to a plausible line in an even band of the calibration's
    /// count (`2 k N +- t`, a whole turn of phase there: issue 37's 43 cycles/rev
    /// line at 20 targets), so a second set of targets at a quarter of its
    /// own step is joined, the fewest that see every plausible line
    /// ([`survey_tables::verification::aliases`]). Targets asked for, a
    /// polygon's faces, a partial range and a continuous scan are kept as
    /// they are (the verdict says what they could not see).
    pub fn seeing(self, calibration: &SurveyPlan, survey: &SurveyRecord, processed: &ProcessOutcome) -> VerifyPlan {
        let full_circle =
            (calibration.targets_deg.len() as f64 * calibration.targets_deg.get(1).copied().unwrap_or(0.0) - 360.0)
                .abs()
                < 1e-9;
        if !self.between || self.asked || self.plan.continuous() || !full_circle {
            return self;
        }
        let (lines, f_max) = (table_lines(&processed.processed), plausible_max(survey));
        let cal = &calibration.targets_deg;
        if aliases::blind(cal, &self.plan.targets_deg, &lines, f_max).is_empty() {
            return self;
        }
        // One evenly spaced set first (every move alike, about as many
        // samples as the calibration's): the fewest targets from n to 2n,
        // half their own step from 0, that see every plausible line.
        let single = (cal.len() + 1..=2 * cal.len()).find_map(|p| {
            let plan = calibration.between_targets(Some(p as u32)).ok()?;
            aliases::blind(cal, &plan.targets_deg, &lines, f_max).is_empty().then_some(plan)
        });
        if let Some(plan) = single {
            let offset_deg = offset_deg(&plan.targets_deg, cal);
            return VerifyPlan { plan, offset_deg, resized: true, ..self };
        }
        let most = 3 * cal.len();
        match aliases::second_spacing(cal, &self.plan.targets_deg, &lines, f_max, most) {
            Some((second, targets)) => {
                let offset_deg = offset_deg(&targets, &calibration.targets_deg);
                VerifyPlan { plan: SurveyPlan { targets_deg: targets, ..self.plan }, offset_deg, second, ..self }
            }
            None => self,
        }
    }
}

/// The lines the table of `p` corrects, at the frequencies it corrects them
/// (cycles per revolution).
pub fn table_lines(p: &Processed) -> Vec<f64> {
    p.decisions
        .lines
        .iter()
        .filter(|d| d.significant && matches!(d.action, LineAction::Kept | LineAction::Relocated))
        .map(|d| d.true_cycles_per_rev)
        .collect()
}

/// The highest line the positioner of `survey` plausibly has: its design's
/// highest line when it has a model, at least
/// [`aliases::PLAUSIBLE_MAX_CYCLES`].
pub fn plausible_max(survey: &SurveyRecord) -> f64 {
    let design_max = survey.model.as_ref().and_then(|m| {
        let c = design_candidates(&m.design, &AnalysisOptions::default());
        c.iter().map(|c| c.cycles_per_rev).reduce(f64::max)
    });
    aliases::plausible_max_cycles(design_max)
}

/// The plausible lines (up to `f_max` cycles/rev, [`plausible_max`]) a
/// verification at `verification` could not see the table of `p` (made at
/// `calibration`) miss. At the calibration's own targets (a polygon's
/// faces) it measures what the calibration did and sees every alias the
/// table may have taken for its line as the calibration saw it: blind to
/// all of them, with either reference (one rule: it confirms nothing there).
/// Targets may repeat (samples').
pub fn blind(calibration: &[f64], verification: &[f64], f_max: f64, p: &Processed) -> Vec<aliases::Blind> {
    let distinct = |t: &[f64]| {
        let mut d = t.to_vec();
        d.sort_by(f64::total_cmp);
        d.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        d
    };
    let (calibration, verification) = (distinct(calibration), distinct(verification));
    aliases::blind(&calibration, &verification, &table_lines(p), f_max)
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
    let calibration = native.plan().cloned().with_context(|| format!("survey {} has no stored plan", native.id))?;
    let verify_plan = &verify_plan.clone().seeing(&calibration, native, processed);
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
    survey_bench::say!(
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
    let measured = store.samples(id).await?;
    // The verification's own drift in time, as a calibration's (issue 49):
    // corrected when significant, and a drift no straight line takes leaves
    // it unable to confirm anything.
    let drift = survey_tables::timedrift::estimate(&measured);
    let corrected = match &drift {
        Some(d) if d.corrected => survey_tables::timedrift::corrected(&measured, d),
        _ => measured,
    };
    // The prediction for this verification: its own count of samples.
    let predicted = survey_tables::verification::predicted_for(&processed.processed.prediction, corrected.len());
    let mut out = figures(id, native.id, native_samples, &corrected, Some(predicted), table.is_directional(), units)?;
    let u = processed.uncertainty.table_u_deg;
    let blind = blind(&calibration.targets_deg, &plan.targets_deg, plausible_max(native), &processed.processed);
    let claim = Claim {
        predicted_deg: predicted,
        u_deg: u,
        native_deg: peak_deg(native_samples),
        not_a_result: processed.processed.prediction.not_a_result(),
        // The verification is made with the calibration's own reference.
        shared_reference_u_deg: processed.uncertainty.reference_systematic_u_deg().map(|u| u * processed.uncertainty.k),
    };
    let mut judged = judge(&claim, &corrected, &blind);
    // What no straight line takes is named with its size, not corrected:
    // the verdict stands on the readings corrected for the straight line.
    // Not a verdict of its own: the test is at 1 %, and on the simulated
    // bench, whose positioner does not drift, one verification in the
    // suite (4 passes of 120 targets, chi-square 19 over 6 degrees of
    // freedom) was called crooked by noise alone.
    if let Some(d) = drift.as_ref().filter(|d| d.left_significant) {
        judged.reason = format!(
            "{}; its readings also drift in time in a way no straight line takes (up to {:.2e} deg a pass, \
             chi-square {:.1} a degree of freedom), named and not corrected",
            judged.reason, d.left_deg, d.left_f
        );
    }
    out.doc["drift_in_time"] = serde_json::to_value(&drift).unwrap_or_default();
    if let Some(d) = &drift {
        // A verification's table is judged, not made: what is left is named.
        out.text += &d.text_saying("named, not corrected");
    }
    out.doc["targets"] = plan.targets_deg.len().into();
    out.doc["between_targets"] = verify_plan.between.into();
    out.doc["offset_deg"] = verify_plan.offset_deg.into();
    out.doc["second_spacing_targets"] = verify_plan.second.into();
    out.doc["resized"] = verify_plan.resized.into();
    out.doc["blind"] = serde_json::to_value(&blind).unwrap_or_default();
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
        Verdict::NotConfirmed if j.reason.starts_with("nothing to confirm") => {
            format!("verdict: not confirmed: {} (the survey and the table stay stored)", j.reason)
        }
        Verdict::NotConfirmed => format!(
            "verdict: NOT CONFIRMED: {}; do not use this table as a result (the survey and the table stay stored)",
            j.reason
        ),
    }
}

/// Where the verification measured, in words.
fn placement(v: &VerifyPlan) -> String {
    if v.between && v.second > 0 {
        format!(
            "at {} targets between the calibration targets (at least {:.4} deg from each): {} half a step from each, \
             and {} of a second spacing at a quarter of their own step, so that no plausible alias of the table's \
             lines hides between them",
            v.plan.targets_deg.len(),
            v.offset_deg,
            v.plan.targets_deg.len() - v.second,
            v.second
        )
    } else if v.between && v.resized {
        format!(
            "at {} targets between the calibration targets (at least {:.4} deg from each), half their own step from \
             0: the fewest above the calibration's own count that leave no plausible alias of the table's lines hidden between \
             them (half a step from every target would)",
            v.plan.targets_deg.len(),
            v.offset_deg
        )
    } else if v.between {
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
