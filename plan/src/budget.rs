//! Instrument time: where a survey's time went, and the physical lower
//! bound of its plan.
//!
//! The engine keeps a [`Ledger`]: every moment of instrument time belongs to
//! exactly one [`Component`] (it switches components as it goes, so the
//! components add up to the acquisition's instrument time). The bound
//! ([`Bound`]) is what the plan needs at least: every move at the configured
//! velocity and acceleration ([`crate::move_time`]), the settling the
//! axis needs after each move that ends at a measuring position (from its
//! [`SettleModel`]), the reference's integration time at every sample, and
//! the locate (its moves, settling and measurements, and the way back to the
//! first target). A continuous scan's bound is its passes at their
//! velocities (the latency's calibration passes included), the moves
//! between them, and the locate; [`scan_bound_at_max_velocity`] is the same
//! plan at the positioner's pace, every pass at the configured velocity and
//! no calibration passes (what it would cost with the latency known). Commands, polls,
//! dwells and recoveries cost instrument time but are not physics: they are
//! the gap between the two.

use crate::{PassPlan, ScanTiming, SurveyPlan, locate_readouts, move_time, passes, scan_order};
use serde::Serialize;
use std::time::Duration;

/// The settling an axis needs after a move, for the lower bound of a plan
/// (the orchestrator's settling model: a simulated servo, a configured
/// settling time, or none).
pub trait Settling {
    /// Seconds of settling a move of `distance` degrees needs at `velocity`
    /// deg/s and `accel` deg/s^2.
    fn needed_s(&self, distance: f64, velocity: f64, accel: f64) -> f64;
}

/// What instrument time is spent on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Component {
    /// Locating the axis with the tracker (everything it takes).
    Locate,
    /// The axis moving along its profile.
    Move,
    /// The axis coming to rest after a move (until within the settle window,
    /// or until the controller reports in position).
    Settle,
    /// A fixed wait after settling (`dwell_s`).
    Dwell,
    /// The reference instrument measuring (the readout is read meanwhile).
    Measure,
    /// The tracker pointed at the other SMRs on the table and back (a survey
    /// of several SMRs: each turned to and searched for at every target).
    Point,
    /// Waiting to see what already happened: polling granularity, and the
    /// time the readout must stay in the window to count as stable.
    PollLag,
    /// Commands and reads outside a measurement (link latency).
    CommandLatency,
    /// A continuous scan's passes (the axis turning while both instruments stream).
    Scan,
    /// Faults: back-off, recovery, repeated work.
    Recovery,
    /// Anything else.
    Other,
}

impl Component {
    /// Every component, in report order.
    pub const ALL: [Component; 11] = [
        Component::Locate,
        Component::Move,
        Component::Settle,
        Component::Dwell,
        Component::Measure,
        Component::Point,
        Component::PollLag,
        Component::CommandLatency,
        Component::Scan,
        Component::Recovery,
        Component::Other,
    ];

    /// The name used in reports and the store.
    pub fn as_str(self) -> &'static str {
        match self {
            Component::Locate => "locate",
            Component::Move => "move",
            Component::Settle => "settle",
            Component::Dwell => "dwell",
            Component::Measure => "measure",
            Component::Point => "point",
            Component::PollLag => "poll_lag",
            Component::CommandLatency => "command_latency",
            Component::Scan => "scan",
            Component::Recovery => "recovery",
            Component::Other => "other",
        }
    }

    /// The component of a stored name.
    pub fn from_name(name: &str) -> Option<Component> {
        Component::ALL.into_iter().find(|c| c.as_str() == name)
    }

    fn index(self) -> usize {
        Component::ALL.iter().position(|c| *c == self).expect("every component is listed")
    }
}

/// Instrument time per component, seconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Spent {
    seconds: [f64; Component::ALL.len()],
}

impl Spent {
    /// Seconds spent on `c`.
    pub fn get(&self, c: Component) -> f64 {
        self.seconds[c.index()]
    }

    /// Add `s` seconds to `c`.
    pub fn add(&mut self, c: Component, s: f64) {
        self.seconds[c.index()] += s;
    }

    /// Everything.
    pub fn total(&self) -> f64 {
        self.seconds.iter().sum()
    }

    /// Both added.
    pub fn plus(&self, other: &Spent) -> Spent {
        let mut out = *self;
        for c in Component::ALL {
            out.add(c, other.get(c));
        }
        out
    }

