//! The whole processing of one survey, from samples to a table and its
//! predicted accuracy (what `survey process` and the end of `survey run` do):
//! the spectral analysis, the recipe's decisions (replayed or derived), the
//! table, the predicted native and corrected accuracy beside the
//! repeatability floor, the paper's Figure 6 interpolation comparison and the
//! controller files ([`survey_controllers::export`]). Pure: the caller reads the samples and writes the files.

use crate::correction::{CorrectionError, Prediction, corrected_errors, predict_accuracy_with_a};
use crate::left::{Left, LeftKind};
use crate::recipe::{
    AliasChoice, AliasChoiceAction, ApplyError, BuiltTable, ChoiceError, Decisions, ExportChoices, Recipe, RecipeError,
};
use crate::resolve::{Resolution, decide as resolve, measured_left_deg as measured_left_deg_of};
use std::borrow::Cow;
use survey_controllers::export::ControllerExport;
use survey_processing::Sample;
use survey_processing::analysis::{Analysis, AnalysisError, analyse_grouped};
use survey_processing::errormap::Coverage;
use survey_processing::iso230::{Iso230, TargetGroups, iso230_2_figures_and_a_with_actual};
use survey_processing::model::Design;
use survey_processing::resample::{MethodScore, compare_interpolation};

/// Why a survey cannot be processed. Every variant is about the data or the
/// recipe given, never about the machine.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PipelineError {
    /// There is nothing to process.
    #[error("there are no samples to process")]
    NoSamples,
    /// The samples cannot be analysed (an incomplete error map, say).
    #[error("the samples cannot be analysed")]
    Analysis(#[from] AnalysisError),
    /// The recipe cannot be applied to these samples; the text names the
    /// recipe file and line when it was replayed from one.
    #[error("{0}")]
    Recipe(String),
    /// The accuracy cannot be predicted from these samples.
    #[error("predicting the corrected accuracy")]
    Prediction(#[from] CorrectionError),
    /// The export choices given apart from a recipe file (on the command
    /// line) cannot be honoured; the key names the `[export]` choice.
    #[error("{0}")]
    Export(ChoiceError),
}

/// A recipe replayed from a file: the recipe, its text and its name (for
/// errors that point at a line of the file).
#[derive(Debug, Clone, Copy)]
pub struct Replay<'a> {
    /// The parsed recipe.
    pub recipe: &'a Recipe,
    /// The file's text.
    pub text: &'a str,
    /// The file's name, as errors show it.
    pub name: &'a str,
}

/// The repeatability floor no correction can beat.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Floor {
    /// Degrees, when the survey allows ISO 230-2 statistics (two runs or more).
    pub deg: Option<f64>,
    /// What it is, in words.
    pub what: String,
}

/// Everything the processing of one survey produced.
#[derive(Debug)]
pub struct Processed {
    /// The spectral analysis.
    pub analysis: Analysis,
    /// The recipe used (replayed, or derived from this survey).
    pub recipe: Recipe,
    /// Whether the recipe was replayed from a file.
    pub replayed: bool,
    /// What the recipe decided on this survey.
    pub decisions: Decisions,
    /// The table.
    pub built: BuiltTable,
    /// What the table leaves uncorrected that the survey saw (nulled lines,
    /// lines that may be aliases).
    pub left: Left,
    /// What check points between the targets decided about the lines in
    /// doubt ([`crate::resolve`]; empty without check points).
    pub resolutions: Vec<Resolution>,
    /// What the check points measure the table leaves between the targets
    /// (its coverage interval, [`crate::resolve::measured_left_deg`]),
    /// when no hypothesis explains them: the table's `U` is at least this.
    pub measured_left_deg: Option<f64>,
    /// What check points fitted with the survey's folds leave unexplained
    /// beyond their noise, an rms in degrees ([`crate::resolve::Folds::unexplained_deg`]):
    /// a term of `U`.
    pub unexplained_deg: Option<f64>,
    /// Native and corrected accuracy, predicted on the survey's samples,
    /// with what the table leaves between the targets.
    pub prediction: Prediction,
    /// The repeatability floor.
    pub floor: Floor,
    /// ISO 230-2 figures of the survey, when it allows them (the figures
    /// only: `targets` is empty, [`survey_processing::iso230::iso230_2`] has them).
    pub iso: Option<Iso230>,
    /// The paper's Figure 6 comparison (or why it could not be made).
    pub interpolation: Result<Vec<MethodScore>, String>,
    /// The controller files the recipe asks for (`[export]`), with their predicted accuracy.
    pub controllers: Vec<ControllerExport>,
    /// Remarks for the operator.
    pub notes: Vec<String>,
}

