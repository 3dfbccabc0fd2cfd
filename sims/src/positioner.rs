//! A simulated positioner controller: one axis with the error model of the
//! paper, a trapezoidal move profile, a settle time, travel limits, a real-time
//! correction table in the feedback path, and injected faults.
//!
//! # The error
//!
//! The encoder reads `raw = actual + e(actual) + n`, where
//! `e = model.systematic_error_deg(actual, direction, runs_elapsed)` and `n` is
//! the noise of the current rest position:
//!
//! - `direction` is the direction of the last move (forward when the target is
//!   above the start readout, reverse when below; a zero-length move keeps the
//!   previous direction; forward at power-up).
//! - `n ~ Normal(0, model.noise_sigma_deg())` is drawn once per accepted move:
//!   it is where the servo came to rest, so reading a stationary axis again
//!   returns the same value.
//! - `runs_elapsed` is the time of the drift in runs (see below) of the move
//!   that brought the axis to rest. The drift is frozen while the axis rests:
//!   only moves pick up new drift.
//!
//! # The time of the drift
//!
//! The model's drift is `rate_deg_per_run` from one run to the next: a ramp
//! grows linearly through a run, a step holds within a run and jumps between
//! runs ([`survey_processing::model::DriftShape`]). The simulator measures
//! the time in runs by one of two clocks, the first that is configured:
//!
//! - [`PlanProgress`] (what the simulated bench uses): the survey's place in
//!   its plan, set by whoever runs the plan to the index of the next step
//!   before that step's moves. Step `j` of run `k` (both from 0, `n` steps a
//!   run) is at `runs_elapsed = k + j / n`: exactly `k` runs at the first
//!   step of each run, whatever the engine does between steps (locating the
//!   axis, overrun moves, faults and retries, a resume). A ramp is then
//!   exactly `rate` from one run to the next and linear in the plan's steps
//!   within a run (linear in time as far as the steps take equal time); a
//!   step is exactly `rate x k`. Moves before the first step (locating the
//!   axis) are at step 0.
//! - `drift_run_period` (a bare positioner, with no plan): `runs_elapsed = t /
//!   drift_run_period`, `t` the clock time the axis comes to rest (the end of
//!   the move's profile).
//!
//! With neither, there is no drift. This is our own design (a simulator
//! needs a definition of "one run"); no public document describes it.
//!
//! The displayed readout is `raw`, or `raw - table.error_at(raw, direction)`
//! when a correction table is enabled (the paper's real-time correction in the
//! feedback path). The servo drives the displayed readout to the target, so at
//! rest the readout equals the target exactly and the true angle solves
//! `actual + e(actual) + n = raw` (fixed-point iteration to 1e-12 degrees).
//!
//! # Motion and status
//!
//! A move starts when `move_to` returns (after the link latency) and follows
//! the profile of [`crate::turntable::Profile`] over the displayed distance;
//! the displayed readout and the true angle both move along the profile.
//! `status()` reports `moving` during the profile, then neither `moving` nor
//! `in_position` during the settle time, then `in_position`. A new `move_to`
//! during a move starts from where the axis is. `stop()` ends the motion where
//! the axis is: the readout there is `actual + e(actual) + n` (no servo target),
//! and after the settle time the axis is in position at that readout.
//!
//! # Link and device faults ([`PositionerFaults`])
//!
//! Every call first pays [`LINK_LATENCY`]. An injected link fault loses the
//! request (nothing happens): a timeout sleeps one hour of clock time and then
//! answers `ErrorKind::Timeout` (so the engine's `with_timeout` fires first), a
//! disconnect answers at once, a garbled reply after the latency. An injected device fault
//! trips the drive halfway through the move's profile (in time): the axis halts
//! there, `status().fault` reports [`FAULT_FOLLOWING_ERROR`], `in_position`
//! stays false, and moves are refused with that device error until
//! `clear_fault()`; after clearing, the axis must be commanded again.

