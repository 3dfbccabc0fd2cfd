//! The correction in force at the positioner (`../shared/contract.md`, "The
//! correction in force"): a calibration measures the native axis, so before
//! one `survey run` reads whether the controller applies a correction table
//! (the driver's `correction_state`: the Modbus status bit, a CiA 402 drive's
//! 0x2101 with the correction objects, an MI-4190's `CORR:STAT?` with the
//! unverified commands). With the correction on it refuses (exit 2, naming
//! it) unless `--correction off` (switched off through the driver first, and
//! recorded) or `--correction keep` (the corrected axis measured on purpose:
//! the survey is marked so, and its table is no calibration). Where the
//! state cannot be read the survey says so, and a calibration whose error is
//! far below the asset's last calibration says the axis may be corrected.
//!
//! The state is stored with the survey (its `instruments` description's
//! `correction`: `off`, `unknown`, `switched off`, `kept on`).

use crate::error::bad_input;
use survey_acquire::{Engine, Timing};
use survey_drivers::clock::with_timeout;

/// What `--correction` asks when the positioner applies a correction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Choice {
    /// Refuse the calibration (the default).
    #[default]
    Refuse,
    /// Switch the correction off first, and record that.
    Off,
    /// Measure the corrected axis on purpose: no calibration.
    Keep,
}

/// The correction at the positioner when the survey started, as read and as handled.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Before {
    /// Read: off.
    Off,
    /// The driver cannot read it; why, for people.
    Unknown(String),
    /// Read on, and switched off through the driver (`--correction off`).
    SwitchedOff,
    /// Read on, and kept on (`--correction keep`).
    KeptOn,
    /// Read on (a check measures what it finds, and leaves it so).
    On,
}

impl Before {
    /// The value stored with the survey (`instruments.correction`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Before::Off => "off",
            Before::Unknown(_) => "unknown",
            Before::SwitchedOff => "switched off",
            Before::KeptOn => "kept on",
            Before::On => "on",
        }
    }

    /// One line for the summary.
    pub fn text(&self) -> String {
        match self {
            Before::Off => "correction at the positioner: off (read through the driver)".into(),
            Before::Unknown(why) => format!("correction at the positioner: unknown ({why}): make sure it is off"),
            Before::SwitchedOff => {
                "correction at the positioner: was on, switched off through the driver before the survey \
                 (--correction off)"
                    .into()
            }
            Before::KeptOn => "correction at the positioner: on, kept (--correction keep): this survey measured the \
                               corrected axis, and its table is no calibration"
                .into(),
            Before::On => "correction at the positioner: on (read through the driver)".into(),
        }
    }
}

impl Before {
    /// The state as stored with a survey (`instruments.correction`).
    pub fn from_stored(stored: &str) -> Option<Before> {
        Some(match stored {
            "off" => Before::Off,
            "unknown" => Before::Unknown("its driver cannot report whether it applies a correction".into()),
            "switched off" => Before::SwitchedOff,
            "kept on" => Before::KeptOn,
            "on" => Before::On,
            _ => return None,
        })
    }
}

/// What a calibration of `survey` (just measured, ISO 230-2 `a_deg`) says
/// when the correction could not be read and its error is far below the
/// asset's last calibration before it ([`far_below`]).
pub async fn maybe_corrected(
    store: &survey_store::Store,
    survey: &survey_store::survey::SurveyRecord,
    a_deg: f64,
) -> anyhow::Result<Option<String>> {
    if !survey.is_calibration() || survey.asset == survey_store::asset::UNASSIGNED {
        return Ok(None);
    }
    let earlier = store.surveys_of_asset(&survey.asset).await?;
    let Some(last) = earlier.iter().rev().find(|r| r.id < survey.id && r.is_complete() && r.is_calibration()) else {
        return Ok(None);
    };
    let loaded = crate::load::load(store, Some(last.id.into()), crate::load::Axis::Refitted).await?;
    let Ok(iso) = survey_processing::iso230::iso230_2(&loaded.analysed()) else { return Ok(None) };
    Ok(far_below(a_deg, iso.a, last.id))
}

