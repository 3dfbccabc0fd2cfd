//! The positioner's motion during a move, beyond the commanded profile: the
//! servo's ripple and ringing ([`crate::servo`]) on the displayed readout,
//! and the true angle along the move.
//!
//! The controller closes its loop on the encoder: the displayed readout
//! follows the profile (plus the servo's ripple and ringing), and the true
//! angle at every moment is the one at which the encoder (through the
//! correction table when it is applied) reads that display:
//! `actual + e(actual) + n = raw(display)`. Along a move the non-repeatable
//! part `n` is a random function of the displayed angle (our own model: an
//! independent normal value of the model's noise sigma every
//! [`MOTION_NOISE_STEP_DEG`], linearly interpolated, drawn afresh for every
//! move and joining the rest noise at the target), so a readout captured
//! while the axis turns carries the error at the angle it passes.
//!
//! At rest (the profile over, the drive holding) the true angle is exactly
//! the rest angle the positioner computed when the move started.

use super::SimPositioner;
use crate::servo::{Response, hashed_normal};
use crate::turntable::{AxisPath, Profile, TruthPath};
use crate::{derive_seed, fixed_point};
use std::sync::{Arc, OnceLock};
use std::time::Duration;
use survey_processing::Direction;
use survey_processing::model::Model;
use survey_processing::table::CorrectionTable;

/// Spacing of the independent values of the non-repeatable error along a
/// move, degrees of displayed angle.
pub const MOTION_NOISE_STEP_DEG: f64 = 0.05;

/// Salt of the seed of the noise along moves.
const MOTION_NOISE_SALT: u64 = 0x6d6f_7469_6f6e;

/// The true angle along one move (see the module documentation).
#[derive(Debug)]
pub(super) struct MoveTruth {
    display: AxisPath,
    response: Option<Response>,
    target: f64,
    rest_actual: f64,
    still_from: Duration,
    model: Arc<Model>,
    direction: Direction,
    /// The model's drift over the move (it changes by the run, not along
    /// a move): `systematic_error_deg`'s second term, made once.
    drift_deg: f64,
    /// The table applied in the feedback path, if any.
    table: Option<Arc<CorrectionTable>>,
    rest_noise: f64,
    noise_seed: u64,
    noise_sigma: f64,
    /// The noise grid's values about the target (what a reference that
    /// integrates near it asks for again and again), made when first asked.
    near_target: OnceLock<NearTarget>,
}

/// The noise grid's values at the four grid points about a move's target.
#[derive(Debug, Clone, Copy)]
struct NearTarget {
    /// The grid index of the first of `values`.
    first: i64,
    values: [f64; 4],
    /// `rest_noise - grid(target)`: the rest noise the path joins.
    rest_offset: f64,
}

impl MoveTruth {
    fn display_at(&self, t: Duration) -> f64 {
        self.display.value(t) + self.response.map_or(0.0, |r| r.offset_deg(t))
    }

    /// The noise grid's value (standard normal) at grid index `k`.
    fn grid_value(&self, k: i64, near: &NearTarget) -> f64 {
        match usize::try_from(k - near.first) {
            Ok(i) if i < near.values.len() => near.values[i],
            _ => hashed_normal(self.noise_seed, k),
        }
    }

    /// The noise grid interpolated at displayed angle `x`.
    fn grid(&self, x: f64, near: &NearTarget) -> f64 {
        let k = (x / MOTION_NOISE_STEP_DEG).floor();
        let f = x / MOTION_NOISE_STEP_DEG - k;
        let (a, b) = (self.grid_value(k as i64, near), self.grid_value(k as i64 + 1, near));
        (a + (b - a) * f) * self.noise_sigma
    }

    fn near_target(&self) -> &NearTarget {
        self.near_target.get_or_init(|| {
            let first = (self.target / MOTION_NOISE_STEP_DEG).floor() as i64 - 1;
            let values = std::array::from_fn(|i| hashed_normal(self.noise_seed, first + i as i64));
            let mut near = NearTarget { first, values, rest_offset: 0.0 };
            near.rest_offset = self.rest_noise - self.grid(self.target, &near);
            near
        })
    }

