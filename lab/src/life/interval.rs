//! When an asset is checked next (issue 53): the interval between its
//! checks, reviewed after each check or calibration by the method its
//! `[asset]` states (ILAC-G24:2022 / OIML D 10), with the reason in words;
//! pure functions over an asset's events ([`Event`]: the date, what the
//! survey found, its own travel), so that a history can be built in a test
//! on any clock. [`super::due`] reads the events from a store.
//!
//! The methods:
//! - `staircase` (M1, the default): after a check in tolerance the interval
//!   is lengthened by [`LENGTHEN`] (a quarter; a check made before three
//!   quarters of the interval, [`EARLY`], keeps it), after one out of tolerance
//!   or out of control shortened by [`SHORTEN`] (to half), always within
//!   `interval_min_days`..`interval_max_days`; a calibration keeps it.
//! - `control-chart` (M2): as the staircase when it shortens; after a check
//!   in tolerance and in control, the trend of the control statistic (the
//!   table's residual against its `U`, 1 where the table no
//!   longer holds) since the calibration, when it rises
//!   significantly (at least three checks, the slope over twice its
//!   standard error), sets the interval to half the time the trend takes to
//!   reach 1 (the table's `U`); without a rising trend, a check that found
//!   the positioner changed (the table still holding) shortens it by half,
//!   one that found it unchanged lengthens it. (Through the simulators the
//!   statistic stays near 0 while a line wears, and jumps only once the
//!   table fails: the change found is what says a positioner is on its way
//!   out, `year_sim_tests`.) The staircase keeps the interval after a
//!   change inside tolerance (our design: ILAC-G24's staircase reads only
//!   in or out, and lengthening after a check that found the positioner
//!   moving had a wearing one checked 113 days later, 159 days out of
//!   tolerance in a simulated year).
//! - `in-use` (M3): `interval_revolutions` of travel between checks, counted
//!   from the surveys' own travel (what the drivers tell today); the date is
//!   projected at the rate the asset turned so far, the calendar interval
//!   where no rate is known yet, always within the bounds.
//! - `fixed`: `interval_days`, whatever the outcome.
//!
//! A change of the asset's interval keys starts again from its
//! `interval_days`.

use survey_store::config::AssetSection;

/// The factor a staircase lengthens the interval by after a check in tolerance.
pub const LENGTHEN: f64 = 1.25;

/// The share of its interval a check in tolerance must come after to
/// lengthen it (a check made early says nothing of the whole interval).
pub const EARLY: f64 = 0.75;

/// The factor a staircase shortens the interval by after a check out of
/// tolerance or out of control.
pub const SHORTEN: f64 = 0.5;

/// How an asset's interval is reviewed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// ILAC-G24 M1: calendar time, lengthened and shortened by outcome.
    Staircase,
    /// ILAC-G24 M2: the control chart's trend.
    ControlChart,
    /// ILAC-G24 M3: the travel in use.
    InUse,
    /// The stated interval, whatever the outcome.
    Fixed,
}

impl Method {
    /// The configuration's word (`interval_method`).
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Staircase => "staircase",
            Method::ControlChart => "control-chart",
            Method::InUse => "in-use",
            Method::Fixed => "fixed",
        }
    }

    /// From the configuration's word (the schema admits no other).
    pub fn parse(word: &str) -> Option<Method> {
        [Method::Staircase, Method::ControlChart, Method::InUse, Method::Fixed].into_iter().find(|m| m.as_str() == word)
    }
}

/// An asset's interval keys, the defaults filled in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// `interval_method`.
    pub method: Method,
    /// `interval_days`: the first interval.
    pub interval_days: f64,
    /// `interval_min_days`.
    pub min_days: f64,
    /// `interval_max_days`.
    pub max_days: f64,
    /// `interval_revolutions` (in use).
    pub revolutions: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings::of(None)
    }
}