use crate::faults::{FaultKind, Injected};
use crate::servo::{DeviceClock, Response, Servo};
use crate::turntable::{AxisPath, Profile, Turntable};
use crate::{FAULT_STREAM, LINK_LATENCY, NOISE_STREAM, fixed_point, seeded_rng};
use async_trait::async_trait;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;
use survey_drivers::clock::Clock;
use survey_drivers::error::{DriverError, ErrorKind, Result};
use survey_drivers::traits::{CapturedReadout, DeviceFault, Limit, Positioner, PositionerStatus};
use survey_processing::Direction;
use survey_processing::model::Model;
use survey_processing::table::CorrectionTable;

/// The instrument name in errors.
const INSTRUMENT: &str = "positioner";

/// Device fault code of a tripped drive: CiA 402 "following error" (0x8611).
pub const FAULT_FOLLOWING_ERROR: i64 = 0x8611;

/// How long an injected timeout keeps the call waiting, clock time.
pub const INJECTED_TIMEOUT: Duration = Duration::from_secs(3600);

/// Tolerance of the travel-limit switches, degrees.
const LIMIT_TOLERANCE_DEG: f64 = 1e-9;

/// Faults to inject. All probabilities are 0 and nothing is scheduled by default.
///
/// Scheduled faults count calls from 1: `fault_on_move: Some(3)` trips the
/// third accepted `move_to`; `timeout_on_call: Some(5)` makes the fifth call
/// of any method (`name()` excepted) time out.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PositionerFaults {
    /// Probability that an accepted move trips the drive.
    pub fault_probability_per_move: f64,
    /// Probability that a call times out (sleeps [`INJECTED_TIMEOUT`], then `Timeout`).
    pub timeout_probability_per_call: f64,
    /// Probability that a call fails with `Disconnected` (once; the next call works).
    pub disconnect_probability_per_call: f64,
    /// Probability that a call's reply is garbled (`Garbled`).
    pub garbled_probability_per_call: f64,
    /// Trip the drive on this accepted move (1-based).
    pub fault_on_move: Option<usize>,
    /// Time out on this call (1-based).
    pub timeout_on_call: Option<usize>,
    /// Disconnect on this call (1-based).
    pub disconnect_on_call: Option<usize>,
}

/// Configuration of a [`SimPositioner`].
#[derive(Debug, Clone, PartialEq)]
pub struct PositionerConfig {
    /// The error model (the contract's model file).
    pub model: Model,
    /// Initial velocity, degrees per second (default 10).
    pub velocity_deg_s: f64,
    /// Acceleration and deceleration, degrees per second squared (default 20).
    pub accel_deg_s2: f64,
    /// Settle time after the profile ends (default 300 ms).
    pub settle: Duration,
    /// Travel limits `(lower, upper)`, readout degrees; `None` = continuous rotation.
    pub travel: Option<(f64, f64)>,
    /// Clock time one survey run takes: turns the model's drift per run into
    /// drift over time (`runs_elapsed = t / period`) when there is no
    /// [`PositionerConfig::drift_progress`]. `None` = no drift by time.
    pub drift_run_period: Option<Duration>,
    /// The survey's place in its plan: the drift's time in runs (see the
    /// module documentation). Takes precedence over `drift_run_period`.
    pub drift_progress: Option<PlanProgress>,
    /// Seed of the noise and fault streams.
    pub seed: u64,
    /// Faults to inject.
    pub faults: PositionerFaults,
    /// Link latency of every call (default [`LINK_LATENCY`], 2 ms).
    pub link_latency: Duration,
    /// The servo's ringing and ripple ([`crate::servo`]); `None` (the
    /// default): the axis rests on its target when the profile ends and is
    /// in position after `settle`.
    pub servo: Option<Servo>,
    /// The position capture ([`Positioner::start_capture`]).
    pub capture: CaptureSim,
}

