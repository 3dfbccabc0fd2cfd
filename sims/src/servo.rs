//! How a servo axis moves and comes to rest, beyond the commanded profile:
//! the residual oscillation after a move (ringing), velocity ripple while it
//! moves, the non-repeatable error along a move, and the clocks of
//! instruments that time-stamp what they stream.
//!
//! Our own model (no public document describes a particular drive): a
//! second-order closed loop of natural frequency `natural_hz` and damping
//! ratio `damping`. When the commanded profile ends the axis overshoots in
//! the direction of the move and rings,
//!
//! `x(s) = sign * A * exp(-sigma s) * sin(omega_d s)`, `s` after the profile's end,
//!
//! with `sigma = 2 pi f_n zeta`, `omega_d = 2 pi f_n sqrt(1 - zeta^2)` and an
//! amplitude `A = overshoot_s * v_peak` proportional to the peak velocity of
//! the move (`v_peak = v` for a trapezoidal move, `sqrt(d a)` for a short
//! triangular one): a long move rings more and for longer than a short step.
//! Once the envelope `A exp(-sigma s)` is below `hold_deg` the drive holds
//! the axis still (its in-position window): from then on the axis is exactly
//! at rest, and the controller reports in position.
//!
//! The time the axis needs to come within a window `w` of its target is
//! [`Servo::settle_time_s`]: `ln(A / w) / sigma` (0 when `A <= w`).
//!
//! While the axis moves, the velocity ripples: the displayed readout follows
//! the profile plus `sign * r / (2 pi f_r) * v(t) * sin(2 pi f_r (t - t0))`,
//! `v(t)` the profile's velocity (so the ripple is zero at rest).

use std::time::Duration;

/// The dynamics of a servo axis (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Servo {
    /// Natural frequency of the closed loop, Hz.
    pub natural_hz: f64,
    /// Damping ratio (0 < zeta < 1).
    pub damping: f64,
    /// Ringing amplitude per unit of the move's peak velocity, seconds
    /// (degrees of overshoot per degree per second).
    pub overshoot_s: f64,
    /// Below this envelope the drive holds the axis still, degrees.
    pub hold_deg: f64,
    /// Velocity ripple as a fraction of the velocity.
    pub ripple_fraction: f64,
    /// Frequency of the velocity ripple, Hz.
    pub ripple_hz: f64,
}

impl Default for Servo {
    /// The simulated bench's axis: 8 Hz, damping 0.25 (the ringing decays
    /// with a time constant of 80 ms), 0.002 s of overshoot (0.02 deg after
    /// a stop from 10 deg/s, 0.004 deg after a 0.2 deg step at 20 deg/s^2),
    /// held below 1e-5 deg, 0.5 % velocity ripple at 3 Hz.
    fn default() -> Self {
        Self {
            natural_hz: 8.0,
            damping: 0.25,
            overshoot_s: 0.002,
            hold_deg: 1e-5,
            ripple_fraction: 0.005,
            ripple_hz: 3.0,
        }
    }
}

impl Servo {
    /// Decay rate of the ringing, 1/s.
    pub fn decay_rate(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.natural_hz * self.damping
    }

    /// Angular frequency of the ringing, rad/s.
    pub fn ring_omega(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.natural_hz * (1.0 - self.damping * self.damping).max(0.0).sqrt()
    }

    /// Ringing amplitude after a move whose peak velocity was `v_peak`, degrees.
    pub fn amplitude_deg(&self, v_peak: f64) -> f64 {
        self.overshoot_s * v_peak.abs()
    }