impl Settings {
    /// The keys of `[asset]` (none: every default).
    pub fn of(section: Option<&AssetSection>) -> Settings {
        let get = |f: fn(&AssetSection) -> Option<f64>, default: f64| section.and_then(f).unwrap_or(default);
        Settings {
            method: section
                .and_then(|s| s.interval_method.as_deref())
                .and_then(Method::parse)
                .unwrap_or(Method::Staircase),
            interval_days: get(|s| s.interval_days, AssetSection::DEFAULT_INTERVAL_DAYS),
            min_days: get(|s| s.interval_min_days, AssetSection::DEFAULT_MIN_DAYS),
            max_days: get(|s| s.interval_max_days, AssetSection::DEFAULT_MAX_DAYS),
            revolutions: get(|s| s.interval_revolutions, AssetSection::DEFAULT_REVOLUTIONS),
        }
    }

    /// `days` within the bounds, in whole days, and whether a bound held it.
    fn bounded(&self, days: f64) -> (f64, Option<String>) {
        let days = days.round();
        if days > self.max_days {
            (self.max_days, Some(format!("held at interval_max_days, {} days", num(self.max_days))))
        } else if days < self.min_days {
            (self.min_days, Some(format!("held at interval_min_days, {} days", num(self.min_days))))
        } else {
            (days, None)
        }
    }
}

/// What a survey of the asset was, for its interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// A calibration (its table then in force).
    Calibration,
    /// A check in tolerance and in control.
    InTolerance,
    /// A check in tolerance and in control that found the positioner
    /// changed (a significant change, the table in force still holding).
    Changed,
    /// A check that called for a recalibration (out of tolerance).
    OutOfTolerance,
    /// A check in tolerance whose control chart fired (a recalibration follows).
    OutOfControl,
    /// Any other survey (a check that decided nothing, a verification): its
    /// travel counts, nothing is reviewed.
    Other,
}

/// One survey of the asset, oldest first.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// The survey (its id in the store).
    pub survey_id: i64,
    /// When it was made: days since 1970-01-01 UTC.
    pub at_days: f64,
    /// What it was.
    pub outcome: Outcome,
    /// Its own travel, revolutions.
    pub revolutions: f64,
    /// A check's control statistic ([`super::control`]: 1 where the table no longer holds), when measured.
    pub statistic: Option<f64>,
    /// The asset's interval keys the survey was made with.
    pub settings: Settings,
}

/// The interval set after a calibration or check.
#[derive(Debug, Clone, PartialEq)]
pub struct Review {
    /// The survey it was reviewed after.
    pub survey_id: i64,
    /// When: days since 1970-01-01 UTC.
    pub at_days: f64,
    /// The method.
    pub method: Method,
    /// The interval to the next check, days.
    pub interval_days: f64,
    /// In use: the revolutions to the next check.
    pub revolutions: Option<f64>,
    /// What moved it, by how much, within which bounds.
    pub reason: String,
}

/// A number of days or revolutions as the reasons write it.
fn num(x: f64) -> String {
    if (x - x.round()).abs() < 1e-9 { format!("{x:.0}") } else { format!("{x:.1}") }
}

