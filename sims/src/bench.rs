//! A bench of simulated instruments: one positioner, one tracker and one
//! autocollimator on one turntable and one clock, built from a preset and a seed.
//!
//! The instruments' seeds are derived from the bench seed with
//! [`derive_seed`](crate::derive_seed) (salts 1, 2, 3 for the positioner, the
//! tracker and the autocollimator), so one number reproduces a whole survey.
//!
//! ```
//! # use std::sync::Arc;
//! # use survey_drivers::{Clock, VirtualClock};
//! # use survey_sims::{Preset, SimBench, PositionerFaults};
//! let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
//! let bench = SimBench::builder(&Preset::default(), 42, clock)
//!     .faults(PositionerFaults { fault_on_move: Some(10), ..Default::default() })
//!     .beam_break_probability(0.01)
//!     .build();
//! let SimBench { positioner, tracker, autocollimator, .. } = bench;
//! ```

use crate::autocollimator::{AutocollimatorConfig, SimAutocollimator};
use crate::derive_seed;
use crate::faults::{FaultRates, Injected};
use crate::positioner::{PlanProgress, PositionerConfig, PositionerFaults, SimPositioner};
use crate::presets::{Preset, without_noise};
use crate::tracker::{ArmGeometry, SimTracker, TrackerConfig};
use crate::turntable::Turntable;
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::clock::Clock;
use survey_processing::model::Model;

/// The three simulated instruments on one turntable and one clock.
#[derive(Debug)]
pub struct SimBench {
    /// The clock every instrument runs on.
    pub clock: Arc<dyn Clock>,
    /// The shared truth (a handle; the positioner drives it).
    pub turntable: Turntable,
    /// The positioner under test.
    pub positioner: SimPositioner,
    /// The tracking laser on the arm's SMR.
    pub tracker: SimTracker,
    /// The autocollimator on the polygon.
    pub autocollimator: SimAutocollimator,
    /// The stage the polygon stands on, when it does
    /// ([`SimBenchBuilder::polygon_stage`]).
    pub polygon_stage: Option<SimPositioner>,
    /// The faults the three instruments injected, by kind.
    pub injected: Injected,
}

/// A typical indexing table under a polygon, seeded from `seed`: its error
/// an eccentricity of 1 arcsec and a fourth order of 0.5 arcsec at drawn
/// phases, 0.1 arcsec of noise per placement, 20 deg/s. Our own choice,
/// of the order a good indexing table's specification states (a few
/// arcsec of positioning error): the closure measures whatever it is.
pub fn index_stage(seed: u64) -> PositionerConfig {
    use rand::Rng;
    let mut rng = crate::seeded_rng(seed, 0);
    let (p1, p4): (f64, f64) = (rng.random_range(0.0..360.0), rng.random_range(0.0..360.0));
    let text = format!(
        "[[effect]]\nkind = \"eccentricity\"\ncycles_per_rev = 1\namplitude_deg = {}\nphase_deg = {p1}\n\n\
         [[effect]]\nkind = \"harmonic\"\ncycles_per_rev = 4\namplitude_deg = {}\nphase_deg = {p4}\n\n\
         [[effect]]\nkind = \"noise\"\nsigma_deg = {}\n",
        1.0 / 3600.0,
        0.5 / 3600.0,
        0.1 / 3600.0
    );
    let model = Model::parse(&text, "index stage").expect("a valid model");
    PositionerConfig { velocity_deg_s: 20.0, seed, ..PositionerConfig::new(model) }
}

impl SimBench {
    /// The bench for `preset` with every instrument at its defaults, seeded from `seed`.
    pub fn new(preset: &Preset, seed: u64, clock: Arc<dyn Clock>) -> Self {
        Self::builder(preset, seed, clock).build()
    }

    /// A builder to change configurations before building.
    pub fn builder(preset: &Preset, seed: u64, clock: Arc<dyn Clock>) -> SimBenchBuilder {
        SimBenchBuilder {
            clock,
            positioner: preset.positioner_config(derive_seed(seed, 1)),
            tracker: TrackerConfig { seed: derive_seed(seed, 2), ..TrackerConfig::default() },
            autocollimator: AutocollimatorConfig::seeded(24, derive_seed(seed, 3)),
            polygon_stage: None,
        }
    }
}

