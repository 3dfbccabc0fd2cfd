//! The control chart of an asset's checks (issue 53; ILAC-G24 M2): each
//! check's statistic, the table in force's residual against its `U`: the
//! cells of the check where the error moved by more than `U` over one more
//! than the most that may while the table holds (at 1 it no longer holds),
//! plotted against a centre line and limits from the asset's earlier checks
//! in control (an individuals chart: the mean, and three standard
//! deviations estimated from the mean moving range over d2 = 1.128), once
//! [`BASELINE`] checks are there; the rules that fire say the check is out
//! of control, and `survey run --check` then recalibrates even inside
//! tolerance. Pure: the checks in, the chart out.
//!
//! What the baseline leaves out: the checks out of control, and every check
//! of a calibration that ended out of tolerance (a positioner wearing until
//! its table no longer held is not what "in control" looks like). The
//! rules read only the checks of the calibration in force (a new table is a
//! new state), and only upwards: a check that finds the table holding
//! better than usual calls for nothing.
//! - `beyond 3 sigma` (WE 1, Nelson 1): the check above the upper limit;
//! - `2 of 3 beyond 2 sigma` (WE 2, Nelson 5): two of the last three checks
//!   more than two standard deviations above the centre, the current one
//!   among them;
//! - `9 on one side` (Nelson 2): the last nine above the centre;
//! - `6 rising` (Nelson 3): the last six each above the one before (wear;
//!   it needs no baseline).

use serde_json::{Value, json};
use survey_store::CheckDecision;

/// What the reason of a check out of control starts with (the decision
/// stored says so; the intervals read it back).
pub const OUT_OF_CONTROL: &str = "out of control on the control chart";

/// What the chart plots.
pub const STATISTIC: &str = "cells_outside / (allowed_outside + 1): the check's cells where the error moved by more \
                             than the table's U, over one more than the most that may while the table holds (at 1 it \
                             no longer holds)";

/// Checks in control needed before the chart has limits.
pub const BASELINE: usize = 5;

/// The earlier checks the centre and limits are taken from, at most.
pub const WINDOW: usize = 25;

/// The smallest standard deviation the limits are set with (a hundredth of
/// `U`: a simulated bench can repeat itself closer than any real one), and
/// never less than one step of the check's statistic ([`next`]).
pub const SIGMA_FLOOR: f64 = 0.01;

/// The statistic of a check whose table check found `outside` cells beyond
/// `U` where `allowed` may be.
pub fn statistic(outside: usize, allowed: usize) -> f64 {
    outside as f64 / (allowed as f64 + 1.0)
}

/// The statistic of a stored check, when it measured one.
pub fn statistic_of(c: &CheckDecision) -> Option<f64> {
    match (c.cells_outside, c.allowed_outside) {
        (Some(o), Some(a)) if o >= 0 && a >= 0 => Some(statistic(o as usize, a as usize)),
        _ => None,
    }
}

/// One check on the chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Its statistic (none: not measured).
    pub statistic: Option<f64>,
    /// The centre line, once the chart has a baseline.
    pub centre: Option<f64>,
    /// The standard deviation the limits are three of.
    pub sigma: Option<f64>,
    /// The rules that fired.
    pub rules: Vec<&'static str>,
}

impl Point {
    /// Whether a rule fired.
    pub fn out_of_control(&self) -> bool {
        !self.rules.is_empty()
    }

    /// The lower control limit (the statistic is not negative).
    pub fn lower(&self) -> Option<f64> {
        Some((self.centre? - 3.0 * self.sigma?).max(0.0))
    }

    /// The upper control limit.
    pub fn upper(&self) -> Option<f64> {
        Some(self.centre? + 3.0 * self.sigma?)
    }

    /// The contract's `control` document (`statistic`, `centre`, `lower`,
    /// `upper`, `out_of_control`, `rules`) and what the chart plots.
    pub fn json(&self) -> Value {
        json!({
            "statistic": self.statistic,
            "centre": self.centre,
            "lower": self.lower(),
            "upper": self.upper(),
            "sigma": self.sigma,
            "out_of_control": self.out_of_control(),
            "rules": self.rules,
            "plots": STATISTIC,
        })
    }
}

/// A check, as the chart reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// Its statistic (none: not measured).
    pub statistic: Option<f64>,
    /// The calibration it checked (its uid).
    pub calibration: String,
    /// It called for a recalibration by tolerance (not by the chart).
    pub out_of_tolerance: bool,
    /// The step of its statistic, one cell beyond `U` more or fewer
    /// (`1 / (allowed + 1)`), when measured.
    pub step: Option<f64>,
}

