//! A simulated tracking laser measuring an SMR on an arm fixed to the turntable.
//!
//! # Geometry ([`ArmGeometry`])
//!
//! The tracker sits at the origin of its frame (mm). The axis passes through
//! `axis_center_mm` along the unit vector `axis_normal`. With `u`, `v` an
//! orthonormal basis of the plane perpendicular to the normal (`u` is the
//! tracker's x axis projected into that plane, `v = normal × u`, so
//! `u × v = normal`), the SMR at true axis angle `theta` is at
//!
//! `centre + smr_height*normal + radius*(cos(theta+phase) u + sin(theta+phase) v)`.
//!
//! Increasing axis angle is a right-handed rotation about `axis_normal`.
//! The tracker does not measure an angle: the engine fits a plane and a circle
//! to the SMR positions and takes each angle around the circle's centre (the
//! arm's phase is a constant offset).
//!
//! # The tracker's own error
//!
//! A real tracker's error is mostly systematic: the geometric error model of
//! laser trackers (encoder eccentricity and harmonics of both axes, transit,
//! beam and range offsets, tilts; `survey_processing::tracker_errors`, from
//! Muralikrishnan et al., J. Res. NIST 114 (2009) 21-35), which repeats at
//! the same place in space on every reading and does not average away, and
//! a small random part on each angle and the range. [`TrackerConfig::errors`]
//! states it (`[tracker_errors]` of a model file); by default an AT-class
//! tracker's typical error, the bench's own tracker's whatever the survey's
//! seed ([`typical_errors`] of [`BENCH_TRACKER`]: each
//! parameter a normal of the size the AT-class specification allows, the
//! draw kept only when the tracker would pass its acceptance test, its
//! transverse error within 0.8 of the MPE over the arm's circle). About
//! 3e-4 deg of systematic error on a 1 m arm 2.7 m away, and 2e-4 deg of
//! random error a reading; `std_dev_mm` reports the random part.
//!
//! # Timing and faults
//!
//! `measure()` takes `measurement_time` of clock time and measures the SMR at
//! the mean true angle over that time (a stationary measurement integrates:
//! an axis still ringing when it starts is seen at its average position), and
//! reports as its standard deviation the instrument's sigma combined with the
//! spread of the SMR's positions over the measurement (a moving SMR shows as a
//! larger deviation). A continuous measurement ([`Tracker::start_stream`]) is
//! described in [`stream`]. With `beam_break_probability` per
//! measurement (or on the scheduled measurement `break_on_measurement`,
//! 1-based) the beam breaks: that measurement fails with the device code
//! [`CODE_BEAM_BROKEN`], the state becomes `BeamBroken` and every measurement
//! fails at once with that code until `reacquire()` (which takes
//! `reacquire_time`). `status()` and a locked `reacquire()` cost the link latency.
//! A broken beam stays blocked for `beam_hold` after the break (someone
//! standing in it): a `reacquire()` before then searches for `reacquire_time`
//! and fails with [`CODE_BEAM_BROKEN`], the beam still broken. Each break is
//! counted by the [`Injected`] handle given with [`SimTracker::count_injected`].

use crate::faults::{FaultKind, Injected};
use crate::turntable::Turntable;
use crate::{FAULT_STREAM, LINK_LATENCY, NOISE_STREAM, seeded_rng};
use async_trait::async_trait;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::clock::Clock;
use survey_drivers::error::{DriverError, Result};
use survey_drivers::traits::{SmrMeasurement, StreamedPoint, Tracker, TrackerState};
use survey_processing::model::{AxisMotions, SmrPlace};
pub use survey_processing::smrs::SmrMount;
use survey_processing::tracker_errors::{
    EncoderHarmonic, TYPICAL_ANGLE_NOISE_URAD, TrackerErrorSpec, TrackerErrors, transverse_mpe_um,
};

const INSTRUMENT: &str = "tracker";

/// Device code of a measurement that failed because the beam is broken (the
/// simulator's own code in the style of emScon's `ES_ResultStatus`, whose TPI
/// reports a lost beam as an error answer with no dedicated status value).
pub const CODE_BEAM_BROKEN: i64 = 9001;