    /// `(component, seconds)` for every component with time on it.
    pub fn entries(&self) -> impl Iterator<Item = (Component, f64)> + '_ {
        Component::ALL.into_iter().map(|c| (c, self.get(c))).filter(|(_, s)| *s != 0.0)
    }
}

/// The engine's running account: the component being charged, since when.
#[derive(Debug, Clone, PartialEq)]
pub struct Ledger {
    current: Component,
    since: Duration,
    spent: Spent,
    /// While set, every switch is ignored (the locate charges itself whole).
    held: Option<Component>,
}

impl Default for Ledger {
    fn default() -> Self {
        Self { current: Component::Other, since: Duration::ZERO, spent: Spent::default(), held: None }
    }
}

impl Ledger {
    /// Start a new account at `now`, charging `Other` (the time before is
    /// not this account's).
    pub fn start(&mut self, now: Duration) {
        *self = Ledger { since: now, ..Ledger::default() };
    }

    /// Charge the time since the last switch to the current component and
    /// charge `to` from `at` on. `at` is clamped to the last switch, so a
    /// switch dated in the past only moves time between the two components.
    pub fn switch(&mut self, at: Duration, to: Component) {
        if self.held.is_some() {
            return;
        }
        let at = at.max(self.since);
        self.spent.add(self.current, (at - self.since).as_secs_f64());
        self.current = to;
        self.since = at;
    }

    /// Charge everything to `c` until [`Ledger::release`].
    pub fn hold(&mut self, at: Duration, c: Component) {
        self.switch(at, c);
        self.held = Some(c);
    }

    /// Stop holding; charge `Other` from `at`.
    pub fn release(&mut self, at: Duration) {
        self.held = None;
        self.switch(at, Component::Other);
    }

    /// The component being charged.
    pub fn current(&self) -> Component {
        self.held.unwrap_or(self.current)
    }

    /// The time charged so far, up to `now`.
    pub fn spent(&self, now: Duration) -> Spent {
        let mut s = self.spent;
        s.add(self.current, now.saturating_sub(self.since).as_secs_f64());
        s
    }
}

/// The physical lower bound of a plan, by component, seconds.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Bound {
    pub locate_s: f64,
    pub move_s: f64,
    pub settle_s: f64,
    pub measure_s: f64,
    pub point_s: f64,
    pub scan_s: f64,
}

impl Bound {
    /// All of it.
    pub fn total(&self) -> f64 {
        self.locate_s + self.move_s + self.settle_s + self.measure_s + self.point_s + self.scan_s
    }

    /// The bound of one component.
    pub fn of(&self, c: Component) -> f64 {
        match c {
            Component::Locate => self.locate_s,
            Component::Move => self.move_s,
            Component::Settle => self.settle_s,
            Component::Measure => self.measure_s,
            Component::Point => self.point_s,
            Component::Scan => self.scan_s,
            _ => 0.0,
        }
    }
}

/// What the bound needs besides the plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    /// Configured velocity and acceleration, deg/s and deg/s^2.
    pub velocity_deg_s: f64,
    pub accel_deg_s2: f64,
    /// The reference's integration time per sample, seconds.
    pub integration_s: f64,
    /// SMR positions that locate the axis (0: no locate).
    pub locate_points: u32,
    /// The SMRs measured at every target beside the first (0: one SMR).
    pub other_smrs: u32,
    /// The least time to point the tracker at another SMR and find it,
    /// seconds (each other SMR, and back to the first, at every target).
    pub point_s: f64,
}

/// One move of a plan and whether a sample is taken at its end.
fn step_moves(plan: &SurveyPlan) -> Vec<(f64, bool)> {
    let mut moves = Vec::new();
    let mut pos = plan.targets_deg[0] - plan.overrun_deg;
    for step in plan.steps() {
        let approach_from = step.target_deg - step.direction.sign() * plan.overrun_deg;
        if (step.target_deg - pos) * step.direction.sign() <= 0.0 {
            moves.push((approach_from - pos, false));
            pos = approach_from;
        }
        moves.push((step.target_deg - pos, true));
        pos = step.target_deg;
    }
    moves
}