    /// Time after the profile's end from which the ringing of amplitude
    /// `amplitude` stays within `window_deg` (positive), seconds: the last
    /// moment it is outside (0 when it never is).
    ///
    /// A search over the ringing's peaks and a bisection (a hundred `sin`
    /// and `exp`): a survey's moves are of a few sizes, so it is made once
    /// per servo, amplitude and window on each thread and remembered.
    pub fn settle_time_s(&self, amplitude: f64, window_deg: f64) -> f64 {
        let (sigma, omega) = (self.decay_rate(), self.ring_omega());
        if amplitude <= window_deg || omega <= 0.0 {
            return 0.0;
        }
        let key = [sigma, omega, amplitude, window_deg].map(f64::to_bits);
        SETTLE_TIMES.with_borrow_mut(|known| {
            if let Some(&t) = known.get(&key) {
                return t;
            }
            if known.len() >= SETTLE_TIMES_KEPT {
                known.clear();
            }
            let t = search_settle_time(sigma, omega, amplitude, window_deg);
            known.insert(key, t);
            t
        })
    }

    /// The settling a move of `distance` degrees at `velocity` and `accel`
    /// needs to come within `window_deg` (what a survey's lower bound counts).
    pub fn move_settle_s(&self, distance: f64, velocity: f64, accel: f64, window_deg: f64) -> f64 {
        self.settle_time_s(self.amplitude_deg(peak_velocity(distance, velocity, accel)), window_deg)
    }
}

/// How many settle times a thread remembers (forgotten all at once past it:
/// a continuous range of move sizes must not grow it without bound).
const SETTLE_TIMES_KEPT: usize = 4096;

thread_local! {
    /// [`Servo::settle_time_s`] by the bits of (decay rate, ringing frequency, amplitude, window).
    static SETTLE_TIMES: std::cell::RefCell<std::collections::HashMap<[u64; 4], f64>> = Default::default();
}

/// [`Servo::settle_time_s`] computed: the last peak of the ringing
/// `amplitude exp(-sigma s) sin(omega s)` outside the window, then the
/// bisection to where it falls into it.
fn search_settle_time(sigma: f64, omega: f64, amplitude: f64, window_deg: f64) -> f64 {
    let x = |s: f64| (amplitude * (-sigma * s).exp() * (omega * s).sin()).abs();
    // |x| peaks where tan(omega s) = omega / sigma, every half period.
    let first = (omega / sigma).atan() / omega;
    let half = std::f64::consts::PI / omega;
    let mut last = None;
    for k in 0..10_000 {
        let peak = first + k as f64 * half;
        if x(peak) > window_deg {
            last = Some((peak, (k + 1) as f64 * half));
        } else if amplitude * (-sigma * peak).exp() <= window_deg {
            break;
        }
    }
    let Some((mut lo, mut hi)) = last else { return 0.0 };
    // |x| falls from the peak to the next zero: the crossing of the window.
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if x(mid) > window_deg {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The peak velocity of a trapezoidal (or triangular) move, deg/s.
pub fn peak_velocity(distance: f64, velocity: f64, accel: f64) -> f64 {
    let d = distance.abs();
    if d >= velocity * velocity / accel { velocity } else { (d * accel).sqrt() }
}

/// The servo's motion beyond the commanded profile for one move: ripple
/// while the profile runs, ringing after it until the drive holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Response {
    servo: Servo,
    /// +1 for a forward move, -1 for a reverse one.
    sign: f64,
    /// Clock time the profile starts and ends.
    start: Duration,
    end: Duration,
    /// Ringing amplitude, degrees.
    amplitude: f64,
    /// The profile's shape: distance, cruise velocity, acceleration.
    distance: f64,
    velocity: f64,
    accel: f64,
    /// From here on the axis is held still (in position).
    hold_at: Duration,
}

impl Response {
    /// The response to a profile over `distance` degrees (signed) from
    /// `start` to `end` at `velocity` and `accel`.
    pub fn new(servo: Servo, start: Duration, end: Duration, distance: f64, velocity: f64, accel: f64) -> Self {
        let amplitude =
            if distance == 0.0 { 0.0 } else { servo.amplitude_deg(peak_velocity(distance, velocity, accel)) };
        let hold = servo.settle_time_s(amplitude, servo.hold_deg);
        Self {
            servo,
            sign: distance.signum(),
            start,
            end,
            amplitude,
            distance: distance.abs(),
            velocity,
            accel,
            hold_at: end + Duration::from_secs_f64(hold),
        }
    }

    /// When the drive holds the axis still (in position).
    pub fn hold_at(&self) -> Duration {
        self.hold_at
    }

    /// The ringing amplitude of this move, degrees.
    pub fn amplitude_deg(&self) -> f64 {
        self.amplitude
    }

    /// The profile's velocity at `t`, deg/s (0 outside the profile).
    fn profile_velocity(&self, t: Duration) -> f64 {
        if t <= self.start || t >= self.end || self.distance == 0.0 {
            return 0.0;
        }
        let total = (self.end - self.start).as_secs_f64();
        let s = (t - self.start).as_secs_f64();
        let ramp = (self.velocity / self.accel).min(total / 2.0);
        let peak = self.accel * ramp;
        if s < ramp {
            self.accel * s
        } else if s > total - ramp {
            self.accel * (total - s)
        } else {
            peak
        }
    }

    /// What the servo adds to the commanded profile at clock time `t`, degrees.
    pub fn offset_deg(&self, t: Duration) -> f64 {
        if t >= self.hold_at || t <= self.start {
            return 0.0;
        }
        if t < self.end {
            let v = self.profile_velocity(t);
            let w = 2.0 * std::f64::consts::PI * self.servo.ripple_hz;
            if w == 0.0 {
                return 0.0;
            }
            return self.sign * self.servo.ripple_fraction / w * v * (w * (t - self.start).as_secs_f64()).sin();
        }
        let s = (t - self.end).as_secs_f64();
        self.sign * self.amplitude * (-self.servo.decay_rate() * s).exp() * (self.servo.ring_omega() * s).sin()
    }
}

/// The clock of an instrument that time-stamps what it streams: its time is
/// `offset_s + (1 + rate_ppm * 1e-6) * t` for clock time `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceClock {
    /// The instrument's time at clock time 0, seconds.
    pub offset_s: f64,
    /// How fast it runs against the clock, parts per million.
    pub rate_ppm: f64,
}