/// The arm on the turntable and where the axis is in the tracker's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmGeometry {
    /// Radius of the SMR's circle, mm (default 1000).
    pub radius_mm: f64,
    /// A point on the axis, mm, tracker frame (default `[2500, 800, -300]`).
    pub axis_center_mm: [f64; 3],
    /// Direction of the axis (normalised on use; default tilted 0.3 deg from +z).
    pub axis_normal: [f64; 3],
    /// Angle of the arm at axis angle 0, deg (default 37).
    pub arm_phase_deg: f64,
    /// Height of the SMR above `axis_center_mm` along the normal, mm (default 50).
    pub smr_height_mm: f64,
    /// The SMRs on the table (default one, at the arm's phase and height):
    /// each at its own phase and height from SMR 0's, on the same radius.
    pub smrs: Vec<SmrMount>,
}

impl Default for ArmGeometry {
    fn default() -> Self {
        let tilt = 0.3f64.to_radians();
        let toward = 30f64.to_radians();
        Self {
            radius_mm: 1000.0,
            axis_center_mm: [2500.0, 800.0, -300.0],
            axis_normal: [tilt.sin() * toward.cos(), tilt.sin() * toward.sin(), tilt.cos()],
            arm_phase_deg: 37.0,
            smr_height_mm: 50.0,
            smrs: vec![SmrMount::FIRST],
        }
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn scaled(a: [f64; 3], k: f64) -> [f64; 3] {
    a.map(|x| x * k)
}

fn normalised(a: [f64; 3]) -> [f64; 3] {
    scaled(a, 1.0 / dot(a, a).sqrt())
}

impl ArmGeometry {
    /// The orthonormal frame `(u, v, normal)` of the axis, `u × v = normal`.
    pub fn basis(&self) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let n = normalised(self.axis_normal);
        // Project the tracker's x axis into the plane (y if x is nearly the normal).
        let seed = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
        let u = normalised(std::array::from_fn(|i| seed[i] - dot(seed, n) * n[i]));
        let v = cross(n, u);
        (u, v, n)
    }

    /// The centre of the SMR's circle, mm.
    pub fn circle_center_mm(&self) -> [f64; 3] {
        let (_, _, n) = self.basis();
        std::array::from_fn(|i| self.axis_center_mm[i] + self.smr_height_mm * n[i])
    }

    /// The (first) SMR's position at true axis angle `theta_deg`, mm, tracker frame.
    pub fn smr_position_mm(&self, theta_deg: f64) -> [f64; 3] {
        self.smr_position_of(0, theta_deg)
    }

    /// SMR `k`'s position at true axis angle `theta_deg`, mm, tracker frame
    /// (the first one's for an SMR the arm does not have).
    pub fn smr_position_of(&self, k: usize, theta_deg: f64) -> [f64; 3] {
        let mount = self.smrs.get(k).copied().unwrap_or(SmrMount::FIRST);
        let (u, v, n) = self.basis();
        let c = self.circle_center_mm();
        let phi = (theta_deg + self.arm_phase_deg + mount.phase_deg).to_radians();
        let (s, k) = phi.sin_cos();
        std::array::from_fn(|i| c[i] + mount.height_mm * n[i] + self.radius_mm * (k * u[i] + s * v[i]))
    }
}

impl ArmGeometry {
    /// `p`, SMR `k`'s position at true axis angle `theta_deg`, moved by the
    /// axis's error motions (`survey_processing::model::AxisMotions`: the
    /// table tilts about `axis_center_mm`) and by `jitter_um`, the bearing's
    /// asynchronous displacement along `u`, `v` and the normal.
    pub fn moved_by(
        &self,
        k: usize,
        theta_deg: f64,
        p: [f64; 3],
        motions: &AxisMotions,
        jitter_um: [f64; 3],
    ) -> [f64; 3] {
        let mount = self.smrs.get(k).copied().unwrap_or(SmrMount::FIRST);
        let place = SmrPlace {
            phase_deg: mount.phase_deg,
            radius_mm: self.radius_mm,
            height_mm: self.smr_height_mm + mount.height_mm,
        };
        let [radial, along, axial] = motions.displacement_um(theta_deg, place);
        let (u, v, n) = self.basis();
        let (s, c) = (theta_deg + self.arm_phase_deg + mount.phase_deg).to_radians().sin_cos();
        std::array::from_fn(|i| {
            let outward = c * u[i] + s * v[i];
            let forward = -s * u[i] + c * v[i];
            let um = radial * outward
                + along * forward
                + axial * n[i]
                + jitter_um[0] * u[i]
                + jitter_um[1] * v[i]
                + jitter_um[2] * n[i];
            p[i] + um * 1e-3
        })
    }
}

/// The typical tracker's random standard deviation per coordinate at
/// `distance_mm` from it, mm: the transverse part of one reading
/// ([`TYPICAL_ANGLE_NOISE_URAD`] at that range), the larger of the two.
pub fn sigma_mm(distance_mm: f64) -> f64 {
    (distance_mm * TYPICAL_ANGLE_NOISE_URAD * 1e-6)
        .max(survey_processing::tracker_errors::TYPICAL_RANGE_NOISE_UM * 1e-3)
}

/// Seed stream of the tracker's drawn error set.
const ERRORS_STREAM: u64 = 5;
/// Seed stream of the bearing noise.
const BEARING_STREAM: u64 = 6;

/// The seed of the simulated bench's own tracker's error set (its serial
/// number, as it were): one instrument, the same on every survey of the
/// bench, as a laboratory's tracker is, whatever the survey's seed (which
/// draws its noise). [`typical_errors`] of another seed is another tracker.
pub const BENCH_TRACKER: u64 = 7788;

/// An AT-class tracker's typical error set, drawn from `seed`: every
/// parameter of the geometric model a zero-mean normal (offsets 5 um, range
/// scale 0.3 ppm, tilts 2 urad, the azimuth encoder's orders 1 to 4 at 1.5,
/// 1.5, 0.7 and 0.5 urad a component, the elevation encoder's orders 1 and 2
/// at 1.2 urad), sizes that make the systematic transverse error about half
/// the MPE at a few metres (a draw whose transverse error at any position of
/// `arm`'s circle exceeds 0.8 of the MPE is drawn again: a tracker that
/// would not pass its acceptance test is not on the bench). Our own choice
/// of sizes within the public model and specification.
pub fn typical_errors(seed: u64, arm: &ArmGeometry) -> TrackerErrors {
    let mut rng = crate::seeded_rng(seed, ERRORS_STREAM);
    let mut best: Option<(f64, TrackerErrors)> = None;
    for _ in 0..32 {
        let mut normal =
            |sd: f64| -> f64 { sd * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng) };
        let harmonic = |order: u32, sd: f64, normal: &mut dyn FnMut(f64) -> f64| {
            let (a, b) = (normal(sd), normal(sd));
            EncoderHarmonic { order, amplitude_urad: a.hypot(b), phase_deg: a.atan2(b).to_degrees() }
        };
        let azimuth = [(1, 1.5), (2, 1.5), (3, 0.7), (4, 0.5)].map(|(k, sd)| harmonic(k, sd, &mut normal)).to_vec();
        let elevation = [(1, 1.2), (2, 1.2)].map(|(k, sd)| harmonic(k, sd, &mut normal)).to_vec();
        let e = TrackerErrors {
            azimuth,
            elevation,
            transit_offset_um: normal(5.0),
            beam_offset_um: normal(5.0),
            beam_offset_normal_um: normal(5.0),
            range_offset_um: normal(5.0),
            range_scale_ppm: normal(0.3),
            vertical_index_urad: normal(2.0),
            beam_tilt_urad: normal(2.0),
            transit_tilt_urad: normal(2.0),
            ..TrackerErrors::ideal()
        };
        let worst = (0..72)
            .map(|i| {
                let p = arm.smr_position_mm(5.0 * i as f64);
                let m = e.measured(p, [0.0; 3]);
                let d = dot(p, p).sqrt();
                // The transverse part: the displacement less its component along the line of sight.
                let delta: [f64; 3] = std::array::from_fn(|k| m[k] - p[k]);
                let along = dot(delta, p) / d;
                let transverse = (dot(delta, delta) - along * along).max(0.0).sqrt();
                transverse * 1000.0 / transverse_mpe_um(d)
            })
            .fold(0.0, f64::max);
        if worst <= 0.8 {
            return e;
        }
        if best.as_ref().is_none_or(|(w, _)| worst < *w) {
            best = Some((worst, e));
        }
    }
    best.map(|(_, e)| e).unwrap_or_default()
}