/// A survey whose targets include both 0 and 360 (the same angle twice)
/// loses the samples at the last one, so that it is one uniform revolution.
fn close_circle(samples: &[Sample]) -> (Cow<'_, [Sample]>, Option<String>) {
    let lo = samples.iter().map(|s| s.target_deg).fold(f64::INFINITY, f64::min);
    let hi = samples.iter().map(|s| s.target_deg).fold(f64::NEG_INFINITY, f64::max);
    if ((hi - lo) - 360.0).abs() < 1e-6 {
        let kept: Vec<Sample> = samples.iter().filter(|s| (s.target_deg - hi).abs() > 1e-6).copied().collect();
        let note = format!(
            "targets {lo} and {hi} deg are the same angle: the samples at {hi} deg are left out of the processing"
        );
        (Cow::Owned(kept), Some(note))
    } else {
        (Cow::Borrowed(samples), None)
    }
}

fn recipe_error(e: ApplyError, replay: Option<Replay<'_>>) -> PipelineError {
    PipelineError::Recipe(match (e, replay) {
        (ApplyError::Choice(c), Some(r)) => RecipeError::of_choice(c, r.text, r.name).to_string(),
        (ApplyError::Choice(c), None) => format!("the derived recipe: {c}"),
        (other, _) => other.to_string(),
    })
}

/// Process `samples` with `design` and, when given, a replayed recipe;
/// derive a recipe from the samples otherwise.
pub fn process(samples: &[Sample], design: &Design, replay: Option<Replay<'_>>) -> Result<Processed, PipelineError> {
    process_with(samples, design, replay, None)
}

/// [`process`], the recipe's `[export]` replaced by `export` when given (the
/// command line's choices; a choice it cannot honour is [`PipelineError::Export`]).
pub fn process_with(
    samples: &[Sample],
    design: &Design,
    replay: Option<Replay<'_>>,
    export: Option<&ExportChoices>,
) -> Result<Processed, PipelineError> {
    process_with_checks(samples, design, replay, export, &[])
}

