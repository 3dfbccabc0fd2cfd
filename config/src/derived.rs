//! The durations a configuration's timing makes, checked where it is read.

use super::SurveyConfig;
use super::place::{Defect, Places};
use survey_plan::move_time;
use survey_processing::num::Num;

/// The longest duration the timing may make, in seconds (a day).
const MAX_DERIVED_S: f64 = 86_400.0;

/// Every duration the timing's rates make stays within a day, so that it
/// is a `Duration` at all (`velocity_deg_s = 1e-300` made a move last
/// 3.6e302 s, and converting it panicked), naming the key whose value
/// makes it too long: a move over the widest span the axis travels (its
/// travel, or a turn, and the overrun both ways) at `velocity_deg_s` and
/// `accel_deg_s2`, and a pass of a continuous scan at
/// `scan_velocity_deg_s` or `calibration_velocity_deg_s`. Every other
/// duration is a sum of these and of keys bounded by their range.
pub(super) fn check(cfg: &SurveyConfig, at: &Places) -> Result<(), Defect> {
    let timing = cfg.timing();
    let t = &cfg.timing;
    let overrun = cfg.survey.overrun_deg.unwrap_or(1.0);
    let span = cfg.survey.travel_deg.map_or(360.0, |[lo, hi]| hi - lo) + 2.0 * overrun;
    let (v, a) = (timing.velocity_deg_s, timing.accel_deg_s2);
    let day = |s: f64| s.is_finite() && s <= MAX_DERIVED_S;
    let too_long = |key: &str, value: f64, what: &str, seconds: f64| {
        let key = format!("timing.{key}");
        let written = at.written(&key).map_or_else(|| Num(value).to_string(), str::to_string);
        let text = format!(
            "{written} makes {what} take {} s, more than a day ({MAX_DERIVED_S} s): is the value in the right unit?",
            Num(seconds)
        );
        at.defect(&key, text)
    };
    let what = format!("a move of {} deg", Num(span));
    let move_s = move_time(span, v, a);
    if !day(move_s) {
        // The cruise at the velocity, or the ramps at the acceleration.
        return Err(if !day(span / v) {
            too_long("velocity_deg_s", v, &what, move_s)
        } else {
            too_long("accel_deg_s2", a, &what, move_s)
        });
    }
    for (key, velocity) in
        [("scan_velocity_deg_s", t.scan_velocity_deg_s), ("calibration_velocity_deg_s", t.calibration_velocity_deg_s)]
    {
        if let Some(velocity) = velocity {
            let pass_s = move_time(span, velocity, a);
            if !day(pass_s) {
                return Err(too_long(key, velocity, &format!("a scan pass of {} deg", Num(span)), pass_s));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const BENCH: &str = "[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n\
        [tracker]\ndriver = \"emscon\"\naddress = \"h:700\"\n";

    fn parsed(timing: &str) -> Result<SurveyConfig, String> {
        SurveyConfig::parse(&format!("{BENCH}[timing]\n{timing}\n"), "c.toml").map_err(|e| e.to_string())
    }

    #[test]
    fn a_rate_that_makes_a_duration_too_long_is_refused_naming_its_key() {
        for (timing, named) in [
            (
                "velocity_deg_s = 1e-300",
                "c.toml:8: timing.velocity_deg_s: 1e-300 makes a move of 362 deg take 3.62e302 s",
            ),
            ("accel_deg_s2 = 1e-300", "c.toml:8: timing.accel_deg_s2: 1e-300 makes a move of 362 deg take"),
            ("velocity_deg_s = 1e-12", "c.toml:8: timing.velocity_deg_s: 1e-12"),
            ("velocity_deg_s = 0.001", "c.toml:8: timing.velocity_deg_s: 0.001"),
            ("accel_deg_s2 = 1e-9", "c.toml:8: timing.accel_deg_s2: 1e-9"),
            (
                "scan_velocity_deg_s = 1e-300",
                "c.toml:8: timing.scan_velocity_deg_s: 1e-300 makes a scan pass of 362 deg",
            ),
            ("calibration_velocity_deg_s = 1e-300", "c.toml:8: timing.calibration_velocity_deg_s: 1e-300"),
        ] {
            let e = parsed(timing).unwrap_err();
            assert!(e.starts_with(named) && e.contains("more than a day"), "{timing}: {e}");
            assert!(e.len() < 300, "no number spelled out in full: {e}");
        }
        // The travel and the overrun set the span.
        let e = SurveyConfig::parse(
            &format!(
                "{BENCH}[survey]\ntravel_deg = [-10.0, 90.0]\noverrun_deg = 5.0\n[timing]\nvelocity_deg_s = 1e-6\n"
            ),
            "c.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("a move of 110 deg"), "{e}");
    }

    #[test]
    fn slow_but_real_axes_pass_and_their_durations_convert() {
        for timing in ["velocity_deg_s = 0.01\naccel_deg_s2 = 0.001", "scan_velocity_deg_s = 0.005", ""] {
            let cfg = parsed(timing).unwrap_or_else(|e| panic!("{timing}: {e}"));
            let t = cfg.timing();
            let s = move_time(362.0, t.velocity_deg_s, t.accel_deg_s2);
            assert!(std::time::Duration::try_from_secs_f64(s).is_ok() && s <= MAX_DERIVED_S, "{timing}: {s}");
        }
    }
}