/// How the simulated controller's position capture stamps and loses readouts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureSim {
    /// The controller's clock (default: 123.4 s ahead, 30 ppm fast).
    pub clock: DeviceClock,
    /// Probability that a captured readout is lost (default 0).
    pub drop_probability: f64,
}

impl Default for CaptureSim {
    fn default() -> Self {
        Self { clock: DeviceClock { offset_s: 123.4, rate_ppm: 30.0 }, drop_probability: 0.0 }
    }
}

impl PositionerConfig {
    /// Defaults around a model: 10 deg/s, 20 deg/s², 300 ms settle, continuous
    /// rotation, no drift period, seed 0, no faults.
    pub fn new(model: Model) -> Self {
        Self {
            model,
            velocity_deg_s: 10.0,
            accel_deg_s2: 20.0,
            settle: Duration::from_millis(300),
            travel: None,
            drift_run_period: None,
            drift_progress: None,
            seed: 0,
            faults: PositionerFaults::default(),
            link_latency: LINK_LATENCY,
            servo: None,
            capture: CaptureSim::default(),
        }
    }
}

/// A survey's place in its plan, shared between the one who runs the plan
/// (it sets the next step before that step's moves) and the simulated
/// positioner (it reads the drift's time from it): step `j` of run `k` is at
/// `k + j / steps_per_run` runs, counted on from the runs of the plans before
/// it on the same bench ([`PlanProgress::continue_with`]: a verification after
/// the calibration's runs). Clones share the same place.
#[derive(Debug, Clone)]
pub struct PlanProgress {
    place: Arc<Place>,
}

#[derive(Debug)]
struct Place {
    next: AtomicU64,
    steps_per_run: AtomicU64,
    /// Runs of the plans before this one, as f64 bits.
    before_runs: AtomicU64,
}

impl PlanProgress {
    /// A plan of `steps_per_run` steps a run (at least 1), at step 0.
    pub fn new(steps_per_run: u64) -> Self {
        Self {
            place: Arc::new(Place {
                next: AtomicU64::new(0),
                steps_per_run: AtomicU64::new(steps_per_run.max(1)),
                before_runs: AtomicU64::new(0f64.to_bits()),
            }),
        }
    }

    /// The next step to be measured is `seq` (from 0, counted over the whole plan).
    pub fn set_next_step(&self, seq: u64) {
        self.place.next.store(seq, Ordering::Relaxed);
    }

    /// The next step to be measured.
    pub fn next_step(&self) -> u64 {
        self.place.next.load(Ordering::Relaxed)
    }

    /// Steps a run.
    pub fn steps_per_run(&self) -> u64 {
        self.place.steps_per_run.load(Ordering::Relaxed)
    }

    /// Runs elapsed at the next step: the runs before this plan, plus `k + j
    /// / steps_per_run` for step `j` of run `k`.
    pub fn runs_elapsed(&self) -> f64 {
        let (seq, n) = (self.next_step(), self.steps_per_run());
        let before = f64::from_bits(self.place.before_runs.load(Ordering::Relaxed));
        before + (seq / n) as f64 + (seq % n) as f64 / n as f64
    }

    /// A new plan of `steps_per_run` steps a run on the same bench, from its
    /// step 0: time goes on from where the plan before it got to (its runs
    /// elapsed at its next step), so a drift keeps growing.
    pub fn continue_with(&self, steps_per_run: u64) {
        let elapsed = self.runs_elapsed();
        self.place.before_runs.store(elapsed.to_bits(), Ordering::Relaxed);
        self.place.steps_per_run.store(steps_per_run.max(1), Ordering::Relaxed);
        self.set_next_step(0);
    }
}

impl PartialEq for PlanProgress {
    /// The same shared place.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.place, &other.place)
    }
}

/// A latched (or pending: `since` in the future) drive fault.
#[derive(Debug, Clone)]
struct Latched {
    since: Duration,
    fault: DeviceFault,
}