/// The state the controller reports (`None`: the driver cannot read it).
pub async fn read(engine: &mut Engine) -> anyhow::Result<Option<bool>> {
    let clock = engine.clock().clone();
    let name = engine.positioner_name().to_string();
    let timeout = Timing::default().call_timeout;
    let p = engine.positioner_mut();
    Ok(with_timeout(&*clock, timeout, &name, "read the correction state", p.correction_state()).await?)
}

/// Switch the correction at the positioner on or off, and read it back.
pub async fn switch(engine: &mut Engine, on: bool) -> anyhow::Result<()> {
    let clock = engine.clock().clone();
    let name = engine.positioner_name().to_string();
    let timeout = Timing::default().call_timeout;
    let what = if on { "switch the correction on" } else { "switch the correction off" };
    with_timeout(&*clock, timeout, &name, what, engine.positioner_mut().enable_correction(on)).await?;
    match read(engine).await? {
        Some(now) if now != on => Err(anyhow::anyhow!(
            "{name}: asked to {what}, the controller still reports it {}",
            if now { "on" } else { "off" }
        )),
        _ => Ok(()),
    }
}

/// Before a calibration on `engine`: read the correction, and refuse,
/// switch it off or keep it as `choice` says (see the module documentation).
/// A refusal is bad input and comes before anything is stored.
pub async fn before_calibration(engine: &mut Engine, choice: Choice) -> anyhow::Result<Before> {
    let name = engine.positioner_name().to_string();
    // An instrument that does not answer now is the acquisition's to survive
    // (or to leave interrupted, resumable): the state is then unknown.
    let state = match read(engine).await {
        Ok(state) => state,
        Err(e) => {
            tracing::warn!(instrument = %name, error = %format!("{e:#}"), "the correction state could not be read");
            return Ok(Before::Unknown(format!("it could not be read: {e:#}")));
        }
    };
    match (state, choice) {
        (None, _) => Ok(Before::Unknown(format!("{name} cannot report whether it applies a correction"))),
        (Some(false), _) => Ok(Before::Off),
        (Some(true), Choice::Refuse) => Err(bad_input(format!(
            "the positioner ({name}) applies a correction table: a calibration measures the native axis. \
             --correction off switches it off first (and records that); --correction keep measures the corrected \
             axis on purpose (the survey is then no calibration)"
        ))),
        (Some(true), Choice::Off) => {
            switch(engine, false).await?;
            Ok(Before::SwitchedOff)
        }
        (Some(true), Choice::Keep) => Ok(Before::KeptOn),
    }
}

/// Whether a calibration's accuracy `a_deg` (ISO 230-2 `A`) is far below
/// the asset's last calibration's `last_a_deg`: below a third of it, which a
/// positioner does not gain by itself (wear goes the other way) and a table
/// in force gives at once. The words to say, when it is.
pub fn far_below(a_deg: f64, last_a_deg: f64, last_id: i64) -> Option<String> {
    (a_deg.is_finite() && last_a_deg.is_finite() && a_deg < last_a_deg / 3.0).then(|| {
        format!(
            "the axis may be corrected: A = {a_deg:.3e} deg is far below the asset's last calibration (survey \
             {last_id}: A = {last_a_deg:.3e} deg), and whether the positioner applies a correction could not be read: \
             check that it is off before loading this table"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_below_is_below_a_third() {
        assert!(far_below(0.01, 0.035, 3).unwrap().contains("survey 3: A = 3.500e-2"));
        assert_eq!(far_below(0.02, 0.035, 3), None);
        assert_eq!(far_below(f64::NAN, 0.035, 3), None);
    }

    #[test]
    fn every_state_is_stored_and_said() {
        let all = [Before::Off, Before::Unknown("x".into()), Before::SwitchedOff, Before::KeptOn, Before::On];
        let names: Vec<&str> = all.iter().map(Before::as_str).collect();
        assert_eq!(names, ["off", "unknown", "switched off", "kept on", "on"]);
        assert!(all.iter().all(|b| b.text().starts_with("correction at the positioner: ")));
    }
}