/// Configuration of a [`SimTracker`].
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Where the SMR is (default [`ArmGeometry::default`]).
    pub arm: ArmGeometry,
    /// Duration of a stationary measurement (default 1 s).
    pub measurement_time: Duration,
    /// Probability that a measurement breaks the beam (default 0).
    pub beam_break_probability: f64,
    /// Time to find the SMR again after a break (default 5 s).
    pub reacquire_time: Duration,
    /// How long the beam stays blocked after a break (default 0: it can be
    /// re-acquired at once).
    pub beam_hold: Duration,
    /// Seed of the noise and beam-break streams.
    pub seed: u64,
    /// Break the beam on this measurement (1-based), for tests.
    pub break_on_measurement: Option<usize>,
    /// Multiplies the noise (1 = the instrument's; 0 = exact positions, for
    /// tests). The reported `std_dev_mm` is always the instrument's sigma.
    pub noise_scale: f64,
    /// The continuous measurement's clock, latency and losses.
    pub stream: stream::StreamSim,
    /// The tracker's own error (default: an AT-class tracker's typical,
    /// the bench's own, [`typical_errors`] of [`BENCH_TRACKER`]).
    pub errors: TrackerErrorSpec,
    /// Pointing at a position ([`SimTracker::go_position`]): the beam turns
    /// at this rate, degrees per second (default 180: an AT-class tracker's
    /// angular speed), after the link latency.
    pub slew_deg_s: f64,
    /// A search for a reflector ([`SimTracker::find_reflector`]) takes this
    /// long (default 500 ms) and finds an SMR within `capture_mm` of where
    /// the beam points (default 25 mm: the search radius our model gives the
    /// tracker; our own choice, an emScon server's `SetSearchParams` sets a
    /// real one's).
    pub find_time: Duration,
    /// See `find_time`.
    pub capture_mm: f64,
    /// The axis's error motions (the model file's `radial_motion`,
    /// `axial_motion`, `tilt_motion`, `bearing_noise`): they move the SMRs,
    /// and the tracker reads them where they truly are.
    pub motions: AxisMotions,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            arm: ArmGeometry::default(),
            measurement_time: Duration::from_secs(1),
            beam_break_probability: 0.0,
            reacquire_time: Duration::from_secs(5),
            beam_hold: Duration::ZERO,
            seed: 0,
            break_on_measurement: None,
            noise_scale: 1.0,
            stream: stream::StreamSim::default(),
            errors: TrackerErrorSpec::Typical,
            slew_deg_s: 180.0,
            find_time: Duration::from_millis(500),
            capture_mm: 25.0,
            motions: AxisMotions::default(),
        }
    }
}