impl DeviceClock {
    /// The instrument's time at clock time `t`, seconds.
    pub fn at(&self, t: Duration) -> f64 {
        self.offset_s + (1.0 + self.rate_ppm * 1e-6) * t.as_secs_f64()
    }
}

/// A standard normal value for (`seed`, `index`), drawn at random access
/// (Box-Muller on two hashed uniforms): the same pair always gives the same value.
pub fn hashed_normal(seed: u64, index: i64) -> f64 {
    let k = index as u64;
    let u1 = crate::derive_seed(seed, k.wrapping_mul(2).wrapping_add(1));
    let u2 = crate::derive_seed(seed, k.wrapping_mul(2).wrapping_add(2));
    // 53-bit uniforms in (0, 1].
    let to_unit = |u: u64| ((u >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
    let (a, b) = (to_unit(u1), to_unit(u2));
    (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ringing_decays_to_the_window_in_the_stated_time_and_then_holds() {
        let servo = Servo::default();
        // A 0.2 deg step at 10 deg/s and 20 deg/s^2: triangular, peak 2 deg/s.
        let r = Response::new(servo, Duration::ZERO, Duration::from_millis(200), 0.2, 10.0, 20.0);
        assert!((r.amplitude_deg() - 0.004).abs() < 1e-12);
        let w = 1e-4;
        let settle = servo.settle_time_s(r.amplitude_deg(), w);
        // The envelope (80 ms time constant: damping 0.25 at 8 Hz) reaches
        // the window after ln(40) of them; the last swing out of it is
        // within the half period before.
        let envelope = 40f64.ln() / (2.0 * std::f64::consts::PI * 2.0);
        let half = std::f64::consts::PI / servo.ring_omega();
        assert!(settle <= envelope && settle > envelope - half, "{settle} vs {envelope}");
        let after = |s: f64| Duration::from_millis(200) + Duration::from_secs_f64(s);
        // Within the window from the settle time on (sampled every 0.1 ms) ...
        for i in 0..5000 {
            let x = r.offset_deg(after(settle + i as f64 * 1e-4));
            // (the clock rounds to whole nanoseconds: 1e-6 of the window covers it)
            assert!(x.abs() <= w * (1.0 + 1e-6), "{x} at +{}", i as f64 * 1e-4);
        }
        // ... and out of it just before.
        assert!(r.offset_deg(after(settle - 1e-6)).abs() > w * (1.0 - 1e-3));
        // Held still (exactly) from the hold time on; the first swing is forward.
        assert_eq!(r.offset_deg(r.hold_at()), 0.0);
        assert_eq!(r.offset_deg(r.hold_at() + Duration::from_secs(1)), 0.0);
        assert!(r.offset_deg(after(0.01)) > 0.0);
        // A long move rings more (and longer) than a short one.
        let long = Response::new(servo, Duration::ZERO, Duration::from_millis(9500), -90.0, 10.0, 20.0);
        assert!((long.amplitude_deg() - 0.02).abs() < 1e-12);
        assert!(long.hold_at() - Duration::from_millis(9500) > r.hold_at() - Duration::from_millis(200));
        assert!(long.offset_deg(Duration::from_millis(9510)) < 0.0, "a reverse move overshoots backward");
        assert!(servo.move_settle_s(90.0, 10.0, 20.0, w) > servo.move_settle_s(0.2, 10.0, 20.0, w));
    }

    #[test]
    fn a_remembered_settle_time_is_the_searched_one_and_the_memory_stays_bounded() {
        let servo = Servo::default();
        let (sigma, omega) = (servo.decay_rate(), servo.ring_omega());
        for i in 0..(SETTLE_TIMES_KEPT + 100) {
            let a = 1e-4 + i as f64 * 1e-6;
            let searched = search_settle_time(sigma, omega, a, 1e-5);
            assert_eq!(servo.settle_time_s(a, 1e-5).to_bits(), searched.to_bits());
            assert_eq!(servo.settle_time_s(a, 1e-5).to_bits(), searched.to_bits(), "remembered");
        }
        assert!(SETTLE_TIMES.with_borrow(|known| known.len()) <= SETTLE_TIMES_KEPT);
        // Another servo's ringing is not taken for this one's.
        let stiff = Servo { natural_hz: 40.0, ..servo };
        assert!(stiff.settle_time_s(0.004, 1e-5) < servo.settle_time_s(0.004, 1e-5) / 4.0);
    }

    #[test]
    fn ripple_is_zero_at_rest_and_proportional_to_the_velocity() {
        let servo = Servo::default();
        let r = Response::new(servo, Duration::ZERO, Duration::from_millis(9500), 90.0, 10.0, 20.0);
        assert_eq!(r.offset_deg(Duration::ZERO), 0.0);
        let amp = servo.ripple_fraction * 10.0 / (2.0 * std::f64::consts::PI * servo.ripple_hz);
        let peak = (0..9000).map(|i| r.offset_deg(Duration::from_millis(500 + i)).abs()).fold(0.0, f64::max);
        assert!((peak - amp).abs() < 0.01 * amp, "{peak} vs {amp}");
    }

    #[test]
    fn hashed_normals_are_stable_and_standard() {
        assert_eq!(hashed_normal(7, 12).to_bits(), hashed_normal(7, 12).to_bits());
        assert_ne!(hashed_normal(7, 12), hashed_normal(7, 13));
        let n = 20_000;
        let xs: Vec<f64> = (0..n).map(|i| hashed_normal(3, i - 5000)).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        // Standard errors: 1/sqrt(n) = 0.007 on the mean, 1/sqrt(2n) = 0.005 on the sd; 4 of them.
        assert!(mean.abs() < 0.03 && (sd - 1.0).abs() < 0.02, "{mean} {sd}");
        let c = DeviceClock { offset_s: 100.0, rate_ppm: 20.0 };
        assert!((c.at(Duration::from_secs(1000)) - 1100.02).abs() < 1e-9);
    }
}
