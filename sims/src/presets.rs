//! The three positioners of the paper, as model files (`sims/presets/*.toml`,
//! embedded in the binary) with their travel and motion settings.
//!
//! | name | what | native peak |
//! |---|---|---|
//! | `fig1` | elevation axis, synchro feedback through a 6:1 gear and a 36:1 dual-speed synchro, travel -10..90 deg (Figures 1-2) | about ±0.04 deg |
//! | `fig4` | azimuth, two encoders on 12:1 pinions off a 216-tooth ring gear (Figures 4-5) | about ±0.016 deg |
//! | `fig8` | azimuth with an integral encoder behind a 20:1 gear pass (Figures 8-9), the default | about ±0.015 deg |
//!
//! The native peak is [`peak_error_deg`]: the largest `|systematic error|` over
//! the travel in either direction, noise excluded.

use crate::positioner::PositionerConfig;
use std::time::Duration;
use survey_processing::Direction;
use survey_processing::model::{Effect, Model};

const FIG1: &str = include_str!("../presets/fig1.toml");
const FIG4: &str = include_str!("../presets/fig4.toml");
const FIG8: &str = include_str!("../presets/fig8.toml");

/// The names of the presets, in order.
pub const NAMES: [&str; 3] = ["fig1", "fig4", "fig8"];

/// A simulated positioner of the paper: its model and motion settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Preset {
    /// Short name (`fig1`, `fig4`, `fig8`).
    pub name: &'static str,
    /// One line on what it models.
    pub description: &'static str,
    /// The error model (the embedded model file).
    pub model: Model,
    /// The model file's text, as embedded (with its comments).
    pub model_toml: &'static str,
    /// Travel limits, readout degrees; `None` = continuous rotation.
    pub travel: Option<(f64, f64)>,
    /// Velocity, degrees per second.
    pub velocity_deg_s: f64,
    /// Acceleration, degrees per second squared.
    pub accel_deg_s2: f64,
    /// Settle time after a move.
    pub settle: Duration,
}

impl Preset {
    /// The preset called `name` (case-insensitive), if there is one.
    pub fn by_name(name: &str) -> Option<Preset> {
        let name = name.trim().to_ascii_lowercase();
        let (name, description, text, travel, velocity) = match name.as_str() {
            "fig1" => (
                "fig1",
                "elevation axis, synchro feedback via a 6:1 gear and a 36:1 dual-speed synchro (paper Figures 1-2), about ±0.04 deg",
                FIG1,
                Some((-10.0, 90.0)),
                5.0,
            ),
            "fig4" => (
                "fig4",
                "azimuth, dual encoders on 12:1 pinions off a 216-tooth ring gear (paper Figures 4-5)",
                FIG4,
                None,
                10.0,
            ),
            "fig8" => (
                "fig8",
                "azimuth with an integral encoder behind a 20:1 gear pass (paper Figures 8-9), about ±0.015 deg",
                FIG8,
                None,
                10.0,
            ),
            _ => return None,
        };
        let model = Model::parse(text, &format!("presets/{name}.toml"))
            .unwrap_or_else(|e| panic!("embedded preset {name} does not parse: {e}"));
        Some(Preset {
            name,
            description,
            model,
            model_toml: text,
            travel,
            velocity_deg_s: velocity,
            accel_deg_s2: 20.0,
            settle: Duration::from_millis(300),
        })
    }

    /// All presets, in the order of [`NAMES`].
    pub fn all() -> Vec<Preset> {
        NAMES.iter().filter_map(|n| Preset::by_name(n)).collect()
    }

    /// A positioner configuration for this preset (no drift period, no faults).
    pub fn positioner_config(&self, seed: u64) -> PositionerConfig {
        PositionerConfig {
            velocity_deg_s: self.velocity_deg_s,
            accel_deg_s2: self.accel_deg_s2,
            settle: self.settle,
            travel: self.travel,
            seed,
            ..PositionerConfig::new(self.model.clone())
        }
    }

    /// The native peak readout error over the travel (see [`peak_error_deg`]).
    pub fn native_peak_deg(&self) -> f64 {
        peak_error_deg(&self.model, self.travel)
    }

    /// The travel as a range, `0..360` for a continuous-rotation axis.
    pub fn travel_or_full(&self) -> (f64, f64) {
        self.travel.unwrap_or((0.0, 360.0))
    }
}

impl Default for Preset {
    /// The `fig8` preset.
    fn default() -> Self {
        Preset::by_name("fig8").expect("fig8 is embedded")
    }
}

/// The largest `|systematic error|` (periodic effects plus backlash, no drift,
/// no noise) over `travel` (or a full revolution), in either direction,
/// evaluated every 0.005 degrees.
pub fn peak_error_deg(model: &Model, travel: Option<(f64, f64)>) -> f64 {
    let (lo, hi) = travel.unwrap_or((0.0, 360.0));
    let n = (((hi - lo) / 0.005).ceil() as usize).max(1);
    (0..=n)
        .map(|i| lo + (hi - lo) * i as f64 / n as f64)
        .flat_map(|t| [Direction::Forward, Direction::Reverse].map(|d| model.repeatable_error_deg(t, d).abs()))
        .fold(0.0, f64::max)
}