/// [`process_with`] with `checks`, samples measured between the targets to
/// decide the lines in doubt ([`crate::resolve`]): a line
/// decided above the sampling's resolution is relocated there (the recipe
/// written says so, so a recalibration replays it), one decided where it is
/// seen is no longer in doubt; what is not decided stays in `left`.
pub fn process_with_checks(
    samples: &[Sample],
    design: &Design,
    replay: Option<Replay<'_>>,
    export: Option<&ExportChoices>,
    checks: &[Sample],
) -> Result<Processed, PipelineError> {
    if samples.is_empty() {
        return Err(PipelineError::NoSamples);
    }
    let mut notes = Vec::new();
    let (samples, note) = close_circle(samples);
    notes.extend(note);
    let base = replay.map(|r| r.recipe.clone()).unwrap_or_default();
    // One grouping by target for the error map, the survey's statistics and
    // its corrected errors'.
    let groups = TargetGroups::of(&samples);
    let analysis = analyse_grouped(&samples, &groups, design, &base.analysis)?;
    let mut recipe = match replay {
        Some(r) => r.recipe.clone(),
        None => Recipe::from_analysis(&analysis, &base),
    };
    if let Some(export) = export {
        recipe.export = export.clone();
    }
    let mut decisions = recipe.decide(&analysis).map_err(|e| recipe_error(e.into(), replay))?;
    let mut built = recipe.build_table(&analysis, &decisions).map_err(|e| recipe_error(e, replay))?;
    let unknown_design = design.gear_ratios.is_empty() && design.tooth_counts.is_empty();
    // Lines the design does not name that fold onto the bins the table
    // holds at this count ([`crate::left::folds`]): in doubt until check points
    // measure them.
    let folds = crate::left::folds::of(&analysis, design, &recipe.analysis, &decisions);
    let mut left = Left::of(&analysis, &decisions, &[], unknown_design).with_folds(folds, &analysis);
    let mut resolutions = Vec::new();
    let mut measured_left = None;
    let mut unexplained = None;
    let in_doubt = !left.is_empty() || !left.folds.is_empty();
    if !checks.is_empty() && in_doubt {
        resolutions = resolve(&left, &built.table, checks);
        let (resolved, stays) = resolved_recipe(&recipe, &left, &resolutions);
        if resolved != recipe {
            recipe = resolved;
            decisions = recipe.decide(&analysis).map_err(|e| recipe_error(e.into(), replay))?;
            built = recipe.build_table(&analysis, &decisions).map_err(|e| recipe_error(e, replay))?;
        }
        let folds = crate::left::folds::of(&analysis, design, &recipe.analysis, &decisions);
        left = Left::of(&analysis, &decisions, &stays, unknown_design).with_folds(folds, &analysis).with_rest(
            &left,
            &resolutions,
            &analysis.error_map.targets_deg,
        );
        notes.extend(resolutions.iter().map(|r| r.why.clone()));
        // The folds measured by the same check points, with the table made
        // from what they decided.
        let folds = crate::resolve::measure_folds(left, &built.table, checks);
        left = folds.left;
        unexplained = folds.unexplained_deg;
        notes.extend(folds.resolutions.iter().map(|r| r.why.clone()));
        resolutions.extend(folds.resolutions);
        // A line on the Nyquist bin: the check points measure the quadrature
        // component the targets do not see (as they measure what no
        // hypothesis explains).
        let nyquist = resolutions.iter().any(|r| 2.0 * r.observed_cycles == left.points as f64);
        if nyquist {
            left = crate::resolve::measure_nyquist(left, &built.table, checks, &analysis.error_map.targets_deg);
        }
        if nyquist || resolutions.iter().any(|r| !r.explained) {
            measured_left = measured_left_deg_of(&built.table, checks);
        }
    }
    notes.extend(left.unseen_folds());
    notes.extend(decisions.notes.iter().cloned());
    notes.extend(built.notes.iter().cloned());
    // The survey's figures and its corrected samples' `A` (actual angles:
    // target - corrected error) from one walk of the groups.
    let corrected = corrected_errors(&samples, &built.table);
    let (iso, corrected_a) =
        iso230_2_figures_and_a_with_actual(&samples, &groups, |i| samples[i].target_deg - corrected[i]);
    let iso = iso.ok();
    let floor = match &iso {
        Some(s) if built.directional => Floor {
            deg: Some(s.r_up.unwrap_or(s.r).max(s.r_down.unwrap_or(0.0)) / 2.0),
            what: "half the larger unidirectional ISO 230-2 repeatability (a directional table removes the reversal)"
                .into(),
        },
        Some(s) => Floor {
            deg: Some(s.r / 2.0),
            what: "half the ISO 230-2 repeatability R (with the reversal a one-column table leaves)".into(),
        },
        None => Floor { deg: None, what: "one run: no repeatability figure".into() },
    };
    let mut prediction = predict_accuracy_with_a(
        &samples,
        &corrected,
        floor.deg.unwrap_or(0.0),
        iso.as_ref().map(|s| s.a),
        corrected_a.ok(),
    )?
    .with_left(&left, &samples, &corrected, &groups);
    drop((groups, corrected));
    // Check points that no hypothesis explains measured the corrected axis
    // between the targets: the prediction does not promise better.
    if let Some((_, peak)) = measured_left {
        prediction.corrected_peak_deg = prediction.corrected_peak_deg.max(peak);
    }
    notes.extend(left.lines.iter().map(|l| l.why.clone()));
    if prediction.no_better_than_native() {
        notes.push(format!(
            "this table is not expected to improve the axis: corrected peak +/-{:.5} deg predicted (with what it leaves \
             between the targets) against +/-{:.5} deg native; it is not a result to load",
            prediction.corrected_peak_deg, prediction.native_peak_deg
        ));
    }
    let single = match analysis.error_map.coverage {
        Coverage::FullCircle { .. } => analysis
            .error_map
            .bidirectional_mean_deg
            .as_ref()
            .or(analysis.error_map.forward.as_ref().map(|d| &d.mean_deg))
            .or(analysis.error_map.reverse.as_ref().map(|d| &d.mean_deg)),
        Coverage::Partial { .. } => None,
    };
    let interpolation = match single {
        Some(map) => compare_interpolation(map).map_err(|e| e.to_string()),
        None => Err("a partial range has no periodic map to resample".to_string()),
    };
    let (full_circle, measured) = match analysis.error_map.coverage {
        Coverage::FullCircle { .. } => (true, (0.0, 360.0)),
        Coverage::Partial { start, end, .. } => (false, (start, end)),
    };
    let controllers = survey_controllers::export::build(&built.table, full_circle, measured, &samples, &recipe.export)
        .map_err(|e| if export.is_some() { PipelineError::Export(e) } else { recipe_error(e.into(), replay) })?;
    Ok(Processed {
        analysis,
        recipe,
        replayed: replay.is_some(),
        decisions,
        built,
        left,
        resolutions,
        measured_left_deg: measured_left.map(|m| m.0),
        unexplained_deg: unexplained,
        prediction,
        floor,
        iso,
        interpolation,
        controllers,
        notes,
    })
}