/// Builds a [`SimBench`]; the configurations are public to change anything.
#[derive(Debug, Clone)]
pub struct SimBenchBuilder {
    /// The clock the instruments will run on.
    pub clock: Arc<dyn Clock>,
    /// The positioner's configuration (from the preset, seed derived).
    pub positioner: PositionerConfig,
    /// The tracker's configuration (defaults, seed derived).
    pub tracker: TrackerConfig,
    /// The autocollimator's configuration (24 faces, certificate and seed derived).
    pub autocollimator: AutocollimatorConfig,
    /// The stage the polygon stands on (`None`: on the table itself).
    pub polygon_stage: Option<PositionerConfig>,
}

impl SimBenchBuilder {
    /// Replace the positioner's error model, and the tracker's own error
    /// with the model file's `[tracker_errors]` (omitted: the typical one).
    pub fn model(mut self, model: Model) -> Self {
        self.tracker.errors = model.tracker_errors.clone();
        self.positioner.model = model;
        self
    }

    /// Inject positioner faults.
    pub fn faults(mut self, faults: PositionerFaults) -> Self {
        self.positioner.faults = faults;
        self
    }

    /// Set the positioner's travel (`None` = continuous rotation).
    pub fn travel(mut self, travel: Option<(f64, f64)>) -> Self {
        self.positioner.travel = travel;
        self
    }

    /// Apply the model's drift over time: one run takes `period` of clock time
    /// (when no [`SimBenchBuilder::drift_progress`] is given).
    pub fn drift_run_period(mut self, period: Duration) -> Self {
        self.positioner.drift_run_period = Some(period);
        self
    }

    /// Apply the model's drift by the survey's place in its plan (see
    /// [`crate::positioner`]): whoever runs the plan sets `progress` to the
    /// next step before that step's moves.
    pub fn drift_progress(mut self, progress: PlanProgress) -> Self {
        self.positioner.drift_progress = Some(progress);
        self
    }

    /// Replace the tracker's arm geometry.
    pub fn arm(mut self, arm: ArmGeometry) -> Self {
        self.tracker.arm = arm;
        self
    }

    /// The positioner's servo rings and ripples ([`crate::servo`]).
    pub fn servo(mut self, servo: crate::servo::Servo) -> Self {
        self.positioner.servo = Some(servo);
        self
    }

    /// Lose this fraction of the tracker's streamed points and of the
    /// positioner's captured readouts.
    pub fn stream_losses(mut self, tracker: f64, positioner: f64) -> Self {
        self.tracker.stream.drop_probability = tracker;
        self.positioner.capture.drop_probability = positioner;
        self
    }

    /// Beam-break probability per tracker measurement.
    pub fn beam_break_probability(mut self, p: f64) -> Self {
        self.tracker.beam_break_probability = p;
        self
    }

    /// Inject faults at `rates` in process (no wire): the positioner's calls
    /// time out, disconnect or come back garbled at the link rates (a stall
    /// needs a wire: see `survey sim`), its moves trip at `move`; the tracker's
    /// beam breaks at `beam` and stays broken `beam_hold_s`; the
    /// autocollimator's reads find no reflection at `device`.
    pub fn fault_rates(mut self, rates: &FaultRates) -> Self {
        let f = &mut self.positioner.faults;
        f.timeout_probability_per_call = rates.timeout;
        f.disconnect_probability_per_call = rates.disconnect;
        f.garbled_probability_per_call = rates.garbled;
        f.fault_probability_per_move = rates.r#move;
        self.tracker.beam_break_probability = rates.beam;
        self.tracker.beam_hold = Duration::from_secs_f64(rates.beam_hold_s);
        self.autocollimator.blocked_probability = rates.device;
        self
    }

    /// The polygon stands on a stage driven by a positioner of `cfg`
    /// ([`index_stage`]: a typical indexing table).
    pub fn polygon_stage(mut self, cfg: PositionerConfig) -> Self {
        self.polygon_stage = Some(cfg);
        self
    }

    /// Replace the autocollimator configuration (e.g. another polygon).
    pub fn autocollimator(mut self, cfg: AutocollimatorConfig) -> Self {
        self.autocollimator = cfg;
        self
    }