/// The locate's bound: the first locate point approached from one overrun
/// below it, then every next one, each settled and measured, and the way
/// to `start_deg`, where the plan starts (the move from wherever the axis
/// was before is not counted: it is not known).
pub fn locate_bound(plan: &SurveyPlan, d: &Dynamics, settle: &dyn Settling, start_deg: f64) -> f64 {
    if d.locate_points == 0 {
        return 0.0;
    }
    let readouts = locate_readouts(plan, d.locate_points);
    let (v, a) = (d.velocity_deg_s, d.accel_deg_s2);
    let mut total = move_time(plan.overrun_deg, v, a) + settle.needed_s(plan.overrun_deg, v, a);
    for w in readouts.windows(2) {
        total += move_time(w[1] - w[0], v, a) + settle.needed_s(w[1] - w[0], v, a);
    }
    total += readouts.len() as f64 * d.integration_s;
    let last = *readouts.last().expect("at least 3 locate points");
    total + move_time(start_deg - last, v, a)
}

/// The bound of a step survey (see the module documentation).
pub fn step_bound(plan: &SurveyPlan, d: &Dynamics, settle: &dyn Settling) -> Bound {
    let start = plan.targets_deg[0] - plan.overrun_deg;
    let mut b = Bound { locate_s: locate_bound(plan, d, settle, start), ..Bound::default() };
    for (distance, measured) in step_moves(plan) {
        b.move_s += move_time(distance, d.velocity_deg_s, d.accel_deg_s2);
        if measured {
            b.settle_s += settle.needed_s(distance, d.velocity_deg_s, d.accel_deg_s2);
            b.measure_s += d.integration_s * f64::from(1 + d.other_smrs);
            if d.other_smrs > 0 {
                b.point_s += d.point_s * f64::from(d.other_smrs + 1);
            }
        }
    }
    b
}

/// The lower bound of a continuous plan: the locate, the moves to the
/// first pass's start and between passes, and every pass (the latency's
/// calibration passes too) at its velocity over its targets plus the
/// acceleration ramps (no margins).
pub fn scan_bound(plan: &SurveyPlan, d: &Dynamics, settle: &dyn Settling, t: &ScanTiming) -> Bound {
    passes_bound(plan, &scan_order(plan, d.velocity_deg_s, d.accel_deg_s2, t), d, settle)
}

/// The lower bound of a continuous plan at the positioner's pace: every
/// pass at the configured velocity (its maximum), and no calibration
/// passes (what the plan costs once the latency is known).
pub fn scan_bound_at_max_velocity(plan: &SurveyPlan, d: &Dynamics, settle: &dyn Settling, t: &ScanTiming) -> Bound {
    let t = ScanTiming { velocity_deg_s: None, ..*t };
    passes_bound(plan, &passes(plan, d.velocity_deg_s, d.accel_deg_s2, &t), d, settle)
}

/// The bound of turning `all` in order (see [`scan_bound`]).
fn passes_bound(plan: &SurveyPlan, all: &[PassPlan], d: &Dynamics, settle: &dyn Settling) -> Bound {
    let mut b = Bound::default();
    let mut pos = all.first().map_or(0.0, |p| p.start);
    b.locate_s = locate_bound(plan, d, settle, pos);
    for p in all {
        let ramp = p.speed * p.speed / (2.0 * d.accel_deg_s2);
        let sign = p.direction.sign();
        let (first, last) = (p.targets[0].1, p.targets[p.targets.len() - 1].1);
        let start = first - sign * ramp;
        b.move_s += move_time(start - pos, d.velocity_deg_s, d.accel_deg_s2);
        b.scan_s += move_time(last - first + sign * 2.0 * ramp, p.speed, d.accel_deg_s2);
        pos = last + sign * ramp;
    }
    b
}