impl Check {
    /// A stored check's decision.
    pub fn of(c: &CheckDecision) -> Check {
        Check {
            statistic: statistic_of(c),
            calibration: c.against_uid.clone(),
            out_of_tolerance: c.recalibrate && !c.reason.starts_with(OUT_OF_CONTROL),
            step: c.allowed_outside.filter(|a| *a >= 0).map(|a| 1.0 / (a as f64 + 1.0)),
        }
    }
}

/// The chart of a sequence of checks, oldest first: one point each.
pub fn chart(checks: &[Check]) -> Vec<Point> {
    let mut points: Vec<Point> = Vec::with_capacity(checks.len());
    for (i, c) in checks.iter().enumerate() {
        let p = next(&checks[..i], &points, c);
        points.push(p);
    }
    points
}

/// The point of a new check `now` (of its calibration, with its
/// statistic), after the checks `before` and their points.
pub fn next(before: &[Check], points: &[Point], now: &Check) -> Point {
    let (x, calibration) = (now.statistic, now.calibration.as_str());
    let worn_out = |cal: &str| before.iter().any(|c| c.calibration == cal && c.out_of_tolerance);
    let baseline: Vec<f64> = before
        .iter()
        .zip(points)
        .filter(|(c, p)| !p.out_of_control() && !worn_out(&c.calibration))
        .filter_map(|(_, p)| p.statistic)
        .collect();
    let baseline = &baseline[baseline.len().saturating_sub(WINDOW)..];
    let Some(x) = x else { return Point { statistic: None, centre: None, sigma: None, rules: Vec::new() } };
    // The run the rules read: the measured checks of this calibration, then this one.
    let mut run: Vec<f64> =
        before.iter().filter(|c| c.calibration == calibration).filter_map(|c| c.statistic).collect();
    run.push(x);
    let rising = run.len() >= 6 && run[run.len() - 6..].windows(2).all(|p| p[1] > p[0]);
    if baseline.len() < BASELINE {
        let rules = if rising { vec!["6 rising"] } else { Vec::new() };
        return Point { statistic: Some(x), centre: None, sigma: None, rules };
    }
    let n = baseline.len() as f64;
    let centre = baseline.iter().sum::<f64>() / n;
    let mr = baseline.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>() / (n - 1.0);
    // Never below one step of the check's statistic: a count of cells
    // resolves no less, and a baseline of checks with no cell beyond `U`
    // would put the upper limit below one cell, when an unchanged
    // positioner shows a cell beyond `U` now and then (through the
    // simulators, `year_sim_tests`: a false recalibration in ten checks).
    let sigma = (mr / 1.128).max(SIGMA_FLOOR).max(now.step.unwrap_or(0.0));
    let mut rules = rules(&run, centre, sigma);
    if rising {
        rules.push("6 rising");
    }
    Point { statistic: Some(x), centre: Some(centre), sigma: Some(sigma), rules }
}