/// `recipe` with what `resolutions` decided about the lines of `left`: a
/// line decided above the sampling's resolution relocated there (its bin's
/// other candidates no longer named), and the bins decided where they are
/// seen (no longer in doubt).
fn resolved_recipe(recipe: &Recipe, left: &Left, resolutions: &[Resolution]) -> (Recipe, Vec<f64>) {
    let mut out = recipe.clone();
    let mut stays = Vec::new();
    let n = left.points as f64;
    for r in resolutions {
        let (Some(f), Some(line)) =
            (r.decided_cycles, left.lines.iter().find(|l| l.observed_cycles == r.observed_cycles))
        else {
            continue;
        };
        let bin = r.observed_cycles;
        match r.kind {
            // Never in doubt: a possible line is what check points left.
            LeftKind::Possible | LeftKind::MayFold | LeftKind::Folded => {}
            LeftKind::MaybeAlias if f == bin => stays.push(bin),
            LeftKind::MaybeAlias => {
                out.lines.keep.retain(|k| *k != bin);
                out.lines.keep.push(f);
            }
            // Above the resolution: relocated there, in place of whatever the
            // bin's candidates were named.
            LeftKind::NotCarried if 2.0 * f > n => {
                out.aliases.retain(|a| !line.candidates.contains(&(a.true_cycles as f64)));
                out.lines.keep.retain(|k| !line.candidates.contains(k));
                out.lines.remove.retain(|k| !line.candidates.contains(k));
                out.aliases.push(AliasChoice {
                    true_cycles: f as usize,
                    action: AliasChoiceAction::Relocate,
                    observed_cycles: Some(bin as usize),
                    source: Some("decided by check points measured between the targets".into()),
                });
            }
            // Decided at a frequency the survey resolves: kept at its bin,
            // the aliased candidates that share it named absent.
            LeftKind::NotCarried => {
                out.aliases.retain(|a| !line.candidates.contains(&(a.true_cycles as f64)));
                out.lines.remove.retain(|k| !line.candidates.contains(k));
                if !out.lines.keep.contains(&f) {
                    out.lines.keep.push(f);
                }
                for &c in line.candidates.iter().filter(|&&c| c != f && 2.0 * c > n) {
                    out.aliases.push(AliasChoice {
                        true_cycles: c as usize,
                        action: AliasChoiceAction::Absent,
                        observed_cycles: Some(bin as usize),
                        source: Some("not there: check points measured between the targets".into()),
                    });
                }
            }
        }
    }
    (out, stays)
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_processing::Direction;

    fn samples(points: usize, with_360: bool) -> Vec<Sample> {
        let mut out = Vec::new();
        let count = if with_360 { points + 1 } else { points };
        for run in 1..=2 {
            for j in 0..count {
                let t = 360.0 * j as f64 / points as f64;
                let e = 0.01 * (20.0 * t).to_radians().sin() + 0.0001 * ((run as usize * 7 + j) % 5) as f64;
                out.push(Sample {
                    run,
                    direction: Direction::Forward,
                    target_deg: t,
                    readout_deg: t,
                    actual_deg: t - e,
                    timestamp_s: None,
                });
            }
        }
        out
    }

    #[test]
    fn a_closed_circle_is_opened_and_processed() {
        let p = process(&samples(90, true), &Design { gear_ratios: vec![20.0], ..Design::default() }, None).unwrap();
        assert!(p.notes.iter().any(|n| n.contains("same angle")), "{:?}", p.notes);
        assert_eq!(p.analysis.error_map.coverage, Coverage::FullCircle { n: 90 });
        assert!(p.decisions.kept_cycles.contains(&20.0));
        assert!(p.prediction.corrected_peak_deg < p.prediction.native_peak_deg / 10.0, "{:?}", p.prediction);
        let linuxcnc = &p.controllers[0];
        assert_eq!(linuxcnc.controller, survey_controllers::export::Controller::LinuxCnc);
        assert_eq!((linuxcnc.grid.points, linuxcnc.grid.start_deg, linuxcnc.grid.end_deg()), (256, 0.0, 360.0));
        assert!(linuxcnc.corrected_peak_deg.unwrap() < p.prediction.native_peak_deg / 10.0);
        let names: Vec<&str> = p.controllers.iter().map(|c| c.controller.as_str()).collect();
        assert_eq!(names, ["linuxcnc", "840d", "fanuc"]);
        assert_eq!(process(&[], &Design::default(), None).unwrap_err(), PipelineError::NoSamples);
    }
}
