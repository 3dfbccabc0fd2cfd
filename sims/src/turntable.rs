//! The shared truth: the true axis angle as a function of time.
//!
//! The [`SimPositioner`](crate::SimPositioner) writes a path into the
//! [`Turntable`] whenever a move starts or ends early; the tracker and the
//! autocollimator read [`Turntable::actual_deg`] at the clock time of their
//! measurement. Nothing runs in the background: the angle at time `t` is
//! evaluated from the stored path.
//!
//! A move follows a trapezoidal velocity profile (or a triangular one when the
//! move is too short to reach the velocity): constant acceleration `a` up to
//! velocity `v`, cruise, constant deceleration. Its duration is `d/v + v/a`
//! when `d >= v^2/a`, else `2*sqrt(d/a)`.

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// A trapezoidal (or triangular) velocity profile over a distance, starting at
/// a clock time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// Clock time the move starts.
    pub start: Duration,
    /// Length of the move, degrees (non-negative).
    pub distance_deg: f64,
    /// Cruise velocity, degrees per second.
    pub velocity_deg_s: f64,
    /// Acceleration and deceleration, degrees per second squared.
    pub accel_deg_s2: f64,
    /// Duration of the whole profile, seconds.
    pub duration_s: f64,
}

impl Profile {
    /// The profile of a move of `distance_deg` (its sign is ignored) starting at
    /// `start`. `velocity` and `accel` must be positive.
    pub fn new(start: Duration, distance_deg: f64, velocity_deg_s: f64, accel_deg_s2: f64) -> Self {
        let d = distance_deg.abs();
        let (v, a) = (velocity_deg_s, accel_deg_s2);
        let duration_s = if d == 0.0 {
            0.0
        } else if d >= v * v / a {
            d / v + v / a
        } else {
            2.0 * (d / a).sqrt()
        };
        Self { start, distance_deg: d, velocity_deg_s: v, accel_deg_s2: a, duration_s }
    }

    /// A profile of no motion at `start`.
    pub fn still(start: Duration) -> Self {
        Self::new(start, 0.0, 1.0, 1.0)
    }

    /// The clock time the profile ends.
    pub fn end(&self) -> Duration {
        self.start + Duration::from_secs_f64(self.duration_s)
    }

    /// The fraction of the distance covered at clock time `now`, 0 to 1.
    pub fn fraction(&self, now: Duration) -> f64 {
        if self.distance_deg == 0.0 || self.duration_s == 0.0 {
            return 1.0;
        }
        // `end()` rounds the duration to whole nanoseconds: from then on the
        // move is complete, whatever the rounding left of `duration_s`.
        if now >= self.end() {
            return 1.0;
        }
        let total = self.duration_s;
        let t = now.saturating_sub(self.start).as_secs_f64().min(total);
        let a = self.accel_deg_s2;
        let ramp = (self.velocity_deg_s / a).min(total / 2.0);
        let peak = a * ramp;
        let covered = if t < ramp {
            0.5 * a * t * t
        } else if t < total - ramp {
            0.5 * a * ramp * ramp + peak * (t - ramp)
        } else {
            let left = total - t;
            self.distance_deg - 0.5 * a * left * left
        };
        (covered / self.distance_deg).clamp(0.0, 1.0)
    }
}

/// A quantity (an angle) that moves from `from` toward `to` along a profile and
/// comes to rest at `rest` at time `halt_at`: at the profile's end for a
/// completed move, earlier for a move that was stopped or tripped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisPath {
    /// The profile the quantity follows until `halt_at`.
    pub profile: Profile,
    /// When the quantity stops moving (and takes the value `rest`).
    pub halt_at: Duration,
    /// The value at the profile's start.
    pub from: f64,
    /// The value at the profile's end (if it is not halted before).
    pub to: f64,
    /// The value from `halt_at` on.
    pub rest: f64,
}

impl AxisPath {
    /// A quantity at rest at `value` since `since`.
    pub fn at_rest(value: f64, since: Duration) -> Self {
        Self { profile: Profile::still(since), halt_at: since, from: value, to: value, rest: value }
    }