/// The rules but the trend that fire on the last of `run`, upwards.
fn rules(run: &[f64], centre: f64, sigma: f64) -> Vec<&'static str> {
    let z: Vec<f64> = run.iter().map(|x| (x - centre) / sigma).collect();
    let last = |k: usize| (z.len() >= k).then(|| &z[z.len() - k..]);
    let now = z[z.len() - 1];
    let mut fired = Vec::new();
    if now > 3.0 {
        fired.push("beyond 3 sigma");
    }
    if let Some(w) = last(3)
        && now > 2.0
        && w.iter().filter(|v| **v > 2.0).count() >= 2
    {
        fired.push("2 of 3 beyond 2 sigma");
    }
    if let Some(w) = last(9)
        && w.iter().all(|v| *v > 0.0)
    {
        fired.push("9 on one side");
    }
    fired
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks of calibration `cal`, in tolerance.
    fn of(cal: &str, stats: &[Option<f64>]) -> Vec<Check> {
        stats
            .iter()
            .map(|&s| Check { statistic: s, calibration: cal.into(), out_of_tolerance: false, step: None })
            .collect()
    }

    fn some(xs: &[f64]) -> Vec<Option<f64>> {
        xs.iter().map(|&x| Some(x)).collect()
    }

    #[test]
    fn a_chart_has_limits_once_it_has_a_baseline_and_a_jump_fires() {
        let steady = [0.30, 0.34, 0.31, 0.33, 0.30, 0.32];
        let mut stats = some(&steady);
        stats.insert(2, None);
        stats.push(Some(0.60));
        let checks = of("a", &stats);
        let c = chart(&checks);
        assert!(c[..6].iter().all(|p| p.centre.is_none() && !p.out_of_control()), "{c:?}");
        assert_eq!(c[2].statistic, None);
        let p = &c[6];
        // Centre 0.316, mean moving range 0.03: sigma 0.0266.
        assert!((p.centre.unwrap() - 0.316).abs() < 1e-12, "{p:?}");
        assert!((p.sigma.unwrap() - 0.03 / 1.128).abs() < 1e-12, "{p:?}");
        assert!(!p.out_of_control());
        let knock = &c[7];
        assert_eq!(knock.rules, ["beyond 3 sigma"], "{knock:?}");
        assert!(knock.upper().unwrap() < 0.60 && knock.lower().unwrap() > 0.0);
        let doc = knock.json();
        for key in ["statistic", "centre", "lower", "upper", "out_of_control", "rules"] {
            assert!(doc.get(key).is_some(), "{key}: {doc}");
        }
        // The knock is not in the next check's baseline; nor is a check far below: none fires.
        let after = next(&checks, &c, &of("b", &[Some(0.10)])[0]);
        assert!((after.centre.unwrap() - 1.9 / 6.0).abs() < 1e-12, "{after:?}");
        assert!(!after.out_of_control() && after.lower().unwrap() > 0.10, "{after:?}");
    }

    #[test]
    fn the_run_rules_fire_on_a_shift_and_a_trend_of_the_calibration_in_force() {
        let base = [0.30, 0.34, 0.31, 0.33, 0.30, 0.32];
        let c = chart(&of("a", &some(&[&base[..], &[0.39, 0.395]].concat())));
        assert_eq!(c[7].rules, ["2 of 3 beyond 2 sigma"], "{:?}", c[7]);
        let rising = some(&[&base[..], &[0.305, 0.31, 0.315, 0.32, 0.325, 0.33]].concat());
        let c = chart(&of("a", &rising));
        assert!(c[..11].iter().all(|p| !p.out_of_control()), "{c:?}");
        assert_eq!(c[11].rules, ["6 rising"], "{:?}", c[11]);
        // A new calibration starts the run again.
        let mut two = of("a", &some(&[0.25, 0.27, 0.29]));
        two.extend(of("b", &some(&[0.30, 0.31, 0.32])));
        assert!(!chart(&two)[5].out_of_control(), "{:?}", chart(&two));
        let c = chart(&of("a", &some(&[&base[..], &[0.33; 9]].concat())));
        assert!(c.last().unwrap().rules.contains(&"9 on one side"), "{:?}", c.last());
    }

    #[test]
    fn a_single_cell_beyond_u_over_a_baseline_of_none_does_not_fire() {
        // Checks with 16 cells allowed: the statistic moves in steps of 1/17.
        let step = 1.0 / 17.0;
        let mut checks = of("a", &some(&[0.0; 6]));
        for c in &mut checks {
            c.step = Some(step);
        }
        let c = chart(&checks);
        let now = |x: f64| Check { statistic: Some(x), step: Some(step), ..checks[0].clone() };
        let one = next(&checks, &c, &now(step));
        assert_eq!((one.sigma, one.out_of_control()), (Some(step), false), "{one:?}");
        let four = next(&checks, &c, &now(4.0 * step));
        assert_eq!(four.rules, ["beyond 3 sigma"], "{four:?}");
        // Without the step (the statistic alone), the floor of a hundredth.
        assert!(next(&checks, &c, &Check { step: None, ..now(step) }).out_of_control());
    }

    #[test]
    fn a_calibration_that_wore_out_is_no_baseline() {
        let mut checks = of("a", &some(&[0.3, 0.5, 0.7, 0.8, 0.9]));
        checks.push(Check { statistic: Some(1.1), calibration: "a".into(), out_of_tolerance: true, step: None });
        checks.extend(of("b", &some(&[0.31, 0.29, 0.32, 0.3, 0.31, 0.3])));
        let c = chart(&checks);
        assert!(c[6..].iter().all(|p| !p.out_of_control()), "{c:?}");
        assert!(c[6..11].iter().all(|p| p.centre.is_none()), "{c:?}");
        assert!((c[11].centre.unwrap() - 0.306).abs() < 1e-12, "{:?}", c[11]);
    }

    #[test]
    fn a_check_without_both_figures_has_no_statistic() {
        let c = |o: Option<i64>, a: Option<i64>| CheckDecision {
            survey_id: 1,
            against_uid: String::new(),
            verdict: "unchanged".into(),
            table_holds: true,
            recalibrate: false,
            reason: String::new(),
            recalibration_uid: None,
            table_file: None,
            residual_peak_deg: Some(0.001),
            stated_u_deg: Some(0.004),
            cells_outside: o,
            allowed_outside: a,
        };
        assert_eq!(statistic_of(&c(Some(21), Some(83))), Some(0.25));
        assert_eq!(statistic_of(&c(None, Some(83))), None);
        // At 1 the table no longer holds: one more cell outside than allowed.
        assert_eq!((statistic(9, 9) < 1.0, statistic(10, 9)), (true, 1.0));
        assert_eq!(statistic(1, 0), 1.0);
    }
}
