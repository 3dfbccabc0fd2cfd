//! What the instruments say they are: read through each driver before a
//! survey is stored (a SCPI controller's `*IDN?`, a CiA 402 drive's device
//! name 0x1008, a Modbus device's Read Device Identification, an emScon
//! tracker's serial number and version; an ELCOMAT has no such request),
//! kept with the survey (`instruments.identified`: `{"positioner": text or
//! null, "reference": text or null}`) and stated on its certificate beside
//! what the configuration states. Best effort: an instrument that does not
//! answer now is logged and recorded as not identified; the survey's own
//! calls survive it or not as they do every fault.
//!
//! `survey sim`'s simulators say "(simulated)" in what they identify
//! themselves as (our own design: a real instrument does not): a survey of
//! them is a rehearsal even on a configuration written by hand
//! ([`survey_store::survey::SurveyRecord::rehearsal`]).

use serde_json::{Value, json};
use survey_acquire::{Engine, Reference};
use survey_bench::instruments::printable;
use survey_drivers::clock::with_timeout;

/// What the engine's instruments say they are, as stored with a survey.
pub async fn read(engine: &mut Engine) -> Value {
    let clock = engine.clock().clone();
    let timeout = engine.timing().call_timeout;
    let name = engine.positioner_name().to_string();
    let positioner = with_timeout(&*clock, timeout, &name, "identification", engine.positioner_mut().identification())
        .await
        .map_err(|e| (name, e));
    let name = engine.reference_name().to_string();
    let reference = match engine.reference_mut() {
        Reference::Tracker(t) => with_timeout(&*clock, timeout, &name, "identification", t.identification()).await,
        Reference::Autocollimator { instrument, .. } => {
            with_timeout(&*clock, timeout, &name, "identification", instrument.identification()).await
        }
    }
    .map_err(|e| (name, e));
    json!({"positioner": said(positioner), "reference": said(reference)})
}

/// An identification as kept ([`survey_bench::instruments::printable`]).
fn said(read: Result<Option<String>, (String, survey_drivers::DriverError)>) -> Value {
    match read {
        Ok(text) => text.as_deref().and_then(printable).map_or(Value::Null, Value::from),
        Err((name, e)) => {
            tracing::warn!(instrument = %name, error = %e, "the instrument's identification could not be read");
            Value::Null
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_bench::instruments::MAX_IDENTIFICATION_CHARS as MAX_CHARS;

    #[test]
    fn an_identification_is_kept_printable_and_bounded() {
        assert_eq!(said(Ok(Some("ACME,AZ-200,1042,2.1\r\n".into()))), json!("ACME,AZ-200,1042,2.1"));
        assert_eq!(said(Ok(Some("a\u{7}b".into()))), json!("a b"));
        assert_eq!(said(Ok(Some("x".repeat(500)))).as_str().map(str::len), Some(MAX_CHARS));
        assert_eq!(said(Ok(Some(" \n".into()))), Value::Null);
        assert_eq!(said(Ok(None)), Value::Null);
        let e = survey_drivers::DriverError::usage("p", "no");
        assert_eq!(said(Err(("p".into(), e))), Value::Null);
    }
}