/// The model without its noise effects (for exact tests).
pub fn without_noise(model: &Model) -> Model {
    Model {
        design: model.design.clone(),
        effects: model.effects.iter().filter(|e| !matches!(e, Effect::Noise { .. })).cloned().collect(),
        motions: survey_processing::model::AxisMotions { bearing_sigma_um: 0.0, ..model.motions.clone() },
        ..model.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_name_themselves() {
        let all = Preset::all();
        assert_eq!(all.iter().map(|p| p.name).collect::<Vec<_>>(), NAMES);
        assert_eq!(Preset::default().name, "fig8");
        assert_eq!(Preset::by_name(" FIG4 ").unwrap().name, "fig4");
        assert!(Preset::by_name("fig9").is_none());
        for p in &all {
            // The embedded text round-trips through the contract's format.
            let again = Model::parse(&p.model.to_toml(), "again").unwrap();
            assert_eq!(again, p.model, "{}", p.name);
            assert!(p.model_toml.starts_with("# "), "{} has a leading comment", p.name);
            assert!(p.model.noise_sigma_deg() > 0.0 && p.model.backlash_deg() > 0.0);
        }
    }

    #[test]
    fn fig8_native_peak_is_about_0_015() {
        let p = Preset::by_name("fig8").unwrap();
        let peak = p.native_peak_deg();
        assert!((0.013..=0.017).contains(&peak), "fig8 native peak {peak}");
        assert_eq!(p.model.design.gear_ratios, vec![20.0]);
        // Hysteresis leaves about ±0.004 for a non-directional correction.
        assert!((p.model.backlash_deg() - 0.008).abs() < 1e-12);
        // The pattern repeats every 18 degrees apart from the small eccentricity.
        let e = |t: f64| p.model.periodic_error_deg(t);
        assert!((e(5.0) - e(23.0)).abs() < 2.0 * 0.0015 * (9f64).to_radians().sin() + 1e-12);
    }

    #[test]
    fn fig1_peak_is_about_0_04_over_its_travel() {
        let p = Preset::by_name("fig1").unwrap();
        assert_eq!(p.travel, Some((-10.0, 90.0)));
        let peak = p.native_peak_deg();
        assert!((0.035..=0.045).contains(&peak), "fig1 peak {peak}");
        assert_eq!(p.model.design.gear_ratios, vec![6.0, 72.0]);
        // The 6:1 gear pass dominates.
        let amp = |c: f64| {
            p.model
                .periodic_effects()
                .filter_map(|e| match e {
                    Effect::Periodic { cycles_per_rev, amplitude_deg, .. } if *cycles_per_rev == c => {
                        Some(*amplitude_deg)
                    }
                    _ => None,
                })
                .sum::<f64>()
        };
        assert!(amp(6.0) > 3.0 * amp(72.0) && amp(72.0) > 0.0);
    }

    #[test]
    fn fig4_has_the_papers_spectrum() {
        let p = Preset::by_name("fig4").unwrap();
        let d = &p.model.design;
        assert_eq!((d.gear_ratios.clone(), d.tooth_counts.clone(), d.encoder_heads), (vec![12.0], vec![216], Some(2)));
        let amp = |c: f64| {
            p.model
                .periodic_effects()
                .filter_map(|e| match e {
                    Effect::Periodic { cycles_per_rev, amplitude_deg, .. } if *cycles_per_rev == c => {
                        Some(*amplitude_deg)
                    }
                    _ => None,
                })
                .sum::<f64>()
        };
        // Pinion harmonics decrease to the 5th; the ring gear fundamental is below
        // the pinion fundamental and its harmonics and sidebands below it.
        let pinion: Vec<f64> = [12.0, 24.0, 36.0, 48.0, 60.0].map(amp).to_vec();
        assert!(pinion.windows(2).all(|w| w[0] > w[1] && w[1] > 0.0), "{pinion:?}");
        assert!(amp(216.0) < amp(12.0));
        for c in [432.0, 648.0, 204.0, 228.0] {
            assert!(amp(c) > 0.0 && amp(c) < amp(216.0), "{c}");
        }
        assert!(amp(2.0) > 0.0);
        // Dual heads: no odd harmonics of 1 below the pinion fundamental.
        for c in [1.0, 3.0, 5.0, 7.0] {
            assert_eq!(amp(c), 0.0);
        }
    }

    #[test]
    fn positioner_config_carries_the_preset() {
        let p = Preset::by_name("fig1").unwrap();
        let c = p.positioner_config(9);
        assert_eq!((c.travel, c.seed, c.velocity_deg_s), (Some((-10.0, 90.0)), 9, 5.0));
        assert_eq!(c.model, p.model);
        assert!(without_noise(&p.model).noise_sigma_deg() == 0.0);
        assert_eq!(p.travel_or_full(), (-10.0, 90.0));
    }
}