/// The simulated positioner. See the module documentation for its behaviour.
#[derive(Debug)]
pub struct SimPositioner {
    clock: Arc<dyn Clock>,
    cfg: PositionerConfig,
    /// `cfg.model`, shared with the truth of every move (not copied each).
    model: Arc<Model>,
    turntable: Turntable,
    velocity_deg_s: f64,
    /// The displayed readout along the current move (or at rest).
    display: AxisPath,
    /// The true angle along the current move (mirrored into the turntable).
    axis: AxisPath,
    /// The raw encoder value at the current rest position.
    raw_rest: f64,
    /// The noise of the current (or coming) rest position.
    noise_deg: f64,
    direction: Direction,
    settle_until: Duration,
    /// Whether the rest position is the commanded target (false after a trip).
    on_target: bool,
    table: Option<Arc<CorrectionTable>>,
    correction: bool,
    /// The servo's response to the current move ([`motion`]).
    response: Option<Response>,
    /// The position capture, while it runs ([`capture`]).
    capture: Option<capture::Capture>,
    fault: Option<Latched>,
    moves: usize,
    calls: usize,
    noise_rng: ChaCha8Rng,
    fault_rng: ChaCha8Rng,
    injected: Option<Injected>,
    name: &'static str,
}

impl SimPositioner {
    /// Call this positioner `name` in logs and errors (default
    /// `sim-positioner`; a polygon's stage is `sim-polygon-stage`).
    pub fn named(mut self, name: &'static str) -> Self {
        self.name = name;
        self
    }

    /// Count every fault this positioner injects in `injected`.
    pub fn count_injected(&mut self, injected: Injected) {
        self.injected = Some(injected);
    }

    fn injected(&self, kind: FaultKind) {
        if let Some(i) = &self.injected {
            i.add(kind);
        }
    }

    /// A positioner driving a new turntable, at rest at readout 0 (or at the
    /// lower travel limit when 0 is outside the travel).
    pub fn new(cfg: PositionerConfig, clock: Arc<dyn Clock>) -> Self {
        Self::with_turntable(cfg, clock, Turntable::new(0.0))
    }

    /// A positioner driving `turntable` (shared with the other instruments).
    pub fn with_turntable(cfg: PositionerConfig, clock: Arc<dyn Clock>, turntable: Turntable) -> Self {
        let start = match cfg.travel {
            Some((lo, hi)) => 0.0f64.clamp(lo, hi),
            None => 0.0,
        };
        let now = clock.now();
        let mut sim = Self {
            velocity_deg_s: cfg.velocity_deg_s,
            noise_rng: seeded_rng(cfg.seed, NOISE_STREAM),
            fault_rng: seeded_rng(cfg.seed, FAULT_STREAM),
            clock,
            turntable,
            display: AxisPath::at_rest(start, now),
            axis: AxisPath::at_rest(start, now),
            raw_rest: start,
            noise_deg: 0.0,
            direction: Direction::Forward,
            settle_until: now,
            on_target: true,
            table: None,
            correction: false,
            response: None,
            capture: None,
            fault: None,
            moves: 0,
            calls: 0,
            injected: None,
            name: "sim-positioner",
            model: Arc::new(cfg.model.clone()),
            cfg,
        };
        let actual = sim.actual_for_raw(start, sim.runs_at(now));
        sim.axis = AxisPath::at_rest(actual, now);
        sim.turntable.set_path(sim.axis);
        sim
    }

    /// A clone of the turntable handle (the truth the other instruments read).
    pub fn truth(&self) -> Turntable {
        self.turntable.clone()
    }

    /// The configuration.
    pub fn config(&self) -> &PositionerConfig {
        &self.cfg
    }

    /// The true readout error (everything but noise) at true angle `theta_deg`
    /// approached in `direction` after `runs_elapsed` runs: the model's
    /// systematic error.
    pub fn true_error_deg(&self, theta_deg: f64, direction: Direction, runs_elapsed: f64) -> f64 {
        self.cfg.model.systematic_error_deg(theta_deg, direction, runs_elapsed)
    }