    /// The non-repeatable error where the display shows `d`.
    fn noise_at(&self, d: f64) -> f64 {
        if self.noise_sigma == 0.0 {
            return self.rest_noise;
        }
        let near = self.near_target();
        let join = (1.0 - (d - self.target).abs() / MOTION_NOISE_STEP_DEG).max(0.0);
        self.grid(d, near) + near.rest_offset * join
    }
}

impl TruthPath for MoveTruth {
    fn actual_deg(&self, t: Duration) -> f64 {
        let d = self.display_at(t);
        if t >= self.still_from || (d == self.target && t >= self.display.halt_at) {
            return self.rest_actual;
        }
        let raw = match &self.table {
            Some(table) => fixed_point(|raw| d + table.error_at(raw, self.direction), d),
            None => d,
        };
        let n = self.noise_at(d);
        // `systematic_error_deg(a, direction, runs)`, term by term.
        fixed_point(|a| raw - n - (self.model.repeatable_error_deg(a, self.direction) + self.drift_deg), raw - n)
    }

    fn still_from(&self) -> Duration {
        self.still_from
    }
}

impl SimPositioner {
    /// The displayed readout at `t`: the commanded path plus the servo's
    /// ripple and ringing.
    pub(super) fn display_at(&self, t: Duration) -> f64 {
        self.display.value(t) + self.response.map_or(0.0, |r| r.offset_deg(t))
    }

    /// A move along `profile` to the display `target` (true rest angle
    /// `actual`) has started: set the servo's response, when the axis will be
    /// in position, and the true angle the other instruments see.
    pub(super) fn follow_move(&mut self, profile: Profile, target: f64, actual: f64) {
        let end = profile.end();
        let distance = target - self.display.from;
        self.response = self.cfg.servo.map(|servo| {
            Response::new(servo, profile.start, end, distance, profile.velocity_deg_s, profile.accel_deg_s2)
        });
        if let Some(r) = &self.response {
            self.settle_until = r.hold_at();
        }
        let table = match (&self.table, self.correction) {
            (Some(t), true) => Some(t.clone()),
            _ => None,
        };
        let truth = MoveTruth {
            display: self.display,
            response: self.response,
            target,
            rest_actual: actual,
            still_from: self.response.map_or(end, |r| r.hold_at().max(end)),
            model: self.model.clone(),
            direction: self.direction,
            drift_deg: self.cfg.model.drift_deg(self.runs_at(end)),
            table,
            rest_noise: self.noise_deg,
            noise_seed: derive_seed(self.cfg.seed ^ MOTION_NOISE_SALT, self.moves as u64),
            noise_sigma: self.cfg.model.noise_sigma_deg(),
            near_target: OnceLock::new(),
        };
        self.turntable.set_truth(Arc::new(truth));
    }
}

#[cfg(test)]
mod tests {
    use super::super::{PositionerConfig, SimPositioner};
    use crate::presets::{Preset, without_noise};
    use crate::servo::Servo;
    use std::sync::Arc;
    use std::time::Duration;
    use survey_drivers::VirtualClock;
    use survey_drivers::clock::Clock;
    use survey_drivers::traits::Positioner;
    use survey_processing::Direction;

    fn servo_sim(noise: bool) -> (VirtualClock, SimPositioner) {
        let model = Preset::default().model;
        let model = if noise { model } else { without_noise(&model) };
        let cfg = PositionerConfig { servo: Some(Servo::default()), seed: 5, ..PositionerConfig::new(model) };
        let clock = VirtualClock::new();
        let p = SimPositioner::new(cfg, Arc::new(clock.clone()));
        (clock, p)
    }

