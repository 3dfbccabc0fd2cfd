//! The environment of a survey (`run --json` and `show --json`'s
//! `"environment"`, the certificate): the air a tracker measured with every
//! sample, its ranges over the survey (`"source": "tracker"`); else the
//! temperature the configuration's `[certificate]` states (`"stated"`, an
//! autocollimator's bench); else nothing (`"none"`).

use serde_json::{Value, json};
use survey_store::Store;
use survey_store::environment::{Measured, Range};
use survey_store::survey::{Setup, SurveyRecord};

/// Where the environment comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Environment {
    /// Measured by the tracker with every sample.
    Tracker(Measured),
    /// The temperature the configuration states, degrees Celsius.
    Stated(f64),
    /// Neither.
    None,
}

impl Environment {
    /// The survey's environment.
    pub async fn of(store: &Store, survey: &SurveyRecord) -> anyhow::Result<Environment> {
        if let Some(m) = store.environment(survey.id).await? {
            return Ok(Environment::Tracker(m));
        }
        let stated = match &survey.setup {
            Setup::Configured(c) => c.config.certificate.as_ref().and_then(|c| c.temperature_c),
            _ => None,
        };
        Ok(stated.map_or(Environment::None, Environment::Stated))
    }

    /// The contract's `"environment"` object.
    pub fn json(&self) -> Value {
        let range = |r: &Range| json!({"min": r.min, "max": r.max, "mean": r.mean});
        match self {
            Environment::Tracker(m) => json!({
                "source": "tracker",
                "measurements": m.count,
                "temperature_c": range(&m.temperature_c),
                "pressure_hpa": range(&m.pressure_hpa),
                "humidity_pct": range(&m.humidity_pct),
            }),
            Environment::Stated(t) => json!({
                "source": "stated",
                "temperature_c": {"min": t, "max": t, "mean": t},
                "pressure_hpa": null,
                "humidity_pct": null,
            }),
            Environment::None => {
                json!({"source": "none", "temperature_c": null, "pressure_hpa": null, "humidity_pct": null})
            }
        }
    }
}