/// The reviews of an asset's events (oldest first): one after each
/// calibration and each decided check.
pub fn reviews(events: &[Event]) -> Vec<Review> {
    let mut out: Vec<Review> = Vec::new();
    for (i, e) in events.iter().enumerate() {
        if e.outcome == Outcome::Other {
            continue;
        }
        let before = out.last();
        let s = &e.settings;
        let restart = match before {
            None => Some(format!("the first interval stated (interval_days, {} days)", num(s.interval_days))),
            Some(_) if previous_settings(events, i) != Some(*s) => Some(format!(
                "the asset's interval keys changed: started again from interval_days, {} days",
                num(s.interval_days)
            )),
            Some(_) => None,
        };
        let (interval_days, reason) = match (restart, before) {
            (Some(why), _) => {
                let (d, held) = s.bounded(s.interval_days);
                (d, held.map_or(why.clone(), |h| format!("{why}, {h}")))
            }
            (None, Some(_)) if s.method == Method::Fixed => {
                (s.interval_days, format!("fixed: interval_days, {} days, whatever the outcome", num(s.interval_days)))
            }
            (None, Some(b)) => moved(b, &events[..=i], s),
            (None, None) => unreachable!("the first review starts from interval_days"),
        };
        let (interval_days, reason, revolutions) = match s.method {
            Method::InUse => in_use(&events[..=i], s, interval_days, reason),
            _ => (interval_days, reason, None),
        };
        out.push(Review {
            survey_id: e.survey_id,
            at_days: e.at_days,
            method: s.method,
            interval_days,
            revolutions,
            reason,
        });
    }
    out
}

/// The settings of the last reviewed event before `i`.
fn previous_settings(events: &[Event], i: usize) -> Option<Settings> {
    events[..i].iter().rev().find(|e| e.outcome != Outcome::Other).map(|e| e.settings)
}

/// The interval after the last of `events`, from the review before
/// (`before`), by the staircase or the control chart.
fn moved(before: &Review, events: &[Event], s: &Settings) -> (f64, String) {
    let e = events.last().expect("an event to review");
    let prev = before.interval_days;
    let elapsed = e.at_days - before.at_days;
    let shorten = |what: &str| {
        let (d, held) = s.bounded(prev * SHORTEN);
        let mut why = format!("{what}: shortened by half, from {} to {} days", num(prev), num(d));
        if let Some(h) = held {
            why += &format!(" ({h})");
        }
        (d, why)
    };
    let lengthen = |what: &str| {
        // A check made early says nothing of the whole interval.
        if elapsed < EARLY * prev {
            let why = format!(
                "{what}, but checked {} days into its {} days (less than three quarters): the interval stays",
                num(elapsed.round()),
                num(prev)
            );
            return (prev, why);
        }
        let (d, held) = s.bounded(prev * LENGTHEN);
        let mut why = format!("{what}: lengthened by a quarter, from {} to {} days", num(prev), num(d));
        if let Some(h) = held {
            why += &format!(" ({h})");
        }
        (d, why)
    };
    match e.outcome {
        Outcome::Calibration => (prev, format!("calibrated: the interval stays {} days", num(prev))),
        Outcome::OutOfTolerance => shorten("out of tolerance"),
        Outcome::OutOfControl => shorten("out of control on the control chart"),
        Outcome::InTolerance if s.method == Method::ControlChart => match trend(events) {
            Some(t) if t.slope_per_day > 0.0 && t.slope_per_day > 2.0 * t.slope_se => {
                rising(t, s, lengthen("in tolerance"))
            }
            Some(t) => {
                lengthen(&format!("in tolerance, no rising trend over {} checks since the calibration", t.checks))
            }
            None => lengthen("in tolerance, too few checks since the calibration for a trend"),
        },
        Outcome::Changed if s.method == Method::ControlChart => match trend(events) {
            Some(t) if t.slope_per_day > 0.0 && t.slope_per_day > 2.0 * t.slope_se => {
                rising(t, s, shorten("in tolerance, but the positioner changed (the table still holds)"))
            }
            _ => shorten("in tolerance, but the positioner changed (the table still holds)"),
        },
        Outcome::Changed => (
            prev,
            format!(
                "in tolerance, but the positioner changed (the table still holds): the interval stays {} days",
                num(prev)
            ),
        ),
        Outcome::InTolerance => lengthen("in tolerance"),
        Outcome::Other => unreachable!("an event without a review"),
    }
}