    #[tokio::test]
    async fn a_servo_axis_rings_after_a_move_and_is_in_position_once_held() {
        let (clock, mut p) = servo_sim(false);
        let servo = Servo::default();
        p.move_to(10.0).await.unwrap();
        let start = clock.now();
        let end = start + Duration::from_secs_f64(crate::turntable::Profile::new(start, 10.0, 10.0, 20.0).duration_s);
        // Right after the profile the readout overshoots forward.
        clock.advance_to(end + Duration::from_millis(25) - crate::LINK_LATENCY);
        let r = p.readout().await.unwrap();
        assert!(r > 10.0 + 1e-3, "{r}");
        let s = p.status().await.unwrap();
        assert!(!s.moving && !s.in_position, "{s:?}");
        // Within the 1e-4 deg window from the servo's settle time on ...
        let settle = servo.move_settle_s(10.0, 10.0, 20.0, 1e-4);
        clock.advance_to(end + Duration::from_secs_f64(settle) - crate::LINK_LATENCY);
        for _ in 0..100 {
            let r = p.readout().await.unwrap();
            assert!((r - 10.0).abs() <= 1e-4 * (1.0 + 1e-6), "{r}");
            clock.sleep(Duration::from_millis(3)).await;
        }
        // ... and exactly on target, in position, once the drive holds.
        let hold = servo.settle_time_s(servo.amplitude_deg(10.0), servo.hold_deg);
        clock.advance_to(end + Duration::from_secs_f64(hold) + Duration::from_millis(1));
        assert_eq!(p.readout().await.unwrap(), 10.0);
        assert!(p.status().await.unwrap().in_position);
    }

    #[tokio::test]
    async fn the_true_angle_along_a_move_is_where_the_encoder_reads_the_display() {
        // With noise: readout - actual - e(actual) is the non-repeatable part,
        // within 5 sigma everywhere along a long move, and the rest noise at rest.
        let (clock, mut p) = servo_sim(true);
        let model = Preset::default().model;
        let sigma = model.noise_sigma_deg();
        let truth = p.truth();
        p.move_to(40.0).await.unwrap();
        let mut seen = Vec::new();
        for _ in 0..400 {
            clock.sleep(Duration::from_millis(10)).await;
            let r = p.readout().await.unwrap();
            let a = truth.actual_deg(clock.now());
            let n = r - a - model.systematic_error_deg(a, Direction::Forward, 0.0);
            assert!(n.abs() < 5.0 * sigma, "{n} at {r}");
            seen.push(n);
        }
        // The noise along the move varies (a function of the angle).
        let spread = seen.iter().cloned().fold(f64::MIN, f64::max) - seen.iter().cloned().fold(f64::MAX, f64::min);
        assert!(spread > sigma, "{spread}");
        clock.sleep(Duration::from_secs(2)).await;
        let r = p.readout().await.unwrap();
        let a = truth.actual_deg(clock.now());
        let n = r - a - model.systematic_error_deg(a, Direction::Forward, 0.0);
        assert!((n - p.rest_noise_deg()).abs() < 1e-9, "{n}");
        assert_eq!(r, 40.0);
    }

    #[tokio::test]
    async fn the_capture_stamps_readouts_on_the_controllers_clock_and_loses_some() {
        let model = without_noise(&Preset::default().model);
        let mut cfg = PositionerConfig { servo: Some(Servo::default()), ..PositionerConfig::new(model) };
        cfg.capture.drop_probability = 0.1;
        let clock = VirtualClock::new();
        let mut p = SimPositioner::new(cfg.clone(), Arc::new(clock.clone()));
        assert!(p.can_capture());
        assert!(p.read_capture().await.is_err(), "nothing captured before a start");
        p.start_capture(Duration::from_millis(5)).await.unwrap();
        let t0 = clock.now();
        p.move_to(20.0).await.unwrap();
        let mut got = Vec::new();
        for _ in 0..80 {
            clock.sleep(Duration::from_millis(50)).await;
            got.extend(p.read_capture().await.unwrap());
        }
        let span = (clock.now() - t0).as_secs_f64();
        let due = (span / 0.005).floor() as usize;
        // 10 % lost: binomial sd sqrt(n p q) ~ 17 of ~810; 4 of them either way.
        let lost = due - got.len();
        assert!((lost as f64 - 0.1 * due as f64).abs() < 70.0, "{lost} of {due}");
        // Stamps: the controller's clock, on the 5 ms grid from the start.
        for r in &got {
            let host = (r.device_time_s - cfg.capture.clock.offset_s) / (1.0 + cfg.capture.clock.rate_ppm * 1e-6);
            let k = (host - t0.as_secs_f64()) / 0.005;
            assert!((k - k.round()).abs() < 1e-6, "{k}");
        }
        assert!(got.windows(2).all(|w| w[1].device_time_s > w[0].device_time_s));
        assert_eq!(got.last().unwrap().readout_deg, 20.0);
        p.stop_capture().await.unwrap();
        assert!(p.read_capture().await.is_err());
    }
}
