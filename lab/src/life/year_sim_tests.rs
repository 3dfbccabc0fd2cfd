//! A simulated year through the simulated instruments (issue 53, item 5):
//! every week a cron line runs `survey run --check --due` ([`run_check`]
//! with `only_due`, as the command runs it) on a virtual clock
//! ([`CheckRequest::at`]: what is due is judged at the tick, and the
//! surveys are dated at it); a due check measures the simulated positioner
//! of that day (its model file written with the truth at that day) with
//! the simulated tracker, the loop designs and judges it, and recalibrates
//! when it calls for it (with the calibration's plan). The truth is known:
//! the table in force leaves the change of the positioner since its
//! calibration, and the asset is out of tolerance when that change is
//! beyond the `U` the table is held to (its `U` beside the reference's own
//! part: the same simulated tracker set up in the same place) at more than
//! 5 % of readouts (the contract's statement of `U` broken). The figures
//! are docs/lab.md's ("A simulated year").
//!
//! The positioner is the rates' simple one (`rates_tests`: a 20 cycles/rev
//! gear line of 0.0078 deg, an eccentricity of 0.0015 deg, backlash 0.008
//! deg, noise 0.0004 deg), calibrated with 120 targets x 2 runs both ways
//! (its `U` about 4e-4 deg): stable; wearing (its gear line growing
//! every day); or knocked once, inside tolerance (its eccentricity grown,
//! or a 3 cycles/rev line off the design appearing).
//!
//! `cargo test -p survey-lab year_sim_tests -- --ignored --nocapture`
//! prints the year of each (about 35 s); the tests run by default are
//! shortened horizons asserting what must hold (about 7 s).

use super::check::{CheckRequest, PlanSize, run_check};
use super::due;
use super::interval::{self, Review};
use crate::correction::Choice;
use serde_json::Value;
use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};
use survey_bench::Bench;
use survey_store::Store;
use survey_store::config::AssetSection;
use survey_store::survey::{Setup, SurveyRef};

/// The asset.
const ASSET: &str = "ax";
/// The calibration's targets (2 runs, both ways).
const CAL_POINTS: u32 = 120;
/// The gear line, cycles/rev, and its amplitude at day 0, deg.
const GEAR: (u32, f64) = (20, 0.0078);
/// The eccentricity: its amplitude at day 0 and phase, deg.
const ECCENTRICITY: (f64, f64) = (0.0015, 110.0);
/// A line off the design a knock may leave: cycles/rev and phase, deg.
const NEW_LINE: (u32, f64) = (3, 30.0);
/// Seconds in a day.
const DAY: u64 = 86_400;

/// The first tick: Monday 2027-01-04, 06:00 UTC (the cron's hour).
fn start() -> SystemTime {
    humantime::parse_rfc3339("2027-01-04T06:00:00Z").expect("a time")
}

/// What a knock does.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Knock {
    /// The mounting shifted: the eccentricity grows by this much, deg.
    Eccentricity(f64),
    /// Something bent: a line off the design ([`NEW_LINE`]) of this amplitude, deg.
    NewLine(f64),
}

/// A positioner's truth over the year.
#[derive(Debug, Clone, Copy)]
struct Truth {
    /// The gear line's growth, deg a day (wear).
    wear_per_day: f64,
    /// A knock: its day, and what it does.
    knock: Option<(f64, Knock)>,
    /// The line off the design there from the start, deg (0: none).
    new_line: f64,
}

impl Truth {
    /// The amplitudes at `day`: the gear line's, the eccentricity's and the line off the design's.
    fn lines(&self, day: f64) -> [f64; 3] {
        let knock = self.knock.filter(|&(k, _)| day >= k).map(|(_, what)| what);
        let ecc = ECCENTRICITY.0 + if let Some(Knock::Eccentricity(a)) = knock { a } else { 0.0 };
        let new = self.new_line + if let Some(Knock::NewLine(a)) = knock { a } else { 0.0 };
        [GEAR.1 + self.wear_per_day * day, ecc, new]
    }

    /// The model file at `day`.
    fn model(&self, day: f64) -> String {
        let [gear, ecc, new] = self.lines(day);
        let mut m = format!(
            "[design]\ngear_ratios = [{k}]\ntooth_counts = []\n\n[[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = \
             {k}\namplitude_deg = {gear}\nphase_deg = 0.0\n\n[[effect]]\nkind = \"eccentricity\"\ncycles_per_rev = \
             1\namplitude_deg = {ecc}\nphase_deg = {}\n\n[[effect]]\nkind = \"backlash\"\namplitude_deg = \
             0.008\n\n[[effect]]\nkind = \"noise\"\nsigma_deg = 0.0004\n",
            ECCENTRICITY.1,
            k = GEAR.0
        );
        if new > 0.0 {
            m += &format!(
                "\n[[effect]]\nkind = \"harmonic\"\ncycles_per_rev = {}\namplitude_deg = {new}\nphase_deg = {}\n",
                NEW_LINE.0, NEW_LINE.1
            );
        }
        m
    }