/// The interval of a check in tolerance whose control statistic rises
/// (`t`): half the time the trend takes to reach 1, when that is shorter
/// than what the check sets without the trend (`without`: a slight rise
/// far from 1 is no reason to lengthen more than that).
fn rising(t: Trend, s: &Settings, without: (f64, String)) -> (f64, String) {
    let to_limit = ((1.0 - t.now) / t.slope_per_day).max(0.0);
    let trend = format!(
        "the control statistic rising {:.2e} a day over {} checks since the calibration: it reaches 1 (the table no \
         longer holding) in {} days",
        t.slope_per_day,
        t.checks,
        num(to_limit.round())
    );
    let (d, held) = s.bounded(to_limit / 2.0);
    if d >= without.0 {
        return (without.0, format!("{}; {trend}, no sooner", without.1));
    }
    let mut why = format!("in tolerance, {trend}, the interval is half that, {} days", num(d));
    if let Some(h) = held {
        why += &format!(" ({h})");
    }
    (d, why)
}

/// The control statistic's straight-line trend over the checks since the
/// last calibration (at least three with a statistic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trend {
    /// The checks it is fitted to.
    pub checks: usize,
    /// The slope, per day.
    pub slope_per_day: f64,
    /// Its standard error.
    pub slope_se: f64,
    /// The fitted statistic at the last check.
    pub now: f64,
}

/// The trend of the statistic over the checks of `events` since the last calibration.
pub fn trend(events: &[Event]) -> Option<Trend> {
    let start = events.iter().rposition(|e| e.outcome == Outcome::Calibration).map_or(0, |i| i + 1);
    let pts: Vec<(f64, f64)> = events[start..].iter().filter_map(|e| Some((e.at_days, e.statistic?))).collect();
    let n = pts.len();
    if n < 3 {
        return None;
    }
    let nf = n as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / nf, pts.iter().map(|p| p.1).sum::<f64>() / nf);
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx;
    let resid: f64 = pts.iter().map(|p| (p.1 - my - slope * (p.0 - mx)).powi(2)).sum();
    let se = (resid / (nf - 2.0).max(1.0) / sxx).sqrt();
    let last = pts[n - 1].0;
    Some(Trend { checks: n, slope_per_day: slope, slope_se: se, now: my + slope * (last - mx) })
}

/// In use: the revolutions to the next check, and the date projected at
/// the rate the asset has turned so far (the calendar interval `days`
/// without one).
fn in_use(events: &[Event], s: &Settings, days: f64, reason: String) -> (f64, String, Option<f64>) {
    let rate = rate_per_day(events);
    match rate {
        Some(r) => {
            let (d, held) = s.bounded(s.revolutions / r);
            let mut why = format!(
                "in use: {} revolutions between checks, at {r:.3} revolutions a day (the surveys' own travel so far): \
                 {} days",
                num(s.revolutions),
                num(d)
            );
            if let Some(h) = held {
                why += &format!(" ({h})");
            }
            (d, why, Some(s.revolutions))
        }
        None => (
            days,
            format!("{reason}; in use: {} revolutions between checks, no rate of use yet", num(s.revolutions)),
            Some(s.revolutions),
        ),
    }
}

/// The revolutions a day the asset turned from its first survey to the last of `events`.
fn rate_per_day(events: &[Event]) -> Option<f64> {
    let (first, last) = (events.first()?, events.last()?);
    let span = last.at_days - first.at_days;
    // Travel between the first survey and the last (the first's own turned before the span began).
    let turned: f64 = events[1..].iter().map(|e| e.revolutions).sum();
    (span >= 1.0 && turned > 0.0).then(|| turned / span)
}

/// What is due: the next check of an asset.
#[derive(Debug, Clone, PartialEq)]
pub struct Due {
    /// The last review (`None`: never calibrated: due now).
    pub last: Option<Review>,
    /// When the next check is due: days since 1970-01-01 UTC.
    pub next_due_days: f64,
    /// The next check's date has come.
    pub overdue: bool,
    /// In use: the revolutions turned since the last review.
    pub revolutions_since: f64,
    /// Why, in words.
    pub reason: String,
    /// Decided checks, and those in tolerance (and in control): the
    /// reliability the intervals achieved.
    pub reliability: (usize, usize),
}

