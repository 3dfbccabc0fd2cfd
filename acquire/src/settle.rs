//! Deciding that the axis is at rest, and measuring there.
//!
//! Two ways ([`SettleMode`], set in [`super::settings::SettleSpec`]):
//!
//! - **adaptive** (the default): after a move to a measuring position the
//!   engine reads the readout every `poll` from the end of the move's
//!   profile. A servo that rings shows it in these readings: from the
//!   successive peaks of the deviation from the target ([`Ringing`]) the
//!   engine predicts when the decaying swing falls within `window_deg`, and
//!   ends the wait once that time has come and the last two readings are
//!   within the window; when no ringing is seen, once every reading for
//!   `stable_for` was within the window. Either way the controller must say
//!   the axis no longer moves. It then starts the reference measurement at once, reads
//!   the readout with it and again when it ends, and takes the sample only
//!   if both readouts are within the window of the target and agree within
//!   it (the axis did not move while the reference integrated) and, with a
//!   tracker, the measurement's standard deviation is not above
//!   `reference_std_ratio` times the typical one of this survey (an SMR
//!   moving during the measurement spreads it); otherwise it measures again.
//!   The sample's readout is the one read at the end of the measurement.
//! - **in-position**: the controller's in-position flag, polled every
//!   `poll_interval_s`, then the fixed `dwell_s` (for instruments that need
//!   a wait the readout cannot show, such as an autocollimator image that
//!   must settle); the readout is read with the measurement.
//!
//! In adaptive mode a move that only takes up backlash before an approach
//! (to the overrun point) waits for the controller to report the motion
//! over, nothing more: the axis turns back at once.
//!
//! The window is stated in the configuration (`settle_window_deg`); by
//! default a tenth of the reference's noise per reading
//! ([`super::settings::default_window_deg`]): 1e-4 deg with a tracker (about 1e-3 deg of
//! noise on a 1 m arm), 3e-6 deg with an autocollimator (0.1 arcsec).

use super::settings::{SettleMode, Timing};
use std::time::Duration;
use survey_drivers::{Clock, DriverError, ErrorKind, Limit, Positioner};
use survey_plan::budget::{Component, Ledger};

/// How many faults a step's requests may have retried in place, in all:
/// four times `max_retries`. A step makes many requests (a move: its
/// command and every poll of its status and readout), so at a few faults in
/// a hundred requests a step meets several; each is retried where it
/// happened (a status poll asked again, the move not commanded again), and
/// only a request that fails `max_retries` times in a row, or a step past
/// this budget, fails the step (then retried as a whole, with recovery, up
/// to `max_retries` times).
pub(crate) fn step_budget(t: &Timing) -> usize {
    4 * t.max_retries as usize
}

/// Whether a request that failed with `e`, after `failed` failures of its
/// own in a row and `spent` retries of its step, is asked again in place:
/// any fault but bad usage, within both budgets.
pub(crate) fn again(e: &DriverError, failed: u32, spent: usize, t: &Timing) -> bool {
    e.kind != ErrorKind::Usage && failed < t.max_retries && spent < step_budget(t)
}

/// A positioner request (`$call`, evaluated again for each try) bounded by
/// the call timeout and retried in place ([`again`]): each fault retried is
/// pushed on `$survived` (the engine records and counts them), after the
/// retry backoff. The last fault, when the request is given up, is the result.
macro_rules! retried {
    ($clock:expr, $t:expr, $name:expr, $what:expr, $survived:expr, $call:expr) => {{
        let mut failed = 0u32;
        loop {
            match survey_drivers::clock::with_timeout($clock, $t.call_timeout, $name, $what, $call).await {
                Ok(v) => break Ok(v),
                Err(e) if !$crate::settle::again(&e, failed, $survived.len(), $t) => break Err(e),
                Err(e) => {
                    failed += 1;
                    tracing::debug!(error = %e, failed, what = $what, "retrying the request in place");
                    $survived.push(e);
                    $clock.sleep($t.retry_backoff).await;
                }
            }
        }
    }};
}
pub(crate) use retried;

/// Settling observed after measured moves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SettleStats {
    pub moves: u64,
    pub sum_s: f64,
    pub max_s: f64,
}

impl SettleStats {
    /// Count one settling time.
    pub fn add(&mut self, s: f64) {
        self.moves += 1;
        self.sum_s += s;
        self.max_s = self.max_s.max(s);
    }

    /// (moves, mean, max), when any.
    pub fn summary(&self) -> Option<(u64, f64, f64)> {
        (self.moves > 0).then(|| (self.moves, self.sum_s / self.moves as f64, self.max_s))
    }
}

/// How often the status is read while the readout is polled (faults, limits).
const STATUS_EVERY: u32 = 10;