/// The bound of a plan, step or continuous.
pub fn plan_bound(plan: &SurveyPlan, d: &Dynamics, settle: &dyn Settling, scan: &ScanTiming) -> Bound {
    if plan.continuous() { scan_bound(plan, d, settle, scan) } else { step_bound(plan, d, settle) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same settling after every move, seconds.
    struct Fixed(f64);

    impl Settling for Fixed {
        fn needed_s(&self, _distance: f64, _velocity: f64, _accel: f64) -> f64 {
            self.0
        }
    }

    #[test]
    fn the_ledger_charges_every_moment_once() {
        let mut l = Ledger::default();
        let ms = Duration::from_millis;
        l.start(ms(1000));
        l.switch(ms(1002), Component::Move);
        l.switch(ms(1202), Component::Settle);
        // A switch dated before the last one is clamped to it.
        l.switch(ms(1100), Component::PollLag);
        l.switch(ms(1500), Component::Measure);
        l.hold(ms(2500), Component::Locate);
        l.switch(ms(2600), Component::Move);
        l.release(ms(3000));
        let s = l.spent(ms(3010));
        assert!((s.total() - 2.010).abs() < 1e-12, "{s:?}");
        assert!((s.get(Component::Other) - 0.012).abs() < 1e-12);
        assert!((s.get(Component::Move) - 0.2).abs() < 1e-12);
        assert_eq!(s.get(Component::Settle), 0.0);
        assert!((s.get(Component::PollLag) - 0.298).abs() < 1e-12);
        assert!((s.get(Component::Measure) - 1.0).abs() < 1e-12);
        assert!((s.get(Component::Locate) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn the_step_bound_counts_moves_settling_and_integration() {
        // 4 targets, 2 runs, both directions, overrun 45 deg: by hand.
        let plan = SurveyPlan::full_circle(4, 2, true).unwrap();
        let d = Dynamics {
            velocity_deg_s: 10.0,
            accel_deg_s2: 20.0,
            integration_s: 1.0,
            locate_points: 0,
            other_smrs: 0,
            point_s: 0.0,
        };
        let b = step_bound(&plan, &d, &Fixed(0.3));
        let mt = |x: f64| move_time(x, 10.0, 20.0);
        // The overrun is 1 deg. Measured: 4 approaches of 1 deg (the first
        // target from the plan's start, the others after an overrun) and 12
        // moves of 90; not measured: the 3 overrun moves of 1 deg.
        assert_eq!(plan.overrun_deg, 1.0);
        assert!((b.move_s - (7.0 * mt(1.0) + 12.0 * mt(90.0))).abs() < 1e-9, "{b:?}");
        assert_eq!(b.measure_s, 16.0);
        assert!((b.settle_s - 16.0 * 0.3).abs() < 1e-12);
        assert_eq!(b.locate_s, 0.0);
        // Three SMRs: each target measures three, and points at two and back.
        let three = step_bound(&plan, &Dynamics { other_smrs: 2, point_s: 0.7, ..d }, &Fixed(0.3));
        assert_eq!(three.measure_s, 48.0);
        assert!((three.point_s - 16.0 * 3.0 * 0.7).abs() < 1e-9, "{three:?}");
        assert_eq!((three.move_s, three.settle_s), (b.move_s, b.settle_s));
    }

    #[test]
    fn the_scan_bound_turns_the_calibration_arc_four_times_and_the_bound_at_pace_none() {
        use crate::ScanMode;
        let mut plan = SurveyPlan::full_circle(36, 2, true).unwrap();
        plan.scan = ScanMode::Continuous;
        let d = Dynamics {
            velocity_deg_s: 10.0,
            accel_deg_s2: 20.0,
            integration_s: 0.0,
            locate_points: 0,
            other_smrs: 0,
            point_s: 0.0,
        };
        let t = ScanTiming::default();
        let mt = |x: f64, v: f64| move_time(x, v, 20.0);
        // At 10 deg/s the ramps are 2.5 deg, at 2.5 deg/s 0.15625 deg: the
        // four passes over the plan (350 deg between its first and last
        // target) at 10 deg/s, and the calibration arc of 60 deg each way at
        // 10 and 2.5.
        let at_pace = scan_bound_at_max_velocity(&plan, &d, &Fixed(0.0), &t);
        assert!((at_pace.scan_s - 4.0 * mt(355.0, 10.0)).abs() < 1e-9, "{at_pace:?}");
        let b = scan_bound(&plan, &d, &Fixed(0.0), &t);
        let arc = 2.0 * mt(65.0, 10.0) + 2.0 * mt(60.3125, 2.5);
        assert!((b.scan_s - at_pace.scan_s - arc).abs() < 1e-9, "{b:?}");
        // Moves: from the first pass's run-up point (where the locate
        // leaves the axis) to its ramp's start; none between the plan's
        // passes (each ends where the next starts); from the calibration
        // passes at 10 deg/s to those at 2.5 and back to run 1's start.
        let first = mt(t.runup_deg(10.0, 20.0) - 2.5, 10.0);
        assert!((at_pace.move_s - first).abs() < 1e-9, "{at_pace:?}");
        assert!((b.move_s - first - 2.0 * mt(2.34375, 10.0)).abs() < 1e-9, "{b:?}");
        // A scan velocity set below the maximum counts in the plan's bound, not in the one at pace.
        let slow = ScanTiming { velocity_deg_s: Some(5.0), ..t };
        assert_eq!(scan_bound_at_max_velocity(&plan, &d, &Fixed(0.0), &slow), at_pace);
        assert!(scan_bound(&plan, &d, &Fixed(0.0), &slow).scan_s > 1.9 * at_pace.scan_s);
    }
}