/// What is due for the asset of `events` at `now_days`.
pub fn due(events: &[Event], now_days: f64) -> Due {
    let reviews = reviews(events);
    let checks = events.iter().filter(|e| {
        matches!(e.outcome, Outcome::InTolerance | Outcome::Changed | Outcome::OutOfTolerance | Outcome::OutOfControl)
    });
    let decided = checks.clone().count();
    let good = checks.filter(|e| matches!(e.outcome, Outcome::InTolerance | Outcome::Changed)).count();
    let Some(last) = reviews.last().cloned() else {
        return Due {
            last: None,
            next_due_days: now_days,
            overdue: true,
            revolutions_since: 0.0,
            reason: "no calibration yet: a full survey calibrates it".into(),
            reliability: (decided, good),
        };
    };
    let after = events.iter().position(|e| e.survey_id == last.survey_id).map_or(events.len(), |i| i + 1);
    let revolutions_since = events[after..].iter().fold(0.0, |sum, e| sum + e.revolutions);
    // A check that called for a recalibration not made since.
    let reviewed = events.iter().rev().find(|e| e.outcome != Outcome::Other).map(|e| e.outcome);
    let pending = matches!(reviewed, Some(Outcome::OutOfTolerance | Outcome::OutOfControl));
    let mut next_due_days = last.at_days + last.interval_days;
    let mut reason = last.reason.clone();
    if pending {
        next_due_days = last.at_days;
        reason = format!("{reason}; the check called for a recalibration that was not made");
    }
    if let Some(budget) = last.revolutions.filter(|&b| revolutions_since >= b) {
        next_due_days = next_due_days.min(now_days);
        reason = format!("{reason}; {} of {} revolutions turned since", num(revolutions_since), num(budget));
    }
    Due {
        overdue: now_days >= next_due_days,
        last: Some(last),
        next_due_days,
        revolutions_since,
        reason,
        reliability: (decided, good),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(id: i64, at_days: f64, outcome: Outcome, settings: Settings) -> Event {
        Event { survey_id: id, at_days, outcome, revolutions: 2.0, statistic: None, settings }
    }

    #[test]
    fn a_staircase_lengthens_after_in_tolerance_and_shortens_after_out_within_its_bounds() {
        let s = Settings::default();
        assert_eq!((s.method, s.interval_days, s.min_days, s.max_days), (Method::Staircase, 90.0, 7.0, 365.0));
        let events = [
            ev(1, 0.0, Outcome::Calibration, s),
            ev(2, 90.0, Outcome::InTolerance, s),
            ev(3, 203.0, Outcome::InTolerance, s),
            ev(4, 344.0, Outcome::OutOfTolerance, s),
            ev(5, 344.1, Outcome::Calibration, s),
            ev(6, 400.0, Outcome::Other, s),
            ev(7, 415.0, Outcome::OutOfControl, s),
        ];
        let r = reviews(&events);
        let days: Vec<f64> = r.iter().map(|r| r.interval_days).collect();
        assert_eq!(days, [90.0, 113.0, 141.0, 71.0, 71.0, 36.0]);
        assert_eq!(r.iter().map(|r| r.survey_id).collect::<Vec<_>>(), [1, 2, 3, 4, 5, 7]);
        assert!(r[0].reason.contains("the first interval stated (interval_days, 90 days)"), "{}", r[0].reason);
        assert_eq!(r[1].reason, "in tolerance: lengthened by a quarter, from 90 to 113 days");
        assert_eq!(r[3].reason, "out of tolerance: shortened by half, from 141 to 71 days");
        assert_eq!(r[4].reason, "calibrated: the interval stays 71 days");
        assert!(r[5].reason.starts_with("out of control on the control chart: shortened"), "{}", r[5].reason);
        // A check made early keeps the interval.
        let early = reviews(&[ev(1, 0.0, Outcome::Calibration, s), ev(2, 30.0, Outcome::InTolerance, s)]);
        assert_eq!(early[1].interval_days, 90.0);
        assert_eq!(
            early[1].reason,
            "in tolerance, but checked 30 days into its 90 days (less than three quarters): the interval stays"
        );
        // The bounds hold it.
        let tight = Settings { min_days: 60.0, max_days: 100.0, ..s };
        let r = reviews(&[
            ev(1, 0.0, Outcome::Calibration, tight),
            ev(2, 90.0, Outcome::InTolerance, tight),
            ev(3, 190.0, Outcome::OutOfTolerance, tight),
        ]);
        assert_eq!(r.iter().map(|r| r.interval_days).collect::<Vec<_>>(), [90.0, 100.0, 60.0]);
        assert!(r[1].reason.ends_with("(held at interval_max_days, 100 days)"), "{}", r[1].reason);
        assert!(r[2].reason.ends_with("(held at interval_min_days, 60 days)"), "{}", r[2].reason);
    }

    #[test]
    fn fixed_keeps_its_interval_and_new_keys_start_again() {
        let fixed = Settings { method: Method::Fixed, interval_days: 30.0, ..Settings::default() };
        let r = reviews(&[
            ev(1, 0.0, Outcome::Calibration, fixed),
            ev(2, 30.0, Outcome::OutOfTolerance, fixed),
            ev(3, 31.0, Outcome::Calibration, fixed),
            ev(4, 60.0, Outcome::InTolerance, Settings::default()),
        ]);
        assert_eq!(r.iter().map(|r| r.interval_days).collect::<Vec<_>>(), [30.0, 30.0, 30.0, 90.0]);
        assert!(r[1].reason.starts_with("fixed: interval_days, 30 days"), "{}", r[1].reason);
        assert!(r[3].reason.contains("interval keys changed"), "{}", r[3].reason);
    }

    #[test]
    fn what_is_due_comes_from_the_last_review_or_a_recalibration_not_made() {
        let s = Settings::default();
        let never = due(&[ev(1, 10.0, Outcome::Other, s)], 12.0);
        assert!(never.overdue && never.last.is_none() && never.next_due_days == 12.0, "{never:?}");
        let events = [ev(1, 0.0, Outcome::Calibration, s), ev(2, 90.0, Outcome::InTolerance, s)];
        let d = due(&events, 150.0);
        assert_eq!((d.next_due_days, d.overdue, d.reliability), (203.0, false, (1, 1)));
        assert!(due(&events, 203.0).overdue);
        let mut pending = vec![ev(1, 0.0, Outcome::Calibration, s), ev(2, 90.0, Outcome::OutOfTolerance, s)];
        let d = due(&pending, 91.0);
        assert!(d.overdue && d.next_due_days == 90.0 && d.reason.contains("not made"), "{d:?}");
        // A verification since is no recalibration.
        pending.push(ev(3, 90.5, Outcome::Other, s));
        assert!(due(&pending, 91.0).reason.contains("not made"));
        assert_eq!(d.reliability, (1, 0));
    }

    #[test]
    fn in_use_counts_the_surveys_travel_and_projects_the_date_at_the_rate_of_use() {
        let s = Settings { method: Method::InUse, revolutions: 20.0, ..Settings::default() };
        // 2 revolutions a survey, one survey a week: 2/7 a day, 20 revolutions in 70 days.
        let mut events = vec![ev(1, 0.0, Outcome::Calibration, s)];
        let r = reviews(&events);
        assert_eq!((r[0].interval_days, r[0].revolutions), (90.0, Some(20.0)));
        assert!(r[0].reason.contains("no rate of use yet"), "{}", r[0].reason);
        for k in 1..=3 {
            events.push(ev(1 + k, 7.0 * k as f64, Outcome::Other, s));
        }
        events.push(ev(5, 28.0, Outcome::InTolerance, s));
        let r = reviews(&events);
        assert_eq!(r[1].interval_days, 70.0, "{}", r[1].reason);
        assert!(r[1].reason.contains("at 0.286 revolutions a day"), "{}", r[1].reason);
        // Turned past its revolutions: due at once.
        for k in 0..10 {
            events.push(ev(6 + k, 29.0 + k as f64 * 0.1, Outcome::Other, s));
        }
        let d = due(&events, 31.0);
        assert!(d.overdue && d.revolutions_since == 20.0 && d.reason.contains("20 of 20 revolutions"), "{d:?}");
    }

    #[test]
    fn a_control_chart_interval_follows_a_rising_trend_and_lengthens_without_one() {
        let s = Settings { method: Method::ControlChart, ..Settings::default() };
        let with = |id: i64, at: f64, stat: f64| Event { statistic: Some(stat), ..ev(id, at, Outcome::InTolerance, s) };
        let mut events = vec![ev(1, 0.0, Outcome::Calibration, s)];
        // Rising 0.005 a day from 0.3: reaches 1 at day 140.
        for (k, at) in [30.0, 60.0, 90.0].into_iter().enumerate() {
            events.push(with(2 + k as i64, at, 0.3 + 0.005 * at + if k == 1 { 0.002 } else { 0.0 }));
        }
        let r = reviews(&events);
        assert!(r[1].reason.contains("too few checks"), "{}", r[1].reason);
        let last = r.last().unwrap();
        assert!(last.reason.contains("reaches 1 (the table no longer holding) in 50 days"), "{}", last.reason);
        assert_eq!(last.interval_days, 25.0);
        // Flat: lengthened.
        let flat: Vec<Event> = std::iter::once(ev(1, 0.0, Outcome::Calibration, s))
            .chain((1..=4).map(|k| with(1 + k, 30.0 * k as f64, 0.3 + 0.01 * ((k % 2) as f64))))
            .collect();
        let r = reviews(&flat);
        assert!(r.last().unwrap().reason.contains("no rising trend over 4 checks"), "{}", r.last().unwrap().reason);
        // A slight rise far from 1: lengthened by a quarter at most.
        let mut slight = vec![ev(1, 0.0, Outcome::Calibration, s)];
        for (k, at) in [28.0, 63.0, 107.0].into_iter().enumerate() {
            slight.push(with(2 + k as i64, at, 0.001 * at));
        }
        let r = reviews(&slight);
        assert_eq!(r.iter().map(|r| r.interval_days).collect::<Vec<_>>(), [90.0, 90.0, 90.0, 90.0], "{r:?}");
        assert!(r[3].reason.ends_with("in 893 days, no sooner"), "{}", r[3].reason);
        // A change inside tolerance without a rising statistic: halved by the
        // control chart's method, kept by the staircase's.
        let mut changed = flat.clone();
        changed.push(Event { statistic: Some(0.3), ..ev(6, 160.0, Outcome::Changed, s) });
        let last = reviews(&changed).last().unwrap().clone();
        assert_eq!(last.interval_days, (0.5 * r.last().unwrap().interval_days).round(), "{last:?}");
        assert!(last.reason.starts_with("in tolerance, but the positioner changed (the table still holds): shortened"));
        let staircase = Settings::default();
        let r = reviews(&[ev(1, 0.0, Outcome::Calibration, staircase), ev(2, 90.0, Outcome::Changed, staircase)]);
        assert_eq!(r[1].interval_days, 90.0, "{:?}", r[1]);
        assert!(r[1].reason.ends_with("the interval stays 90 days"), "{:?}", r[1]);
        assert_eq!(due(&changed, 170.0).reliability, (5, 5));
    }
}