/// The swing of a ringing axis, seen in the readout's deviation from the
/// target: its local peaks (a reading larger in magnitude than both its
/// neighbours, above a quarter of the window) give the decay rate of the
/// envelope, `ln(p1 / p2) / (t2 - t1)` from the last two, and so the time
/// the envelope reaches the window, `t2 + ln(p2 / w) / rate`. Readings
/// taken every `poll` see a swing of half-period `h` as peaks lower by at
/// most `1 - cos(pi poll / 2h)`; the prediction is only used when two
/// peaks at least two polls apart decay.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Ringing {
    /// The last two readings' `(time s, |deviation|)`.
    last: LastTwo,
    /// The last two peaks.
    peaks: LastTwo,
}

/// The two most recent of a series of `(time s, value)`, oldest first
/// (a settling wait keeps them at every poll: no vector each).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct LastTwo {
    older: Option<(f64, f64)>,
    newer: Option<(f64, f64)>,
}

impl LastTwo {
    fn push(&mut self, v: (f64, f64)) {
        self.older = self.newer.replace(v);
    }

    /// Both, oldest first, once two were pushed.
    fn both(&self) -> Option<[(f64, f64); 2]> {
        Some([self.older?, self.newer?])
    }
}

impl Ringing {
    /// Take a reading at `t` seconds deviating `d` degrees from the target.
    pub fn push(&mut self, t: f64, d: f64, window: f64) {
        let a = d.abs();
        if let Some([(_, a0), (t1, a1)]) = self.last.both()
            && a1 > a0
            && a1 > a
            && a1 > window / 4.0
        {
            self.peaks.push((t1, a1));
        }
        self.last.push((t, a));
    }

    /// When the envelope reaches `window`, seconds, if the swing is seen
    /// decaying (`min_gap`: the least time between two peaks, two polls).
    pub fn within_at(&self, window: f64, min_gap: f64) -> Option<f64> {
        let [(t1, p1), (t2, p2)] = self.peaks.both()?;
        if t2 - t1 < min_gap || p2 >= p1 {
            return None;
        }
        let rate = (p1 / p2).ln() / (t2 - t1);
        Some(if p2 <= window { t2 } else { t2 + (p2 / window).ln() / rate })
    }
}

/// The engine's own code on the error of a move that ended at a limit switch
/// (no instrument code says it: the status shows the switch).
pub const CODE_LIMIT_SWITCH: i64 = -(0x4c49_4d54); // "LIMT"

/// The error of a move to `target` that stopped at `limit`.
pub fn limit_error(instrument: impl Into<String>, target: f64, limit: Limit) -> DriverError {
    let mut e = DriverError::new(
        ErrorKind::Device,
        instrument,
        format!("the move to {target} deg stopped at the {limit:?} limit switch"),
    );
    e.code = Some(CODE_LIMIT_SWITCH);
    e
}

/// Whether `e` is a move stopped at a limit switch.
pub fn is_limit(e: &DriverError) -> bool {
    e.kind == ErrorKind::Device && e.code == Some(CODE_LIMIT_SWITCH)
}

/// What waiting for a move needs.
#[derive(Debug)]
pub struct Wait<'a> {
    pub positioner: &'a mut dyn Positioner,
    pub clock: &'a dyn Clock,
    pub timing: &'a Timing,
    pub ledger: &'a mut Ledger,
    pub target: f64,
    /// When the move's profile should end.
    pub end: Duration,
    /// When the move counts as stuck.
    pub deadline: Duration,
    /// Whether a sample is taken at the end of this move.
    pub measured: bool,
    /// The faults its requests met and retried in place ([`retried`]).
    pub survived: &'a mut Vec<DriverError>,
}