    /// Runs elapsed for the drift of a move commanded at clock time `t` (see
    /// the module documentation; 0 without a plan progress or a drift period).
    pub fn runs_elapsed_at(&self, t: Duration) -> f64 {
        self.runs_at(t)
    }

    /// The direction of the last move.
    pub fn direction(&self) -> Direction {
        self.direction
    }

    /// The noise of the current rest position, degrees (for tests).
    pub fn rest_noise_deg(&self) -> f64 {
        self.noise_deg
    }

    /// The raw encoder value at the current rest position (before correction).
    pub fn raw_readout_deg(&self) -> f64 {
        self.raw_rest
    }

    /// Number of accepted moves so far.
    pub fn moves(&self) -> usize {
        self.moves
    }

    fn runs_at(&self, t: Duration) -> f64 {
        if let Some(p) = &self.cfg.drift_progress {
            return p.runs_elapsed();
        }
        match self.cfg.drift_run_period {
            Some(p) if !p.is_zero() => t.as_secs_f64() / p.as_secs_f64(),
            _ => 0.0,
        }
    }

    fn error_at(&self, actual: f64, runs: f64) -> f64 {
        self.cfg.model.systematic_error_deg(actual, self.direction, runs)
    }

    /// What the controller displays for a raw encoder value.
    fn displayed_of_raw(&self, raw: f64) -> f64 {
        match (&self.table, self.correction) {
            (Some(t), true) => raw - t.error_at(raw, self.direction),
            _ => raw,
        }
    }

    /// The raw encoder value at which the display shows `target`.
    fn raw_for_display(&self, target: f64) -> f64 {
        match (&self.table, self.correction) {
            (Some(t), true) => fixed_point(|raw| target + t.error_at(raw, self.direction), target),
            _ => target,
        }
    }

    /// The true angle at which the encoder reads `raw` (with the rest noise).
    fn actual_for_raw(&self, raw: f64, runs: f64) -> f64 {
        let n = self.noise_deg;
        fixed_point(|a| raw - n - self.error_at(a, runs), raw - n)
    }

    fn fault_active(&self, now: Duration) -> Option<&DeviceFault> {
        self.fault.as_ref().filter(|f| f.since <= now).map(|f| &f.fault)
    }

    /// Halt the axis where it is at `now` (stop, or a trip that happens now).
    fn halt(&mut self, now: Duration, tripped: bool) {
        // A trip is planned when its move starts (along the move's plain
        // path); a stop finds the axis where the turntable has it.
        let actual = if tripped { self.axis.value(now) } else { self.turntable.actual_deg(now) };
        self.response = None;
        let raw = actual + self.error_at(actual, self.runs_at(now)) + self.noise_deg;
        self.raw_rest = raw;
        let shown = self.displayed_of_raw(raw);
        self.display = AxisPath { halt_at: now, rest: shown, ..self.display };
        self.axis = AxisPath { halt_at: now, rest: actual, ..self.axis };
        self.turntable.set_path(self.axis);
        self.settle_until = now + self.cfg.settle;
        self.on_target = !tripped;
    }

    /// A fault that is due later in the current move happens now instead (a
    /// new command interrupts the move).
    fn trip_pending_fault_now(&mut self, now: Duration) {
        if let Some(f) = &mut self.fault
            && f.since > now
        {
            f.since = now;
            self.halt(now, true);
        }
    }