    /// The value at clock time `now`.
    pub fn value(&self, now: Duration) -> f64 {
        if now >= self.halt_at {
            self.rest
        } else {
            let s = self.profile.fraction(now);
            self.from + (self.to - self.from) * s
        }
    }

    /// Whether the quantity is still moving at `now`.
    pub fn is_moving(&self, now: Duration) -> bool {
        now < self.halt_at
    }
}

/// A true axis angle over time that is not a plain [`AxisPath`]: the
/// positioner installs one for each move (the servo's motion, the angle that
/// makes the encoder read the displayed readout).
pub trait TruthPath: Send + Sync + std::fmt::Debug {
    /// The true axis angle at clock time `t`, degrees.
    fn actual_deg(&self, t: Duration) -> f64;
    /// From this clock time on the angle no longer changes.
    fn still_from(&self) -> Duration;
}

/// What the turntable follows.
#[derive(Debug, Clone)]
enum Truth {
    Path(AxisPath),
    Custom(Arc<dyn TruthPath>),
}

impl Truth {
    fn value(&self, t: Duration) -> f64 {
        match self {
            Truth::Path(p) => p.value(t),
            Truth::Custom(c) => c.actual_deg(t),
        }
    }
    fn still_from(&self) -> Duration {
        match self {
            Truth::Path(p) => p.halt_at,
            Truth::Custom(c) => c.still_from(),
        }
    }
}

/// The turntable: a shared handle to the true axis angle (clones share it).
#[derive(Debug, Clone)]
pub struct Turntable {
    path: Arc<Mutex<Truth>>,
}

/// Sub-intervals of the Simpson rule that averages the angle over a
/// measurement during which the axis moves (an even number).
const MEAN_INTERVALS: usize = 32;

impl Turntable {
    /// A turntable at rest at `initial_deg`.
    pub fn new(initial_deg: f64) -> Self {
        Self { path: Arc::new(Mutex::new(Truth::Path(AxisPath::at_rest(initial_deg, Duration::ZERO)))) }
    }

    fn lock(&self) -> MutexGuard<'_, Truth> {
        self.path.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// The true axis angle at clock time `now`, degrees (not wrapped: a
    /// continuous-rotation axis that turned twice reads 720 + x).
    pub fn actual_deg(&self, now: Duration) -> f64 {
        self.lock().value(now)
    }

    /// The mean true angle over `[from, to]` (what an instrument that
    /// integrates over that time sees) and the rms of the angle about it,
    /// degrees: the angle itself and 0 when the axis does not move in it,
    /// else both by Simpson's rule over the same 32 intervals.
    pub fn mean_and_spread_deg(&self, from: Duration, to: Duration) -> (f64, f64) {
        let truth = self.lock().clone();
        if from >= truth.still_from() || to <= from {
            return (truth.value(from), 0.0);
        }
        let (a, b) = (from.as_secs_f64(), to.as_secs_f64());
        let h = (b - a) / MEAN_INTERVALS as f64;
        let weight = |i: usize| match i {
            0 | MEAN_INTERVALS => 1.0,
            i if i % 2 == 1 => 4.0,
            _ => 2.0,
        };
        let angles: [f64; MEAN_INTERVALS + 1] =
            std::array::from_fn(|i| truth.value(Duration::from_secs_f64(a + h * i as f64)));
        let average = |f: &dyn Fn(f64) -> f64| {
            angles.iter().enumerate().map(|(i, &x)| weight(i) * f(x)).sum::<f64>() / (3.0 * MEAN_INTERVALS as f64)
        };
        let mean = average(&|x| x);
        (mean, average(&|x| (x - mean).powi(2)).sqrt())
    }

    /// Whether the axis is moving at `now`.
    pub fn is_moving(&self, now: Duration) -> bool {
        now < self.lock().still_from()
    }

    /// Put the axis at rest at `deg` at once. For testing the tracker or the
    /// autocollimator without a positioner: a positioner driving this turntable
    /// is not told, and overwrites it on its next move.
    pub fn place(&self, deg: f64) {
        *self.lock() = Truth::Path(AxisPath::at_rest(deg, Duration::ZERO));
    }