    /// The share of readouts where what changed from `calibrated` (the day
    /// of the calibration in force) to `day` is beyond `u`: the table in
    /// force corrects the positioner of its day, and leaves the change.
    /// The table's own error is within its `U` by its statement; the
    /// change is what can break it (a sum of sinusoids, on 3600 readouts).
    fn beyond(&self, calibrated: f64, day: f64, u: f64) -> f64 {
        let ([g0, e0, k0], [g1, e1, k1]) = (self.lines(calibrated), self.lines(day));
        let n = 3600;
        let out = (0..n)
            .filter(|i| {
                let t = (*i as f64) * std::f64::consts::TAU / f64::from(n);
                let r = (g1 - g0) * (f64::from(GEAR.0) * t).sin()
                    + (e1 - e0) * (t + ECCENTRICITY.1.to_radians()).sin()
                    + (k1 - k0) * (f64::from(NEW_LINE.0) * t + NEW_LINE.1.to_radians()).sin();
                r.abs() > u
            })
            .count();
        out as f64 / f64::from(n)
    }

    /// Out of tolerance: the change beyond `U` at more than 5 % of readouts.
    fn out(&self, calibrated: f64, day: f64, u: f64) -> bool {
        self.beyond(calibrated, day, u) > 0.05
    }
}

/// The simulated bench of `model` at `seed`, of the loop's plan `size`
/// (the rates' bench), with the asset's interval keys `keys`.
fn bench(model: &Path, seed: u64, size: PlanSize, keys: &AssetSection) -> anyhow::Result<Bench> {
    let mut b = super::rates_tests::bench(model, seed, size)?;
    if let Setup::Simulated(s) = &mut b.setup {
        s.asset = Some(keys.clone());
    }
    Ok(b)
}

/// The asset's keys: its interval method, first interval and bounds.
fn keys(method: &str, interval_days: f64, max_days: Option<f64>) -> AssetSection {
    AssetSection {
        id: ASSET.into(),
        interval_days: Some(interval_days),
        interval_method: Some(method.into()),
        interval_min_days: None,
        interval_max_days: max_days,
        interval_revolutions: None,
    }
}

/// One tick that measured: its day, what the loop said, the check's
/// statistic and rules, the `U` the table was held to, and the reason.
#[derive(Debug, Clone)]
struct Tick {
    day: f64,
    outcome: String,
    statistic: Option<f64>,
    rules: Vec<String>,
    held_u: Option<f64>,
    reason: String,
}

impl Tick {
    fn recalibrated(&self) -> bool {
        matches!(self.outcome.as_str(), "recalibrated" | "calibrated")
    }

    /// What a check said, in a word or two: `in`, `changed`, `OUT` (out of
    /// tolerance), the chart's rules, `undecided`.
    fn said(&self) -> String {
        match self.outcome.as_str() {
            "in tolerance" => "in".into(),
            "changed, the table holds" => "changed".into(),
            "not decided" => "undecided".into(),
            "calibrated" => "calibrated".into(),
            _ if self.reason.starts_with(super::control::OUT_OF_CONTROL) => self.rules.join("+"),
            _ => "OUT".into(),
        }
    }
}

/// What a year gave.
#[derive(Debug)]
struct Year {
    /// Every tick that measured (a check, a calibration).
    ticks: Vec<Tick>,
    /// The intervals set: after which day, how many days, why.
    reviews: Vec<Review>,
    /// The calibrations: their day and their table's stated `U`, deg.
    calibrations: Vec<(f64, f64)>,
    /// Days the truth was out of tolerance with no calibration since.
    days_out: Vec<u32>,
    /// The day the truth first left tolerance after each calibration.
    left: Vec<f64>,
    /// Wall time, seconds.
    wall_s: f64,
}

/// The days from the first tick to `t`.
fn day_of(t: SystemTime) -> f64 {
    t.duration_since(start()).unwrap_or_default().as_secs_f64() / DAY as f64
}

