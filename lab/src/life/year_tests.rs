//! A simulated year of an asset's life on a virtual clock (issue 53): a
//! cron line asks every week whether a check is due ([`interval::due`]);
//! a due check measures the control statistic (the table's residual
//! against its `U`, [`control`]: 1 where the table no longer holds) of a
//! positioner whose truth is known (stable, wearing slowly, knocked once),
//! with seeded noise; it is judged as `survey run --check`
//! judges (out of tolerance above 1, else the control chart,
//! [`control::next`]), and a recalibration resets the truth's drift. The
//! figures are those of docs/lab.md ("A simulated year").

use super::control::{self, Check, Point};
use super::interval::{self, Event, Method, Outcome, Settings};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A positioner's truth: the statistic a check would measure without noise.
#[derive(Debug, Clone, Copy)]
struct Truth {
    /// Right after a calibration (what the table leaves: the noise's own peak).
    base: f64,
    /// Growth a day since the calibration (a line wearing).
    wear_per_day: f64,
    /// A knock: its day and what it adds until the next calibration.
    knock: Option<(f64, f64)>,
}

impl Truth {
    fn at(&self, day: f64, calibrated: f64) -> f64 {
        let knock = self.knock.filter(|&(k, _)| k > calibrated && k <= day).map_or(0.0, |(_, size)| size);
        self.base + self.wear_per_day * (day - calibrated) + knock
    }
}

/// What a year gave.
#[derive(Debug)]
struct Year {
    /// Each check: its day, the statistic, what it was.
    checks: Vec<(f64, f64, Outcome, Vec<&'static str>)>,
    /// The interval set after each review: its day and days.
    intervals: Vec<(f64, f64)>,
    /// Days the truth was above tolerance (1) with no calibration since.
    days_out: usize,
}

/// The noise of a check's statistic (its standard deviation, in U).
const NOISE: f64 = 0.02;

fn year(truth: Truth, settings: Settings, seed: u64) -> Year {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, NOISE).unwrap();
    let ev = |id: usize, at_days: f64, outcome: Outcome, statistic: Option<f64>| Event {
        survey_id: id as i64,
        at_days,
        outcome,
        revolutions: 2.0,
        statistic,
        settings,
    };
    let mut events = vec![ev(0, 0.0, Outcome::Calibration, None)];
    let (mut chart, mut charted): (Vec<Point>, Vec<Check>) = (Vec::new(), Vec::new());
    let mut calibrations = vec![0.0];
    let mut checks = Vec::new();
    for week in 1..=52 {
        let now = 7.0 * f64::from(week);
        if !interval::due(&events, now).overdue {
            continue;
        }
        let calibrated = *calibrations.last().unwrap();
        let x = truth.at(now, calibrated) + noise.sample(&mut rng);
        let this =
            Check { statistic: Some(x), calibration: format!("{calibrated}"), out_of_tolerance: false, step: None };
        let point = control::next(&charted, &chart, &this);
        let outcome = match (x > 1.0, point.out_of_control()) {
            (true, _) => Outcome::OutOfTolerance,
            (false, true) => Outcome::OutOfControl,
            (false, false) => Outcome::InTolerance,
        };
        checks.push((now, x, outcome, point.rules.clone()));
        chart.push(point);
        charted.push(Check {
            statistic: Some(x),
            calibration: format!("{calibrated}"),
            out_of_tolerance: outcome == Outcome::OutOfTolerance,
            step: None,
        });
        events.push(ev(events.len(), now, outcome, Some(x)));
        if outcome != Outcome::InTolerance {
            events.push(ev(events.len(), now + 0.01, Outcome::Calibration, None));
            calibrations.push(now + 0.01);
        }
    }
    let days_out = (0..365)
        .filter(|&d| {
            let d = f64::from(d);
            let calibrated = calibrations.iter().rev().find(|&&c| c <= d).copied().unwrap_or(0.0);
            truth.at(d, calibrated) > 1.0
        })
        .count();
    let intervals = interval::reviews(&events).iter().map(|r| (r.at_days, r.interval_days)).collect();
    Year { checks, intervals, days_out }
}