    /// Replace the path (the positioner does this when a move starts or halts).
    pub(crate) fn set_path(&self, path: AxisPath) {
        *self.lock() = Truth::Path(path);
    }

    /// Follow `truth` from now on (the positioner does this when a move starts).
    pub(crate) fn set_truth(&self, truth: Arc<dyn TruthPath>) {
        *self.lock() = Truth::Custom(truth);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_and_triangle_durations() {
        let p = Profile::new(Duration::ZERO, 90.0, 10.0, 20.0);
        assert!((p.duration_s - 9.5).abs() < 1e-12);
        assert_eq!(p.end(), Duration::from_millis(9500));
        // v^2/a = 5 deg: a 2 deg move is triangular, 2*sqrt(2/20).
        let q = Profile::new(Duration::ZERO, -2.0, 10.0, 20.0);
        assert!((q.duration_s - 2.0 * 0.1f64.sqrt()).abs() < 1e-12);
        assert_eq!(Profile::new(Duration::ZERO, 0.0, 10.0, 20.0).duration_s, 0.0);
    }

    #[test]
    fn fraction_is_monotone_and_hits_landmarks() {
        let p = Profile::new(Duration::from_secs(1), 90.0, 10.0, 20.0);
        let at = |s: f64| p.fraction(Duration::from_secs_f64(1.0 + s));
        assert_eq!(at(-0.5), 0.0);
        // End of the ramp: 0.5 * 20 * 0.25 = 2.5 deg.
        assert!((at(0.5) * 90.0 - 2.5).abs() < 1e-9);
        // Half time is half distance (symmetric profile).
        assert!((at(4.75) - 0.5).abs() < 1e-12);
        assert_eq!(at(9.5), 1.0);
        let mut last = 0.0;
        for i in 0..=1000 {
            let f = at(i as f64 * 0.0095);
            assert!(f >= last - 1e-15);
            last = f;
        }
        let tri = Profile::new(Duration::ZERO, 2.0, 10.0, 20.0);
        assert!((tri.fraction(Duration::from_secs_f64(tri.duration_s / 2.0)) - 0.5).abs() < 1e-8);
    }

    proptest::proptest! {
        #[test]
        fn profile_is_monotone_bounded_and_respects_its_limits(
            d in 0.001f64..400.0, v in 0.1f64..50.0, a in 0.1f64..100.0, probes in proptest::collection::vec(0.0f64..1.0, 1..20)
        ) {
            let p = Profile::new(Duration::from_secs(2), d, v, a);
            proptest::prop_assert!(p.duration_s >= d / v - 1e-9);
            proptest::prop_assert!(p.duration_s >= 2.0 * (d / a).sqrt() - 1e-9);
            proptest::prop_assert_eq!(p.fraction(p.end()), 1.0);
            proptest::prop_assert_eq!(p.fraction(Duration::from_secs(2)), 0.0);
            let mut ts = probes.clone();
            ts.sort_by(f64::total_cmp);
            let mut last = 0.0;
            for t in ts {
                let f = p.fraction(Duration::from_secs(2) + Duration::from_secs_f64(t * p.duration_s));
                proptest::prop_assert!((0.0..=1.0).contains(&f) && f >= last - 1e-12);
                last = f;
            }
        }
    }

    #[test]
    fn path_rests_at_its_rest_value() {
        let p = Profile::new(Duration::ZERO, 10.0, 10.0, 20.0);
        let path = AxisPath { profile: p, halt_at: Duration::from_millis(700), from: 0.0, to: 10.0, rest: 3.0 };
        assert!(path.is_moving(Duration::from_millis(100)));
        assert!((path.value(Duration::from_millis(500)) - 2.5).abs() < 1e-12);
        assert_eq!(path.value(Duration::from_millis(700)), 3.0);
        let t = Turntable::new(5.0);
        assert_eq!(t.actual_deg(Duration::from_secs(3)), 5.0);
        let t2 = t.clone();
        t2.place(7.0);
        assert_eq!(t.actual_deg(Duration::ZERO), 7.0);
        assert!(!t.is_moving(Duration::ZERO));
    }
}