/// A year (or `days` of it) of weekly ticks of `truth` with the asset's
/// `keys`, seeded by `seed`, in the directory `dir`.
async fn year(dir: &Path, truth: Truth, keys: &AssetSection, days: u32, seed: u64) -> Year {
    let wall = std::time::Instant::now();
    let db = dir.join(format!("year-{seed}.db"));
    assert!(!db.exists(), "one year a seed: {}", db.display());
    let mut ticks = Vec::new();
    for week in 0..=u64::from(days / 7) {
        let at = start() + Duration::from_secs(week * 7 * DAY);
        let day = day_of(at);
        let model: PathBuf = dir.join(format!("day-{week:02}.toml"));
        std::fs::write(&model, truth.model(day)).expect("the day's model");
        // The first calibration is the operator's (its plan on the command
        // line); every later tick is the cron's `run --check --due`.
        let first = week == 0;
        let req = CheckRequest {
            asset: ASSET.into(),
            polygon: false,
            size: PlanSize { points: first.then_some(CAL_POINTS), runs: first.then_some(2), bidirectional: first },
            json: true,
            recipe: None,
            units: Default::default(),
            correction: Choice::Refuse,
            only_due: !first,
            at: Some(at),
        };
        let calls = Cell::new(0u64);
        let made = |size: PlanSize| {
            calls.set(calls.get() + 1);
            bench(&model, seed * 100_000 + week * 10 + calls.get(), size, keys)
        };
        let out = run_check(&db, &req, &made).await.unwrap_or_else(|e| panic!("day {day}: {e:#}"));
        let doc = out.output.doc;
        let outcome = doc["outcome"].as_str().unwrap_or_default().to_string();
        if outcome == "not due" {
            continue;
        }
        let control = &doc["check"]["control"];
        let tick = Tick {
            day,
            outcome,
            statistic: control["statistic"].as_f64(),
            rules: control["rules"]
                .as_array()
                .map(|r| r.iter().filter_map(Value::as_str).map(String::from).collect())
                .unwrap_or_default(),
            held_u: doc["check"]["table_of_a_on_b"]["stated_u_deg"].as_f64(),
            reason: doc["reason"].as_str().unwrap_or_default().to_string(),
        };
        ticks.push(tick);
    }
    let store = Store::open(&db).await.expect("the store");
    let events = due::events(&store, ASSET).await.expect("the events");
    let first = due::days_at(start());
    // Each calibration's day (as stored: the virtual clock's) and the U its
    // table is held to by a check with the same reference set up in the same
    // place (its U beside the reference's own systematic part, which both
    // surveys share: `compared`): the tolerance the loop keeps.
    let mut calibrations: Vec<(f64, f64)> = Vec::new();
    for r in store.surveys_of_asset(ASSET).await.expect("surveys") {
        if r.is_complete() && r.is_calibration() {
            let day = due::days_of(&r.created_at).expect("a date") - first;
            let m = super::measure(&store, SurveyRef::Id(r.id)).await.expect("measured");
            calibrations.push((day, m.table_u_beside_reference_deg.expect("a U")));
        }
    }
    store.close().await;
    assert_eq!(
        calibrations.len(),
        ticks.iter().filter(|t| t.recalibrated()).count(),
        "a calibration stored for each the loop said it made"
    );
    // Every check held the table to that U (the simulated tracker is set
    // up in one place: the same reference setup every time).
    for t in &ticks {
        let Some(u) = t.held_u else { continue };
        let cal = calibrations.iter().rev().find(|c| c.0 < t.day).expect("a calibration before a check");
        assert!((u - cal.1).abs() <= 1e-12 * cal.1, "day {}: held to {u}, the calibration's {cal:?}", t.day);
    }
    let mut reviews = interval::reviews(&events);
    for r in &mut reviews {
        r.at_days -= first;
    }
    // The truth, day by day: the calibration in force, and whether what
    // changed since is beyond its U.
    let (mut days_out, mut left) = (Vec::new(), Vec::new());
    for d in 0..days {
        let day = f64::from(d);
        let Some(&(calibrated, u)) = calibrations.iter().rev().find(|c| c.0 <= day) else { continue };
        if truth.out(calibrated, day, u) {
            if !left.iter().any(|l| *l > calibrated) {
                left.push(day);
            }
            days_out.push(d);
        }
    }
    Year { ticks, reviews, calibrations, days_out, left, wall_s: wall.elapsed().as_secs_f64() }
}

