//! The room the simulated tracker's weather station reports: our own model
//! of a temperature-controlled laboratory, not measured data. Over a
//! survey's hours the air warms and cools slowly (a daily swing of ±0.3 °C
//! about 20 °C) with the air conditioning's short cycle on it (±0.05 °C
//! every 15 minutes); the pressure follows the weather (±1.5 hPa over a
//! day about 1013.25 hPa) and the relative humidity moves against the
//! temperature (45 %RH, −3 %RH per °C). Every value is a function of the
//! instrument clock's time only, so a survey repeats exactly.

use std::f64::consts::TAU;
use survey_drivers::AirEnvironment;

/// One day, seconds.
const DAY_S: f64 = 86_400.0;
/// The air conditioning's cycle, seconds.
const CYCLE_S: f64 = 900.0;

/// The air at `t_s` seconds of the instrument clock.
pub fn air_at(t_s: f64) -> AirEnvironment {
    let day = TAU * t_s / DAY_S;
    let temperature_c = 20.0 + 0.3 * (day - 1.0).sin() + 0.05 * (TAU * t_s / CYCLE_S).sin();
    AirEnvironment {
        temperature_c,
        pressure_hpa: 1013.25 + 1.5 * (day + 0.7).sin(),
        humidity_pct: 45.0 - 3.0 * (temperature_c - 20.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_room_changes_slowly_within_a_laboratorys_limits() {
        let hours: Vec<AirEnvironment> = (0..=48).map(|h| air_at(f64::from(h) * 1800.0)).collect();
        for a in &hours {
            assert!((19.6..=20.4).contains(&a.temperature_c), "{a:?}");
            assert!((1011.0..=1015.5).contains(&a.pressure_hpa) && (43.0..=47.0).contains(&a.humidity_pct), "{a:?}");
        }
        // Over 8 hours it changes, by tenths of a degree, never by a jump.
        let span =
            hours[..17].iter().map(|a| a.temperature_c).fold((f64::MAX, f64::MIN), |(l, h), t| (l.min(t), h.max(t)));
        assert!(span.1 - span.0 > 0.1 && span.1 - span.0 < 0.7, "{span:?}");
        for w in hours.windows(2) {
            assert!((w[1].temperature_c - w[0].temperature_c).abs() < 0.15, "{w:?}");
        }
        assert_eq!(air_at(3600.0), air_at(3600.0), "a function of time alone");
    }
}