impl Wait<'_> {
    /// Wait until the axis is at rest (see the module documentation); the
    /// settling observed after the profile's end, for adaptive measured moves.
    pub async fn run(self) -> Result<Option<Duration>, DriverError> {
        let Wait { positioner: p, clock, timing: t, ledger, target, end, mut deadline, measured, survived } = self;
        let name = p.name().to_string();
        // A request asked again in place: the time its faults took is not
        // the axis's, so the deadline moves on by it.
        macro_rules! polled {
            ($what:expr, $call:expr) => {{
                let (before, faults) = (clock.now(), survived.len());
                let r = retried!(clock, t, &name, $what, survived, $call);
                if survived.len() > faults {
                    deadline += clock.now().saturating_sub(before);
                }
                r
            }};
        }
        // Until the profile's predicted end the status is read every
        // `poll_interval` (and once at the end): an axis faster than the
        // configured velocity (or a simulator on a faster clock) is not
        // waited for longer than it moves.
        while clock.now() < end {
            clock.sleep(t.poll_interval.min(end - clock.now())).await;
            if clock.now() >= end {
                break;
            }
            let s = polled!("status", p.status())?;
            if let Some(f) = s.fault {
                return Err(DriverError::device(name, f.code, f.text));
            }
            if !s.moving {
                break;
            }
        }
        let adaptive = t.settle.mode == SettleMode::Adaptive;
        ledger.switch(clock.now(), if measured { Component::Settle } else { Component::Move });
        let w = t.settle.window_deg;
        let mut first_in: Option<Duration> = None;
        let mut recent_in = 0u32;
        let mut ringing = Ringing::default();
        let mut polls = 0u32;
        loop {
            let asked = clock.now();
            if adaptive && measured {
                let r = polled!("readout", p.readout())?;
                let at = clock.now();
                polls += 1;
                ringing.push(at.as_secs_f64(), r - target, w);
                if (r - target).abs() <= w {
                    first_in.get_or_insert(at);
                    recent_in += 1;
                } else {
                    first_in = None;
                    recent_in = 0;
                }
                let predicted = ringing.within_at(w, 2.0 * t.settle.poll.as_secs_f64());
                let settled_at = match predicted {
                    Some(p) => first_in.map(|f| f.max(Duration::from_secs_f64(p))),
                    None => first_in,
                };
                let stable = match predicted {
                    Some(p) => recent_in >= 2 && at.as_secs_f64() >= p,
                    None => first_in.is_some_and(|f| at - f >= t.settle.stable_for),
                };
                if stable || polls.is_multiple_of(STATUS_EVERY) {
                    let s = polled!("status", p.status())?;
                    if let Some(f) = s.fault {
                        return Err(DriverError::device(name, f.code, f.text));
                    }
                    // A limit switch without in-position is a move stopped
                    // short (the deadline names it), whatever the readout says.
                    if stable && !s.moving && (s.limit.is_none() || s.in_position) {
                        let f = settled_at.expect("stable").min(at);
                        ledger.switch(f, Component::PollLag);
                        return Ok(Some(f.saturating_sub(end)));
                    }
                }
            } else {
                let s = polled!("status", p.status())?;
                if let Some(f) = s.fault {
                    return Err(DriverError::device(name, f.code, f.text));
                }
                let done = if adaptive {
                    !s.moving && (s.limit.is_none() || s.in_position)
                } else {
                    s.in_position && !s.moving
                };
                if done {
                    ledger.switch(asked, Component::PollLag);
                    return Ok(None);
                }
            }
            if clock.now() > deadline {
                let s = polled!("status", p.status())?;
                // A limit switch is reported at a target on the end of the
                // travel too, so it only explains a move that never arrived.
                if let Some(limit) = s.limit {
                    return Err(limit_error(name, target, limit));
                }
                let what = if adaptive && measured {
                    format!("did not settle within {w} deg")
                } else {
                    "did not reach in-position".to_string()
                };
                return Err(DriverError::new(
                    ErrorKind::Timeout,
                    name,
                    format!("the move to {target} deg {what} by its deadline"),
                ));
            }
            let interval = if adaptive && measured { t.settle.poll } else { t.poll_interval };
            clock.sleep(interval.saturating_sub(clock.now() - asked)).await;
        }
    }
}

/// The typical standard deviation of this survey's tracker measurements:
/// the median of the first accepted ones.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TypicalStd {
    values: Vec<f64>,
}

impl TypicalStd {
    const KEEP: usize = 15;
    const NEEDED: usize = 3;

    /// Whether `std` is steady against the typical one (always, until a few are known).
    pub fn accepts(&self, std: f64, ratio: f64) -> bool {
        if self.values.len() < Self::NEEDED {
            return true;
        }
        let mut v = self.values.clone();
        v.sort_by(f64::total_cmp);
        std <= ratio * v[v.len() / 2]
    }

    /// Count an accepted measurement's standard deviation.
    pub fn add(&mut self, std: f64) {
        if self.values.len() < Self::KEEP && std.is_finite() {
            self.values.push(std);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ringing_swing_predicts_when_it_is_within_the_window() {
        // The simulated servo's ring after a 0.2 deg step (0.004 deg), read every 10 ms.
        let servo = survey_sims::servo::Servo::default();
        let (a, sigma, omega, w) = (0.004, servo.decay_rate(), servo.ring_omega(), 1e-4);
        let mut r = Ringing::default();
        let mut predicted = None;
        for i in 0..25 {
            let t = 0.002 + i as f64 * 0.01;
            r.push(t, a * (-sigma * t).exp() * (omega * t).sin(), w);
            predicted = r.within_at(w, 0.02).or(predicted);
        }
        let p = predicted.expect("peaks seen within 250 ms");
        // The swing last leaves the window at 293 ms. Peaks read every 10 ms
        // sit up to 3 % below the true ones (2.4 ms of decay each way), and a
        // true peak is 3 % below the envelope: the prediction lands within
        // 5 ms before and 10 ms after the exit.
        let exit = servo.settle_time_s(a, w);
        assert!(p > exit - 0.005 && p < exit + 0.010, "{p} vs {exit}");
        // No swing (a monotone approach, or a still readout): no prediction.
        let mut still = Ringing::default();
        for i in 0..20 {
            still.push(i as f64 * 0.01, 0.001 * (-(i as f64)).exp(), w);
        }
        assert_eq!(still.within_at(w, 0.02), None);
    }

    #[test]
    fn the_typical_std_is_the_median_of_the_first_ones() {
        let mut t = TypicalStd::default();
        assert!(t.accepts(100.0, 1.5), "nothing known yet");
        for s in [1.0, 1.2, 0.9] {
            t.add(s);
        }
        assert!(t.accepts(1.5, 1.5) && !t.accepts(1.51, 1.5));
    }
}