/// What a year says, for docs/lab.md (`cargo test -p survey-lab year -- --nocapture`).
fn show(name: &str, y: &Year) {
    let checks: Vec<String> = y
        .checks
        .iter()
        .map(|(d, x, o, rules)| {
            let o = match o {
                Outcome::InTolerance => String::new(),
                Outcome::OutOfTolerance => " OUT".into(),
                _ => format!(" {}", rules.join("+")),
            };
            format!("{d:.0}:{x:.2}{o}")
        })
        .collect();
    let intervals: Vec<String> = y.intervals.iter().map(|(_, i)| format!("{i:.0}")).collect();
    println!("{name}: {} checks [{}]", y.checks.len(), checks.join(", "));
    println!("{name}: intervals {}; days out of tolerance {}", intervals.join(" "), y.days_out);
}

const STABLE: Truth = Truth { base: 0.3, wear_per_day: 0.0, knock: None };
const WEARING: Truth = Truth { base: 0.3, wear_per_day: 0.005, knock: None };

#[test]
fn a_year_stable_positioner_gets_longer_intervals() {
    let y = year(STABLE, Settings::default(), 1);
    show("stable, staircase from 90 days", &y);
    let days: Vec<f64> = y.intervals.iter().map(|i| i.1).collect();
    assert_eq!(days, [90.0, 113.0, 141.0, 176.0], "{y:?}");
    assert!(y.checks.iter().all(|c| c.2 == Outcome::InTolerance) && y.days_out == 0, "{y:?}");
}

#[test]
fn a_year_wearing_positioner_gets_shorter_intervals_before_it_leaves_tolerance() {
    // The control chart's trend: from 28 days, shortened as the statistic
    // rises; the truth reaches 1 at day 140 after each calibration.
    let settings = Settings { method: Method::ControlChart, interval_days: 28.0, ..Settings::default() };
    let y = year(WEARING, settings, 2);
    show("wearing, control chart from 28 days", &y);
    let first_out = y.checks.iter().position(|c| c.2 != Outcome::InTolerance).expect("caught");
    let before: Vec<f64> = y.intervals[..=first_out].iter().map(|i| i.1).collect();
    assert!(before[first_out] < before[1] && before[first_out] <= 14.0, "shortened before it left: {before:?}");
    assert!(y.checks[first_out].0 <= 147.0, "caught within a week of leaving (day 140): {y:?}");
    assert!(y.days_out <= 2 * 7, "{y:?}");
    // Worn again after the recalibration: the chart's trend rule catches it inside tolerance.
    assert!(y.checks.iter().any(|c| c.2 == Outcome::OutOfControl && c.1 < 1.0 && c.3.contains(&"6 rising")), "{y:?}");
    // The staircase, for comparison: it learns only from a check out of tolerance.
    let s = year(WEARING, Settings::default(), 2);
    show("wearing, staircase from 90 days", &s);
    assert!(s.days_out > y.days_out, "{s:?}");
}

#[test]
fn a_year_knock_is_caught_by_the_control_chart_at_the_next_check() {
    let settings = Settings { interval_days: 7.0, max_days: 21.0, ..Settings::default() };
    let knocked = Truth { knock: Some((150.0, 0.25)), ..STABLE };
    let y = year(knocked, settings, 3);
    show("knocked at day 150, staircase from 7 days", &y);
    let next = y.checks.iter().find(|c| c.0 >= 150.0).unwrap();
    assert_eq!(next.2, Outcome::OutOfControl, "{y:?}");
    assert!(next.1 < 1.0 && next.3.contains(&"beyond 3 sigma"), "inside tolerance, caught by the chart: {next:?}");
    assert!(y.checks.iter().filter(|c| c.0 < 150.0).all(|c| c.2 == Outcome::InTolerance), "{y:?}");
}