/// The simulated tracking laser. See the module documentation.
#[derive(Debug)]
pub struct SimTracker {
    clock: Arc<dyn Clock>,
    cfg: TrackerConfig,
    turntable: Turntable,
    state: TrackerState,
    measurements: usize,
    noise_rng: ChaCha8Rng,
    fault_rng: ChaCha8Rng,
    /// The continuous measurement, while it runs.
    streaming: Option<stream::Streaming>,
    /// The beam cannot be re-acquired before this clock time.
    blocked_until: Duration,
    injected: Option<Injected>,
    /// The error set in use (the configuration's, or drawn).
    errors: TrackerErrors,
    /// The SMR the beam is on (or was on, when it broke).
    target: usize,
    /// Draws the bearing noise (the axis's asynchronous error motion).
    bearing_rng: ChaCha8Rng,
    /// Where the beam points since a [`SimTracker::go_position`], until a
    /// reflector is found there.
    aim: Option<[f64; 3]>,
}

impl SimTracker {
    /// A tracker looking at the SMR on `turntable`'s arm.
    pub fn new(cfg: TrackerConfig, clock: Arc<dyn Clock>, turntable: Turntable) -> Self {
        let errors = match &cfg.errors {
            TrackerErrorSpec::Typical => typical_errors(BENCH_TRACKER, &cfg.arm),
            TrackerErrorSpec::None => TrackerErrors::ideal(),
            TrackerErrorSpec::Given(e) => e.clone(),
        };
        Self {
            errors,
            target: 0,
            aim: None,
            noise_rng: seeded_rng(cfg.seed, NOISE_STREAM),
            bearing_rng: seeded_rng(cfg.seed, BEARING_STREAM),
            fault_rng: seeded_rng(cfg.seed, FAULT_STREAM),
            clock,
            cfg,
            turntable,
            state: TrackerState::TargetLocked,
            measurements: 0,
            streaming: None,
            blocked_until: Duration::ZERO,
            injected: None,
        }
    }

    /// Count every beam break in `injected`.
    pub fn count_injected(&mut self, injected: Injected) {
        self.injected = Some(injected);
    }

    /// The configuration (the designed geometry, for tests).
    pub fn config(&self) -> &TrackerConfig {
        &self.cfg
    }