    /// Pay the link latency, after injecting a link fault if one is due.
    async fn link(&mut self, what: &str) -> Result<()> {
        self.calls += 1;
        let f = &self.cfg.faults;
        let n = Some(self.calls);
        // Always three draws per call, so the fault stream stays aligned.
        let (d, t, g): (f64, f64, f64) = (self.fault_rng.random(), self.fault_rng.random(), self.fault_rng.random());
        if f.disconnect_on_call == n || d < f.disconnect_probability_per_call {
            self.injected(FaultKind::Disconnect);
            return Err(DriverError::new(
                ErrorKind::Disconnected,
                INSTRUMENT,
                format!("connection reset during {what} (simulated)"),
            ));
        }
        if f.timeout_on_call == n || t < f.timeout_probability_per_call {
            self.injected(FaultKind::Timeout);
            self.clock.sleep(INJECTED_TIMEOUT).await;
            return Err(DriverError::timeout(INSTRUMENT, what, INJECTED_TIMEOUT));
        }
        self.clock.sleep(self.cfg.link_latency).await;
        if g < f.garbled_probability_per_call {
            self.injected(FaultKind::Garbled);
            return Err(DriverError::new(
                ErrorKind::Garbled,
                INSTRUMENT,
                format!("bad checksum in the reply to {what} (simulated)"),
            ));
        }
        Ok(())
    }

    fn check_target(&self, target_deg: f64) -> Result<()> {
        if !target_deg.is_finite() {
            return Err(DriverError::usage(INSTRUMENT, format!("target {target_deg} deg is not a finite angle")));
        }
        if let Some((lo, hi)) = self.cfg.travel
            && !(lo..=hi).contains(&target_deg)
        {
            return Err(DriverError::usage(
                INSTRUMENT,
                format!("target {target_deg} deg is outside the travel {lo}..{hi} deg"),
            ));
        }
        Ok(())
    }

    /// Start a move to `target` at `now` (all checks done).
    fn start_move(&mut self, now: Duration, target: f64) {
        self.moves += 1;
        self.capture_until(now);
        let from_display = self.display_at(now);
        let from_actual = self.turntable.actual_deg(now);
        if target > from_display {
            self.direction = Direction::Forward;
        } else if target < from_display {
            self.direction = Direction::Reverse;
        }
        let profile = Profile::new(now, target - from_display, self.velocity_deg_s, self.cfg.accel_deg_s2);
        let end = profile.end();
        let z: f64 = StandardNormal.sample(&mut self.noise_rng);
        self.noise_deg = z * self.cfg.model.noise_sigma_deg();
        let raw = self.raw_for_display(target);
        let actual = self.actual_for_raw(raw, self.runs_at(end));
        let faults = &self.cfg.faults;
        let draw: f64 = self.fault_rng.random();
        let trips = faults.fault_on_move == Some(self.moves) || draw < faults.fault_probability_per_move;
        self.display = AxisPath { profile, halt_at: end, from: from_display, to: target, rest: target };
        self.axis = AxisPath { profile, halt_at: end, from: from_actual, to: actual, rest: actual };
        self.raw_rest = raw;
        self.settle_until = end + self.cfg.settle;
        self.on_target = true;
        if trips {
            self.injected(FaultKind::Move);
            let at = profile.start + Duration::from_secs_f64(profile.duration_s / 2.0);
            self.halt(at, true);
            self.fault = Some(Latched {
                since: at,
                fault: DeviceFault {
                    code: FAULT_FOLLOWING_ERROR,
                    text: format!("following error: drive disabled during the move to {target} deg (simulated)"),
                },
            });
            tracing::debug!(target, ?at, "simulated positioner trips");
            self.turntable.set_path(self.axis);
        } else {
            self.follow_move(profile, target, actual);
        }
    }

    /// Recompute the displayed readout at rest after the table or its use changed.
    fn refresh_display(&mut self, now: Duration) {
        debug_assert!(!self.display.is_moving(now));
        let shown = self.displayed_of_raw(self.raw_rest);
        self.display = AxisPath::at_rest(shown, self.display.halt_at);
    }
}

#[async_trait]
impl Positioner for SimPositioner {
    fn name(&self) -> &str {
        self.name
    }