/// What a year says, for docs/lab.md.
fn show(name: &str, y: &Year) {
    println!("== {name}: {:.0} s wall", y.wall_s);
    for t in &y.ticks {
        println!(
            "  day {:>3}: {:<26} statistic {:>5} held to U {:>8} {}{}",
            t.day,
            t.outcome,
            t.statistic.map_or("-".into(), |x| format!("{x:.2}")),
            t.held_u.map_or("-".into(), |u| format!("{u:.2e}")),
            t.rules.join("+"),
            if t.outcome != "in tolerance" && t.outcome != "calibrated" {
                format!(" [{}]", t.reason)
            } else {
                String::new()
            }
        );
    }
    let intervals: Vec<String> = y.reviews.iter().map(|r| format!("{:.0}", r.interval_days)).collect();
    println!("  intervals set: {}", intervals.join(", "));
    let said: Vec<String> = y.ticks.iter().skip(1).map(|t| format!("{:.0} {}", t.day, t.said())).collect();
    println!("  checks ({}): {}", said.len(), said.join(", "));
    println!("  calibrations (day, U): {:?}", y.calibrations);
    println!("  truth left tolerance on days {:?}; days out with no calibration since: {}", y.left, y.days_out.len());
}

/// The stable positioner.
const STABLE: Truth = Truth { wear_per_day: 0.0, knock: None, new_line: 0.0 };
/// The wearing one: its gear line grows 4e-6 deg a day, the `U` its table
/// is held to (about 4.3e-4 deg) in about 108 days.
const WEARING: Truth = Truth { wear_per_day: 4e-6, ..STABLE };
/// A knock's size, deg: 0.78 of that `U`, inside tolerance (beyond `U` at
/// no readout).
const KNOCK: f64 = 3.5e-4;

/// The whole year of the three positioners (see the module documentation).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "minutes: a year of weekly checks through the simulators, printed for docs/lab.md"]
async fn a_year_of_weekly_checks_through_the_simulators() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let y = year(d, WEARING, &keys("control-chart", 28.0, None), 365, 2).await;
    show("wearing, control chart from 28 days", &y);
    let y = year(d, WEARING, &keys("staircase", 90.0, None), 365, 4).await;
    show("wearing, staircase from 90 days", &y);
    let y = year(d, STABLE, &keys("staircase", 90.0, None), 365, 1).await;
    show("stable, staircase from 90 days", &y);
    let knocked = Truth { knock: Some((150.0, Knock::Eccentricity(KNOCK))), ..STABLE };
    let y = year(d, knocked, &keys("staircase", 7.0, Some(21.0)), 365, 3).await;
    show("knocked at day 150 (eccentricity), staircase from 7 days", &y);
    let y = year(d, knocked, &keys("control-chart", 7.0, Some(21.0)), 365, 7).await;
    show("knocked at day 150 (eccentricity), control chart from 7 days", &y);
    let bent = Truth { knock: Some((150.0, Knock::NewLine(KNOCK))), ..STABLE };
    let y = year(d, bent, &keys("staircase", 7.0, Some(21.0)), 365, 5).await;
    show("knocked at day 150 (a 3 cycles/rev line), staircase from 7 days", &y);
}

/// The shortened horizon run by default: a wearing positioner on the
/// control chart's method, checked from 28 days, up to a week after its
/// truth leaves tolerance (about day 108). Its checks find the gear line
/// changing before then, and the intervals shorten to the least (7 days)
/// while it is still in tolerance; it is recalibrated when the best
/// estimate of what changed is beyond the table's `U`: once the wear is
/// near `U` (a check's estimate of a change at `U` falls either side of
/// it, so the recalibration may come a check early), and at the latest at
/// the first check after it left.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wearing_positioner_is_checked_sooner_before_it_leaves_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let y = year(dir.path(), WEARING, &keys("control-chart", 28.0, None), 115, 2).await;
    show("wearing, control chart from 28 days, to day 115", &y);
    // The truth: the gear line's change reaches the U the table is held to
    // (times 1.0031, where a sinusoid is beyond U at 5 % of readouts) at
    // U / 4e-6 a day.
    let u = y.calibrations[0].1;
    let leaves = (1.0031 * u / WEARING.wear_per_day).ceil();
    let recalibrated = y.ticks.iter().skip(1).find(|t| t.recalibrated()).map(|t| t.day);
    let recalibrated = recalibrated.unwrap_or_else(|| panic!("not recalibrated by day 115: {:#?}", y.ticks));
    // Not a false alarm: the wear had reached most of U; and not late: at
    // most the weekly interval after it left.
    assert!(WEARING.wear_per_day * recalibrated >= 0.8 * u, "recalibrated on day {recalibrated}, U {u}");
    assert!(recalibrated <= leaves + 7.0, "recalibrated on day {recalibrated}, left on day {leaves}");
    assert!(y.days_out.len() <= 7, "{:?}", y.days_out);
    let before: Vec<&Review> = y.reviews.iter().filter(|r| r.at_days < recalibrated).collect();
    let first = before[0].interval_days;
    let in_force = before.last().unwrap().interval_days;
    // Shortened to a quarter of the first interval or less before then, by
    // checks that found the positioner changing, the table still holding.
    assert!(in_force <= first / 4.0, "{:?}", y.reviews);
    assert!(before.iter().any(|r| r.reason.contains("the positioner changed")), "{:?}", y.reviews);
    let said: Vec<String> = y.ticks.iter().filter(|t| t.day < recalibrated).skip(1).map(Tick::said).collect();
    assert!(said.iter().all(|s| s == "in" || s == "changed") && said.last().unwrap() == "changed", "{said:?}");
}