    /// No noise anywhere: the positioner model loses its noise effects, the
    /// tracker (an ideal one, without its own error) and the autocollimator
    /// read exact values. For exact tests.
    pub fn without_noise(mut self) -> Self {
        self.positioner.model = without_noise(&self.positioner.model);
        self.tracker.noise_scale = 0.0;
        self.tracker.errors = survey_processing::tracker_errors::TrackerErrorSpec::None;
        self.autocollimator.noise_arcsec = 0.0;
        self
    }

    /// The axis without error motions (ISO 230-7): the table turns about a
    /// fixed line, so the tracker sees the positioner's angle alone (a test
    /// of something else held to the positioner's truth within microdegrees:
    /// a tilt motion with the SMR above its centre moves it along its circle).
    pub fn without_motions(mut self) -> Self {
        self.positioner.model.motions = survey_processing::model::AxisMotions::default();
        self
    }

    /// Build the instruments on one new turntable.
    pub fn build(mut self) -> SimBench {
        // The axis's error motions are the positioner's, seen by the tracker.
        self.tracker.motions = self.positioner.model.motions.clone();
        let turntable = Turntable::new(0.0);
        let injected = Injected::new();
        let mut positioner = SimPositioner::with_turntable(self.positioner, self.clock.clone(), turntable.clone());
        let mut tracker = SimTracker::new(self.tracker, self.clock.clone(), turntable.clone());
        let mut autocollimator = SimAutocollimator::new(self.autocollimator, self.clock.clone(), turntable.clone());
        positioner.count_injected(injected.clone());
        tracker.count_injected(injected.clone());
        autocollimator.count_injected(injected.clone());
        let polygon_stage = self.polygon_stage.map(|cfg| {
            let stage = Turntable::new(0.0);
            autocollimator.on_stage(stage.clone());
            let mut p = SimPositioner::with_turntable(cfg, self.clock.clone(), stage).named("sim-polygon-stage");
            p.count_injected(injected.clone());
            p
        });
        SimBench { clock: self.clock, turntable, positioner, tracker, autocollimator, polygon_stage, injected }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_drivers::VirtualClock;
    use survey_drivers::traits::{Autocollimator, Positioner, Tracker};

    async fn settle(p: &mut SimPositioner) {
        for _ in 0..100_000 {
            if p.status().await.unwrap().in_position {
                return;
            }
        }
        panic!("never in position");
    }

    /// One short survey: moves, readouts and measurements of all three instruments.
    async fn survey(seed: u64) -> Vec<f64> {
        let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
        let mut b = SimBench::new(&Preset::default(), seed, clock);
        let mut out = Vec::new();
        for k in [0.0, 15.0, 30.0, 45.0, 30.0] {
            b.positioner.move_to(k).await.unwrap();
            settle(&mut b.positioner).await;
            out.push(b.positioner.readout().await.unwrap());
            out.push(b.turntable.actual_deg(b.clock.now()));
            out.extend(b.tracker.measure().await.unwrap().xyz());
            let r = b.autocollimator.read().await.unwrap();
            out.extend([r.x_arcsec, r.y_arcsec]);
        }
        out.push(b.clock.now().as_secs_f64());
        out
    }

    #[tokio::test]
    async fn same_seed_is_bit_identical_and_another_differs() {
        let a = survey(42).await;
        let b = survey(42).await;
        assert_eq!(
            a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            b.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        assert_ne!(a, survey(43).await);
    }

    #[tokio::test]
    async fn instruments_share_the_turntable() {
        let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
        let mut b = SimBench::builder(&Preset::by_name("fig4").unwrap(), 1, clock).without_noise().build();
        b.positioner.move_to(45.0).await.unwrap();
        settle(&mut b.positioner).await;
        let actual = b.positioner.truth().actual_deg(b.clock.now());
        assert!((actual - 45.0).abs() < 0.02);
        let m = b.tracker.measure().await.unwrap();
        let expect = b.tracker.config().arm.smr_position_mm(actual);
        assert!((0..3).all(|i| (m.xyz()[i] - expect[i]).abs() < 1e-9));
        let r = b.autocollimator.read().await.unwrap();
        let cert = b.autocollimator.certificate_arcsec()[3];
        assert!((45.0 + (r.x_arcsec + cert) / 3600.0 - actual).abs() < 1e-9);
    }
}