    async fn move_to(&mut self, target_deg: f64) -> Result<()> {
        self.link("move_to").await?;
        let now = self.clock.now();
        self.trip_pending_fault_now(now);
        if let Some(f) = self.fault_active(now) {
            return Err(DriverError::device(INSTRUMENT, f.code, format!("{} (clear the fault first)", f.text)));
        }
        self.check_target(target_deg)?;
        self.start_move(now, target_deg);
        Ok(())
    }

    async fn readout(&mut self) -> Result<f64> {
        self.link("readout").await?;
        Ok(self.display_at(self.clock.now()))
    }

    async fn status(&mut self) -> Result<PositionerStatus> {
        self.link("status").await?;
        let now = self.clock.now();
        let fault = self.fault_active(now).cloned();
        let moving = self.display.is_moving(now);
        let shown = self.display.value(now);
        let limit = self.cfg.travel.and_then(|(lo, hi)| {
            if shown <= lo + LIMIT_TOLERANCE_DEG {
                Some(Limit::Lower)
            } else if shown >= hi - LIMIT_TOLERANCE_DEG {
                Some(Limit::Upper)
            } else {
                None
            }
        });
        Ok(PositionerStatus {
            moving,
            in_position: !moving && fault.is_none() && self.on_target && now >= self.settle_until,
            fault,
            limit,
            correction_enabled: self.correction,
        })
    }

    async fn stop(&mut self) -> Result<()> {
        self.link("stop").await?;
        let now = self.clock.now();
        if self.fault.as_ref().is_some_and(|f| f.since > now) {
            self.trip_pending_fault_now(now);
        } else if self.display.is_moving(now) {
            self.halt(now, false);
        }
        Ok(())
    }

    async fn set_velocity(&mut self, deg_per_s: f64) -> Result<()> {
        self.link("set_velocity").await?;
        if !(deg_per_s.is_finite() && deg_per_s > 0.0) {
            return Err(DriverError::usage(
                INSTRUMENT,
                format!("velocity {deg_per_s} deg/s is not a positive finite number"),
            ));
        }
        self.velocity_deg_s = deg_per_s;
        Ok(())
    }

    async fn clear_fault(&mut self) -> Result<()> {
        self.link("clear_fault").await?;
        let now = self.clock.now();
        if self.fault_active(now).is_some() {
            self.fault = None;
        }
        Ok(())
    }

    async fn load_correction_table(&mut self, table: &CorrectionTable) -> Result<()> {
        self.link("load_correction_table").await?;
        let now = self.clock.now();
        if self.display.is_moving(now) {
            return Err(DriverError::usage(INSTRUMENT, "cannot load a correction table while the axis is moving"));
        }
        self.table = Some(Arc::new(table.clone()));
        self.refresh_display(now);
        Ok(())
    }

    async fn enable_correction(&mut self, enabled: bool) -> Result<()> {
        self.link("enable_correction").await?;
        let now = self.clock.now();
        if self.display.is_moving(now) {
            return Err(DriverError::usage(INSTRUMENT, "cannot switch the correction while the axis is moving"));
        }
        if enabled && self.table.is_none() {
            return Err(DriverError::usage(INSTRUMENT, "no correction table loaded"));
        }
        self.correction = enabled;
        self.refresh_display(now);
        Ok(())
    }

    async fn correction_state(&mut self) -> Result<Option<bool>> {
        self.link("correction_state").await?;
        Ok(Some(self.correction))
    }

    fn can_capture(&self) -> bool {
        true
    }

    async fn start_capture(&mut self, period: Duration) -> Result<()> {
        self.link("start_capture").await?;
        self.begin_capture(period)
    }

    async fn read_capture(&mut self) -> Result<Vec<CapturedReadout>> {
        self.link("read_capture").await?;
        self.take_capture()
    }

    async fn stop_capture(&mut self) -> Result<()> {
        self.link("stop_capture").await?;
        self.capture = None;
        Ok(())
    }
}

mod capture;
mod motion;
#[cfg(test)]
mod tests;