/// A knock (the eccentricity grows by 0.78 `U` on day 30, inside
/// tolerance) is seen at the next check: the checks before it found the
/// positioner unchanged, the first after it names the 1 cycles/rev line
/// changed, the table still holding, and the control chart's method halves
/// the interval. (The chart's statistic, cells beyond `U`, barely moves for
/// a change inside tolerance: the line comparison is what sees it.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_knock_is_seen_at_the_next_check() {
    let dir = tempfile::tempdir().unwrap();
    let knocked = Truth { knock: Some((30.0, Knock::Eccentricity(KNOCK))), ..STABLE };
    let y = year(dir.path(), knocked, &keys("control-chart", 7.0, Some(21.0)), 60, 3).await;
    show("knocked on day 30, control chart from 7 days", &y);
    assert!(y.days_out.is_empty(), "inside tolerance: {:?}", y.days_out);
    let checks = &y.ticks[1..];
    assert!(checks.iter().filter(|t| t.day < 30.0).all(|t| t.said() == "in"), "{checks:?}");
    let next = checks.iter().find(|t| t.day >= 30.0).expect("a check after the knock");
    assert_eq!(next.said(), "changed", "{next:?}");
    assert!(next.reason.contains("the 1 cycles/rev line changed"), "{}", next.reason);
    let review = y.reviews.iter().find(|r| r.at_days == next.day).expect("its review");
    assert!(review.reason.starts_with("in tolerance, but the positioner changed"), "{}", review.reason);
}

/// A positioner with a line off its design (3 cycles/rev, 3.5e-4 deg) from
/// the start: its calibration's 120 targets place the line, so its checks
/// (36 or 48 targets, which alone cannot tell 3 from 33 or 45 cycles/rev)
/// decide. Before, every such check went undecided, and the cron checked
/// again every week.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_line_off_the_design_placed_by_the_calibration_leaves_its_checks_decided() {
    let dir = tempfile::tempdir().unwrap();
    let off = Truth { new_line: KNOCK, ..STABLE };
    let y = year(dir.path(), off, &keys("fixed", 7.0, None), 15, 6).await;
    show("a line off the design, fixed 7 days", &y);
    let said: Vec<String> = y.ticks[1..].iter().map(Tick::said).collect();
    assert_eq!(said, ["in", "in"], "{:?}", y.ticks);
}

/// A line off the design appearing after the calibration (the knock of the
/// year, on day 10, checked every 7 days): a check that cannot place it is
/// "not decided", and the next one measures the calibration's own targets
/// (120), which place it, and decides: the 3 cycles/rev line changed. The
/// checks after it, on their own fewer targets, take the line as that check
/// placed it and decide too (the loop was undecided every week).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_a_check_that_could_not_decide_the_next_measures_the_calibrations_targets() {
    let dir = tempfile::tempdir().unwrap();
    let bent = Truth { knock: Some((10.0, Knock::NewLine(KNOCK))), ..STABLE };
    let y = year(dir.path(), bent, &keys("fixed", 7.0, None), 49, 5).await;
    show("a line off the design from day 10, fixed 7 days", &y);
    let said: Vec<String> = y.ticks.iter().map(Tick::said).collect();
    let undecided: Vec<usize> = (0..said.len()).filter(|&i| said[i] == "undecided").collect();
    assert_eq!(undecided.len(), 1, "{said:?}");
    // Every check after it measured the line the check before could not
    // place: 3.5e-4 deg appeared, said as a change of the 3 cycles/rev line.
    let after = &y.ticks[undecided[0] + 1..];
    assert!(after.len() >= 2, "{said:?}");
    for t in after {
        assert!(t.reason.contains("the 3 cycles/rev line changed"), "day {}: {}", t.day, t.reason);
    }
}
