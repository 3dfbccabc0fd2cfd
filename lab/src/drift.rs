//! Drift control's side of a stored survey: whether the survey asked for its
//! samples to be corrected, and the samples the statistics and processing
//! use ([`survey_plan::drift`] holds the drift and the correction).

use survey_plan::drift::DriftPoint;
use survey_processing::Sample;
use survey_store::survey::{Setup, SurveyRecord};

/// Whether `survey` asked for its samples to be corrected for the drift.
pub fn correction_asked(survey: &SurveyRecord) -> bool {
    match &survey.setup {
        Setup::Configured(c) => c.config.drift_control.as_ref().is_some_and(|d| d.correct),
        _ => false,
    }
}

/// The samples the statistics and the processing of `survey` use: as
/// measured (borrowed), or corrected for the drift when the survey asked for it.
pub fn for_analysis<'a>(
    survey: &SurveyRecord,
    samples: &'a [Sample],
    points: &[DriftPoint],
) -> std::borrow::Cow<'a, [Sample]> {
    survey_plan::drift::for_analysis(correction_asked(survey), samples, points)
}

/// The JSON of the drift points (`[{"at_s", "drift_deg", "before_seq"}]`)
/// and whether the samples were corrected for them.
pub fn json(survey: &SurveyRecord, points: &[DriftPoint]) -> serde_json::Value {
    serde_json::json!({ "points": points, "corrected": correction_asked(survey) && !points.is_empty() })
}