    /// Whether the tracker runs on a virtual clock (a server pushing its
    /// streamed points on a timer must not on one).
    pub fn clock_is_virtual(&self) -> bool {
        self.clock.is_virtual()
    }

    /// The tracker's own error in use (the truth the processing does not know).
    pub fn errors(&self) -> &TrackerErrors {
        &self.errors
    }

    /// Where this tracker reads the SMR it is locked on at true axis angle
    /// `theta_deg`, with the random part's standard normals `z` (scaled by
    /// `noise_scale`).
    fn read_at(&mut self, theta_deg: f64, z: [f64; 3]) -> [f64; 3] {
        let mut p = self.cfg.arm.smr_position_of(self.target, theta_deg);
        if !self.cfg.motions.is_none() {
            let sigma = self.cfg.motions.bearing_sigma_um;
            let mut draw = || {
                if sigma > 0.0 {
                    sigma * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut self.bearing_rng)
                } else {
                    0.0
                }
            };
            let jitter = [draw(), draw(), draw()];
            p = self.cfg.arm.moved_by(self.target, theta_deg, p, &self.cfg.motions, jitter);
        }
        self.errors.measured(p, z.map(|v| v * self.cfg.noise_scale))
    }

    /// The SMR the beam is locked on (0-based, the arm's order).
    pub fn target(&self) -> usize {
        self.target
    }

    /// Turn the beam to `xyz_mm` (the tracker's frame, as it reads it):
    /// emScon's `GoPosition`. The beam leaves the SMR it was on; the time
    /// is the link latency and the turn at `slew_deg_s`.
    pub async fn go_position(&mut self, xyz_mm: [f64; 3]) -> Result<()> {
        if self.streaming.is_some() {
            self.clock.sleep(LINK_LATENCY).await;
            return Err(DriverError::usage(INSTRUMENT, "measuring continuously: stop the stream first"));
        }
        if !xyz_mm.iter().all(|v| v.is_finite()) || dot(xyz_mm, xyz_mm) == 0.0 {
            self.clock.sleep(LINK_LATENCY).await;
            return Err(DriverError::usage(INSTRUMENT, format!("cannot point at {xyz_mm:?}")));
        }
        let theta = self.turntable.actual_deg(self.clock.now());
        let from = self.aim.unwrap_or_else(|| self.cfg.arm.smr_position_of(self.target, theta));
        let cos = dot(from, xyz_mm) / (dot(from, from) * dot(xyz_mm, xyz_mm)).sqrt();
        let turn_deg = cos.clamp(-1.0, 1.0).acos().to_degrees();
        self.clock.sleep(LINK_LATENCY + Duration::from_secs_f64(turn_deg / self.cfg.slew_deg_s.max(1e-6))).await;
        self.aim = Some(xyz_mm);
        if self.state == TrackerState::TargetLocked {
            self.state = TrackerState::BeamBroken;
        }
        Ok(())
    }

    /// Search for a reflector where the beam points (emScon's
    /// `FindReflector`): the SMR nearest the aim within `capture_mm` (its
    /// true position at the axis's true angle), locked after `find_time`;
    /// none there (or the beam still blocked) is a device fault with
    /// [`CODE_BEAM_BROKEN`]. Without an aim, the SMR the beam was on.
    pub async fn find_reflector(&mut self) -> Result<()> {
        let Some(aim) = self.aim else { return self.reacquire().await };
        self.clock.sleep(self.cfg.find_time).await;
        if self.clock.now() < self.blocked_until {
            return Err(DriverError::device(INSTRUMENT, CODE_BEAM_BROKEN, "no reflector found: the beam is blocked"));
        }
        let theta = self.turntable.actual_deg(self.clock.now());
        let nearest = (0..self.cfg.arm.smrs.len().max(1))
            .map(|k| {
                let p = self.cfg.arm.smr_position_of(k, theta);
                let d: [f64; 3] = std::array::from_fn(|i| p[i] - aim[i]);
                (k, dot(d, d).sqrt())
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match nearest {
            Some((k, d)) if d <= self.cfg.capture_mm => {
                self.target = k;
                self.aim = None;
                self.state = TrackerState::TargetLocked;
                Ok(())
            }
            _ => Err(DriverError::device(
                INSTRUMENT,
                CODE_BEAM_BROKEN,
                format!(
                    "no reflector found within {} mm of ({:.1}, {:.1}, {:.1}) mm",
                    self.cfg.capture_mm, aim[0], aim[1], aim[2]
                ),
            )),
        }
    }

    /// Measurements attempted so far (broken ones included).
    pub fn measurements(&self) -> usize {
        self.measurements
    }

    fn broken(&self) -> DriverError {
        DriverError::device(INSTRUMENT, CODE_BEAM_BROKEN, "beam broken: the SMR is not locked (reacquire it)")
    }
}

#[async_trait]
impl Tracker for SimTracker {
    fn name(&self) -> &str {
        "sim-tracker"
    }

    async fn measure(&mut self) -> Result<SmrMeasurement> {
        if self.state != TrackerState::TargetLocked {
            self.clock.sleep(LINK_LATENCY).await;
            return Err(self.broken());
        }
        if self.streaming.is_some() {
            self.clock.sleep(LINK_LATENCY).await;
            return Err(DriverError::usage(INSTRUMENT, "measuring continuously: stop the stream first"));
        }
        self.measurements += 1;
        let t0 = self.clock.now();
        let draw: f64 = self.fault_rng.random();
        let breaks = self.cfg.break_on_measurement == Some(self.measurements) || draw < self.cfg.beam_break_probability;
        self.clock.sleep(self.cfg.measurement_time).await;
        let t1 = t0 + self.cfg.measurement_time;
        let (theta, spread_deg) = self.turntable.mean_and_spread_deg(t0, t1);
        if breaks {
            self.state = TrackerState::BeamBroken;
            self.blocked_until = self.clock.now() + self.cfg.beam_hold;
            if let Some(i) = &self.injected {
                i.add(FaultKind::Beam);
            }
            tracing::debug!(measurement = self.measurements, "simulated tracker beam break");
            return Err(DriverError::device(
                INSTRUMENT,
                CODE_BEAM_BROKEN,
                "beam broken during the measurement (reacquire the SMR)",
            ));
        }
        let sigma = self.errors.random_sd_mm(self.cfg.arm.smr_position_mm(theta));
        // The SMR's rms distance from its mean position during the measurement.
        let spread = self.cfg.arm.radius_mm * spread_deg.to_radians();
        let reported = (sigma * sigma + spread * spread).sqrt();
        let z: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut self.noise_rng));
        let noisy = self.read_at(theta, z);
        Ok(SmrMeasurement {
            x_mm: noisy[0],
            y_mm: noisy[1],
            z_mm: noisy[2],
            std_dev_mm: [reported; 3],
            measurement_time_s: self.cfg.measurement_time.as_secs_f64(),
            // The room when the measurement ends ([`crate::room`], our own model).
            environment: Some(crate::room::air_at(self.clock.now().as_secs_f64())),
        })
    }

    async fn status(&mut self) -> Result<TrackerState> {
        self.clock.sleep(LINK_LATENCY).await;
        Ok(self.state)
    }

    async fn reacquire(&mut self) -> Result<()> {
        self.aim = None;
        if self.state == TrackerState::TargetLocked {
            self.clock.sleep(LINK_LATENCY).await;
            return Ok(());
        }
        self.clock.sleep(self.cfg.reacquire_time).await;
        if self.clock.now() < self.blocked_until {
            return Err(DriverError::device(
                INSTRUMENT,
                CODE_BEAM_BROKEN,
                "no reflector found: the beam is still blocked (simulated)",
            ));
        }
        self.state = TrackerState::TargetLocked;
        Ok(())
    }

    async fn point_at(&mut self, xyz_mm: [f64; 3]) -> Result<()> {
        self.go_position(xyz_mm).await?;
        self.find_reflector().await
    }

    fn can_point(&self) -> bool {
        true
    }

    fn can_stream(&self) -> bool {
        true
    }

    async fn start_stream(&mut self, period: Duration) -> Result<()> {
        self.clock.sleep(LINK_LATENCY).await;
        if self.state != TrackerState::TargetLocked {
            return Err(self.broken());
        }
        self.begin_stream(period)
    }

    async fn read_stream(&mut self) -> Result<Vec<StreamedPoint>> {
        self.clock.sleep(LINK_LATENCY).await;
        self.take_stream()
    }

    async fn stop_stream(&mut self) -> Result<()> {
        self.clock.sleep(LINK_LATENCY).await;
        self.streaming = None;
        Ok(())
    }
}

pub mod stream;
#[cfg(test)]
mod tests;
