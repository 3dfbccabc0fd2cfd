//! The comparison on surveys simulated from a model (model-gap's simulator,
//! seeded): control pairs (the same positioner twice) and the changes a
//! positioner's life brings (wear, a disturbed mounting, more backlash).

use super::*;
use crate::tests::{circle, model, periodic, simulate};
use survey_processing::model::{Effect, Model, PeriodicKind};
use survey_processing::{Direction, Sample};

/// The paper's Figure 8 positioner (`sims/presets/fig8.toml`), with `change`
/// applied to its effects.
fn fig8(change: impl Fn(&mut Vec<Effect>)) -> Model {
    let mut effects = vec![
        periodic(PeriodicKind::GearPass, 20.0, 0.0078, 0.0),
        periodic(PeriodicKind::GearPass, 40.0, 0.0025, 60.0),
        periodic(PeriodicKind::Eccentricity, 1.0, 0.0015, 110.0),
        Effect::Backlash { amplitude_deg: 0.008 },
        Effect::Noise { sigma_deg: 0.0004 },
    ];
    change(&mut effects);
    model(&[20.0], &[], effects)
}

/// The tracker's own noise, degrees (about 1 m of arm).
const REFERENCE_SIGMA: f64 = 0.0006;

/// A full survey: 360 targets, 5 runs, both ways.
fn full(m: &Model, seed: u64) -> Vec<Sample> {
    simulate(m, &circle(360), 5, true, REFERENCE_SIGMA, seed)
}

/// A check survey: 36 targets (every tenth of the full survey's), 2 runs, both ways.
fn check(m: &Model, seed: u64) -> Vec<Sample> {
    simulate(m, &circle(36), 2, true, REFERENCE_SIGMA, seed)
}

/// The expanded uncertainty (k = 2) of [`table_of`] a full survey: each
/// row a mean of 5 samples.
fn table_u() -> f64 {
    2.0 * (0.0004f64.powi(2) + REFERENCE_SIGMA.powi(2)).sqrt() / 5f64.sqrt()
}

fn options() -> CompareOptions {
    CompareOptions { lines: vec![1.0, 20.0, 40.0], ..CompareOptions::default() }
}

fn line(c: &Comparison, k: f64) -> &LineChange {
    c.lines.iter().find(|l| l.cycles_per_rev == k).unwrap_or_else(|| panic!("line {k} tested: {c:#?}"))
}

/// The table a survey makes of itself: its mean error per target and
/// direction (the survey's targets are the table's rows).
fn table_of(samples: &[Sample], rows: usize) -> CorrectionTable {
    let column = |d: Direction| -> Vec<f64> {
        (0..rows)
            .map(|i| {
                let t = 360.0 * i as f64 / rows as f64;
                let e: Vec<f64> = samples
                    .iter()
                    .filter(|s| s.direction == d && (s.target_deg - t).abs() < 1e-9)
                    .map(Sample::error_deg)
                    .collect();
                e.iter().sum::<f64>() / e.len() as f64
            })
            .collect()
    };
    CorrectionTable::directional(column(Direction::Forward), column(Direction::Reverse)).unwrap()
}

/// The false-alarm rate, counted on control pairs: the same simulated
/// positioner surveyed twice with different seeds, full survey against full
/// survey and full survey against a check survey. At the stated 1 % at most
/// about one pair in a hundred is "changed" (the bound allows a Poisson
/// count's 4.5 standard deviations); the tests are calibrated, not just
/// quiet: at the per-test level, each test's p-value is below 0.1 in about a
/// tenth of the pairs; the table of the first holds on the second but in
/// about 1 % of pairs. `COMPARE_FALSE_ALARM_PAIRS=2000` counts more pairs.
#[test]
fn false_alarms_on_control_pairs() {
    let truth = fig8(|_| {});
    let pairs: u64 = std::env::var("COMPARE_FALSE_ALARM_PAIRS").ok().and_then(|v| v.parse().ok()).unwrap_or(60);
    for (what, second) in [("full", full as fn(&Model, u64) -> Vec<Sample>), ("check", check)] {
        let (mut changed, mut low, mut tests, mut failed, mut recalibrated) = (0u64, 0usize, 0usize, 0u64, 0u64);
        // Which test said "changed": a line, the backlash, the map.
        let mut by = [0usize; 3];
        for seed in 0..pairs {
            let a = full(&truth, 1000 + 2 * seed);
            let b = second(&truth, 1001 + 2 * seed);
            let c = compare(&a, &b, &options()).unwrap();
            changed += u64::from(c.verdict == Verdict::Changed);
            let held = table_on(&table_of(&a, 360), table_u(), &a, &b, 0.01, [0.0; 2]).unwrap();
            failed += u64::from(!held.holds);
            recalibrated += u64::from(decide(&c, Some(&held), None).recalibrate);
            by[0] += c.lines.iter().filter(|l| l.significant).count();
            by[1] += usize::from(c.backlash.as_ref().is_some_and(|b| b.significant));
            by[2] += usize::from(c.map.as_ref().is_some_and(|m| m.significant));
            let p: Vec<f64> = c
                .lines
                .iter()
                .map(|l| l.p_value)
                .chain(c.backlash.iter().map(|b| b.p_value))
                .chain(c.map.iter().map(|m| m.p_value))
                .collect();
            low += p.iter().filter(|&&p| p < 0.1).count();
            tests += p.len();
        }
        let expected = 0.01 * pairs as f64;
        eprintln!(
            "{what}: {changed} of {pairs} control pairs changed ({:.4}: a line {}, the backlash {}, the map {}); {low} of \
             {tests} tests with p < 0.1; the table failed in {failed}, recalibrated {recalibrated}",
            changed as f64 / pairs as f64,
            by[0],
            by[1],
            by[2]
        );
        assert!(failed as f64 <= expected + 4.5 * expected.sqrt().max(1.0), "{what}: the table failed in {failed}");
        assert!(changed as f64 <= expected + 4.5 * expected.sqrt().max(1.0), "{what}: {changed} of {pairs}");
        // The decision (the cells' test and the best estimate of what
        // changed, each at the rate) recalibrates no more often.
        assert!(
            recalibrated as f64 <= 2.0 * expected + 4.5 * (2.0 * expected).sqrt().max(1.0),
            "{what}: {recalibrated}"
        );
        let share = low as f64 / tests as f64;
        let sd = (0.09 / tests as f64).sqrt();
        assert!((share - 0.1).abs() < 4.5 * sd, "{what}: p < 0.1 in {share:.3} of tests");
    }
}

#[test]
fn the_same_positioner_twice_is_unchanged_and_its_table_holds() {
    let truth = fig8(|_| {});
    let (a, b) = (full(&truth, 1), full(&truth, 2));
    let c = compare(&a, &b, &options()).unwrap();
    assert_eq!(c.verdict, Verdict::Unchanged, "{c:#?}");
    // Three lines, the backlash and the map: five tests at 0.2 % each.
    assert_eq!((c.lines.len(), c.lines_not_tested.len()), (3, 0));
    assert!((c.per_test_rate - 0.002).abs() < 1e-15);
    let l20 = line(&c, 20.0);
    assert!((l20.amplitude_from_deg - 0.0078).abs() < 1e-4 && (l20.amplitude_to_deg - 0.0078).abs() < 1e-4, "{l20:?}");
    assert!(l20.phase_from_deg.abs() < 1.0, "{l20:?}");
    let bl = c.backlash.as_ref().unwrap();
    assert!((bl.from_deg - 0.008).abs() < 1e-4 && (bl.to_deg - 0.008).abs() < 1e-4, "{bl:?}");
    let map = c.map.as_ref().unwrap();
    assert_eq!(map.cells, 720);
    // The repeatability: the positioner's and the reference's noise.
    let sigma = (0.0004f64.powi(2) + REFERENCE_SIGMA.powi(2)).sqrt();
    assert!(c.repeatability_deg.iter().all(|s| (s / sigma - 1.0).abs() < 0.05), "{:?}", c.repeatability_deg);
    // A phasor's change: the standard error of each component of a line is
    // sigma sqrt(2 / 3600) in each survey; the threshold at 0.2 % (2 dof) is
    // sqrt(-2 ln 0.002) = 3.53 standard errors of the pair.
    let se = sigma * (2.0f64 / 3600.0).sqrt() * 2f64.sqrt();
    assert!((l20.change_u_deg / (3.53 * se) - 1.0).abs() < 0.06, "{} against {}", l20.change_u_deg, 3.53 * se);

    let held = table_on(&table_of(&a, 360), table_u(), &a, &b, 0.01, [0.0; 2]).unwrap();
    assert!(held.holds && held.cells == 720 && held.predicted_peak_deg.is_some(), "{held:?}");
    // On a check survey (its cells a tenth of the calibration's) too.
    let held = table_on(&table_of(&a, 360), table_u(), &a, &check(&truth, 3), 0.01, [0.0; 2]).unwrap();
    assert!(held.holds && held.cells == 72, "{held:?}");
    let d = decide(&c, Some(&held), None);
    assert!(!d.recalibrate && d.reason.starts_with("no change beyond"), "{d:?}");
}

#[test]
fn wear_a_disturbed_mounting_and_more_backlash_are_changes_named_with_their_size() {
    let truth = fig8(|_| {});
    let a = full(&truth, 1);
    let table = table_of(&a, 360);
    let grown = |k: f64, to: f64| {
        move |e: &mut Vec<Effect>| {
            for x in e.iter_mut() {
                if let Effect::Periodic { cycles_per_rev, amplitude_deg, .. } = x
                    && *cycles_per_rev == k
                {
                    *amplitude_deg = to;
                }
            }
        }
    };
    // Wear: the gear line a third larger.
    let worn = fig8(grown(20.0, 0.0104));
    // A disturbed mounting: a new once-per-revolution term beside the old one.
    let moved = fig8(|e| e.push(periodic(PeriodicKind::Harmonic, 1.0, 0.002, 200.0)));
    let expected_once = {
        let (s1, c1) = (110f64.to_radians().sin_cos(), 200f64.to_radians().sin_cos());
        (0.0015 * s1.0 + 0.002 * c1.0).hypot(0.0015 * s1.1 + 0.002 * c1.1)
    };
    // More backlash.
    let slack = fig8(|e| {
        e.retain(|x| !matches!(x, Effect::Backlash { .. }));
        e.push(Effect::Backlash { amplitude_deg: 0.012 });
    });
    for (name, m, sparse) in
        [("wear", &worn, false), ("mounting", &moved, false), ("backlash", &slack, false), ("wear", &worn, true)]
    {
        let b = if sparse { check(m, 7) } else { full(m, 7) };
        let c = compare(&a, &b, &options()).unwrap();
        assert_eq!(c.verdict, Verdict::Changed, "{name}: {c:#?}");
        let bl = c.backlash.as_ref().unwrap();
        match name {
            "wear" => {
                let l = line(&c, 20.0);
                assert!(l.significant && (l.amplitude_to_deg - 0.0104).abs() < 3.0 * l.change_u_deg / 3.5, "{l:?}");
                assert!(!bl.significant && !line(&c, 40.0).significant, "{c:#?}");
            }
            "mounting" => {
                let l = line(&c, 1.0);
                assert!(l.significant && (l.amplitude_to_deg - expected_once).abs() < 2e-4, "{l:?} {expected_once}");
                assert!(!line(&c, 20.0).significant && !bl.significant, "{c:#?}");
            }
            _ => {
                assert!(bl.significant && (bl.to_deg - 0.012).abs() < 1e-4, "{bl:?}");
                assert!(c.lines.iter().all(|l| !l.significant), "{c:#?}");
            }
        }
        let held = table_on(&table, table_u(), &a, &b, 0.01, [0.0; 2]).unwrap();
        assert!(!held.holds, "{name}: {held:?}");
        let d = decide(&c, Some(&held), None);
        let said = match name {
            "wear" => "the 20 cycles/rev line changed from 7.",
            "mounting" => "the 1 cycles/rev line changed",
            _ => "the backlash changed from",
        };
        assert!(d.recalibrate && d.reason.contains(said) && d.reason.contains("no longer holds"), "{name}: {d:?}");
        // Named with its size.
        let size = match name {
            "wear" => line(&c, 20.0).amplitude_to_deg,
            "mounting" => line(&c, 1.0).amplitude_to_deg,
            _ => bl.to_deg,
        };
        assert!(d.reason.contains(&format!("to {size:.3e} deg")), "{name}: {d:?}");
    }
}

/// A table that corrects only part of the error (here nothing of the gear
/// lines, as a sparse survey's table leaves aliased lines) still holds on the
/// same positioner: what it leaves was its prediction. A change smaller than
/// the stated `U` is significant, and the table holds all the same.
#[test]
fn a_table_holds_against_its_own_prediction_and_within_its_stated_u() {
    let truth = fig8(|_| {});
    let a = full(&truth, 1);
    let only_once = CorrectionTable::new(
        (0..360).map(|i| 0.0015 * (f64::from(i).to_radians() + 110f64.to_radians()).sin()).collect(),
    )
    .unwrap();
    let held = table_on(&only_once, table_u(), &a, &full(&truth, 2), 0.01, [0.0; 2]).unwrap();
    assert!(held.holds && held.residual_peak_deg > 0.01, "{held:?}");
    assert!(held.predicted_peak_deg.is_some_and(|p| (p - held.residual_peak_deg).abs() < 2e-3), "{held:?}");
    // Without common cells (targets half a degree apart), the residual itself is held to U: it does not hold.
    let shifted: Vec<f64> = circle(360).iter().map(|t| t + 0.5).collect();
    let elsewhere = simulate(&truth, &shifted, 5, true, REFERENCE_SIGMA, 3);
    assert!(!table_on(&only_once, table_u(), &a, &elsewhere, 0.01, [0.0; 2]).unwrap().holds);
    // The gear line grown by 2e-4 deg: significant, within a stated U of 1e-3 deg.
    let worn = fig8(|e| e[0] = periodic(PeriodicKind::GearPass, 20.0, 0.0080, 0.0));
    let b = full(&worn, 4);
    let c = compare(&a, &b, &options()).unwrap();
    assert!(line(&c, 20.0).significant, "{c:#?}");
    let held = table_on(&table_of(&a, 360), 1e-3, &a, &b, 0.01, [0.0; 2]).unwrap();
    assert!(held.holds, "{held:?}");
    // A significant change within a table that holds recalibrates nothing:
    // "changed, the table holds", what changed named.
    let d = decide(&c, Some(&held), None);
    assert!(!d.recalibrate && d.changed && d.reason.starts_with("changed, the table holds: the 20"), "{d:?}");
    // Unless it exceeds the asset's tolerance.
    let change = line(&c, 20.0).change_deg;
    let d = decide(&c, Some(&held), Some(change / 2.0));
    assert!(d.recalibrate && d.reason.contains("beyond the asset's tolerance"), "{d:?}");
    assert!(!decide(&c, Some(&held), Some(change * 2.0)).recalibrate);
}

/// Issue 49: the Figure 8 positioner worn (its 40 cycles/rev line 0.0025 ->
/// 0.0040 deg) checked at 36 targets. Whatever the few noisy cells say, the
/// change the line's test measured (1.5e-3 deg, less what the repeatability
/// allows) is what the table now leaves at most readouts, far beyond its U:
/// the table no longer holds. Held to a U above the change, it does.
#[test]
fn the_table_fails_on_the_best_estimate_of_what_changed() {
    let truth = fig8(|_| {});
    let a = full(&truth, 1);
    let worn = fig8(|e| e[1] = periodic(PeriodicKind::GearPass, 40.0, 0.0040, 60.0));
    let b = check(&worn, 9);
    let c = compare(&a, &b, &options()).unwrap();
    let l = line(&c, 40.0);
    assert!(l.significant && (l.change_deg - 0.0015).abs() < l.change_u_deg, "{l:?}");
    let left = changes_left(&c, table_u());
    eprintln!("{l:?}\n{left:?}, U {:.2e}", table_u());
    // The change as measured, and where it exceeds U (4.8e-4).
    // (Its peak on 3600 readouts of a 40 cycles/rev line: within 1e-3 of it.)
    assert!((left.peak_deg - l.change_deg).abs() < 1e-3 * l.change_deg, "{left:?}");
    assert!(left.share > 0.5, "{left:?}");
    let cells_hold = TableCheck {
        holds: true,
        cells_outside: 0,
        ..table_on(&table_of(&a, 360), table_u(), &a, &b, 0.01, [0.0; 2]).unwrap()
    };
    let d = decide(&c, Some(&cells_hold), None);
    assert!(
        d.recalibrate && d.reason.contains("what changed leaves") && d.reason.contains("the best estimate"),
        "{d:?}"
    );
    eprintln!("{}", d.reason);
    // Held to a U above the change's lower bound (the change less what
    // the repeatability allows) but below its best estimate, the table no
    // longer holds: the best estimate decides.
    let between = l.change_deg - l.change_u_deg / 2.0;
    assert!(changes_left(&c, between).share > 0.05);
    let d = decide(&c, Some(&TableCheck { stated_u_deg: between, ..cells_hold.clone() }), None);
    assert!(d.recalibrate, "{d:?}");
    let wide = TableCheck { stated_u_deg: 0.003, ..cells_hold };
    assert_eq!(changes_left(&c, 0.003).share, 0.0);
    let d = decide(&c, Some(&wide), None);
    assert!(!d.recalibrate && d.reason.starts_with("changed, the table holds"), "{d:?}");
}

#[test]
fn a_sparse_survey_leaves_out_the_lines_that_alias_onto_another() {
    let truth = fig8(|_| {});
    let a = full(&truth, 1);
    // At 36 targets, 16 cycles is 20's alias: the same columns.
    let opts = CompareOptions { lines: vec![1.0, 20.0, 40.0, 16.0, 20.0, 0.0], ..options() };
    let c = compare(&a, &check(&truth, 2), &opts).unwrap();
    assert_eq!(c.lines.iter().map(|l| l.cycles_per_rev).collect::<Vec<_>>(), [1.0, 20.0, 40.0]);
    assert_eq!(c.lines_not_tested, [16.0]);
    assert_eq!(c.map.as_ref().unwrap().cells, 72);
    assert_eq!(c.verdict, Verdict::Unchanged, "{c:#?}");
}

#[test]
fn the_axis_of_a_tracker_is_known_only_so_well() {
    // Each survey's axis off by its own small amount: a once-per-revolution
    // error of the reference, as large as the stated axis uncertainty allows.
    let truth = fig8(|_| {});
    let shifted = fig8(|e| e.push(periodic(PeriodicKind::Harmonic, 1.0, 1.5e-4, 30.0)));
    let (a, b) = (full(&truth, 3), full(&shifted, 4));
    let told = CompareOptions { axis_se_deg: [1.0e-4, 1.0e-4], ..options() };
    let unknown = compare(&a, &b, &options()).unwrap();
    assert!(line(&unknown, 1.0).significant, "without the axis's uncertainty: {unknown:#?}");
    let known = compare(&a, &b, &told).unwrap();
    assert_eq!(known.verdict, Verdict::Unchanged, "{known:#?}");
}

#[test]
fn surveys_without_repeatability_cannot_be_compared() {
    let truth = fig8(|_| {});
    let one_run = simulate(&truth, &circle(36), 1, true, 0.0, 1);
    let e = compare(&full(&truth, 1), &one_run, &options()).unwrap_err();
    assert_eq!(e, CompareError::NoRepeatability("B"));
    assert!(e.to_string().contains("survey B has no target measured twice"));
    assert!(table_on(&table_of(&full(&truth, 1), 360), 1e-4, &full(&truth, 1), &one_run, 0.01, [0.0; 2]).is_none());
}

#[test]
fn the_binomial_quantile_is_exact_on_small_counts() {
    // P(Bin(20, 0.05) > q): q = 2 leaves 0.0755, q = 3 leaves 0.0159, q = 4 leaves 0.0026.
    assert_eq!(binomial_isf(20, 0.05, 0.05), 3);
    assert_eq!(binomial_isf(20, 0.05, 0.01), 4);
    assert_eq!(binomial_isf(1, 0.05, 0.01), 1);
    assert_eq!(binomial_isf(0, 0.05, 0.01), 0);
    // 720 cells: mean 36, sd 5.85: about 50 at 1 %.
    let q = binomial_isf(720, 0.05, 0.01);
    assert!((49..=52).contains(&q), "{q}");
}

/// The check: at 40 targets the 20 cycles/rev line sits on the
/// Nyquist bin (its sine vanishes at the targets) and the 40 aliases onto
/// the mean. Neither is estimable: no amplitude is computed for them (it was
/// 2e10 deg), each is said with why, and the rest is still tested.
#[test]
fn a_line_on_the_nyquist_bin_or_the_mean_is_not_estimable_and_says_why() {
    let truth = fig8(|_| {});
    let a = simulate(&truth, &circle(120), 2, true, REFERENCE_SIGMA, 3);
    let b = simulate(&truth, &circle(40), 2, true, REFERENCE_SIGMA, 4);
    let c = compare(&a, &b, &options()).unwrap();
    assert_eq!(c.lines.iter().map(|l| l.cycles_per_rev).collect::<Vec<_>>(), [1.0], "{c:#?}");
    assert_eq!(c.lines_not_tested, [20.0, 40.0]);
    let why = |k: f64| &c.not_estimable.iter().find(|u| u.cycles_per_rev == k).unwrap().why;
    assert!(why(20.0).contains("Nyquist bin (20)") && why(20.0).contains("survey B"), "{}", why(20.0));
    assert!(why(40.0).contains("onto the mean"), "{}", why(40.0));
    let largest = c.lines.iter().map(|l| l.amplitude_from_deg.max(l.amplitude_to_deg)).fold(0.0, f64::max);
    assert!(largest < 0.01, "{c:#?}");
}

/// A line the fit would make larger than the whole error's span is left out
/// too: a line just off the Nyquist bin of a sparse grid, ill-conditioned.
#[test]
fn a_fitted_line_larger_than_the_error_itself_is_not_estimable() {
    let truth = fig8(|_| {});
    let a = full(&truth, 5);
    let b = simulate(&truth, &circle(40), 2, true, REFERENCE_SIGMA, 6);
    let opts = CompareOptions { lines: vec![1.0, 19.999_999], ..CompareOptions::default() };
    let c = compare(&a, &b, &opts).unwrap();
    assert_eq!(c.lines_not_tested, [19.999_999], "{c:#?}");
    assert!(c.not_estimable[0].why.contains("span"), "{:?}", c.not_estimable);
}

/// The stated false-alarm rate at every point count and reference (issue
/// 37): control pairs of the Figure 8 positioner, two surveys of `n`
/// targets, 3 runs both ways, with a tracker's noise (0.0006 deg a reading)
/// and its axis's once-per-revolution uncertainty (stated, 1e-4 deg a
/// component, and drawn for each survey), or an autocollimator's (0.1 arcsec,
/// no axis term), at 180, 360, 720 and 1800 targets. Each count's rate of
/// "changed" must stay within a Poisson count's 4.5 standard deviations of
/// the stated 1 %. 40 pairs a cell by default (the suite's share);
/// `COMPARE_RATE_PAIRS=1000` gives the figures of docs/validation.md.
#[test]
fn the_false_alarm_rate_holds_at_every_count_and_reference() {
    let pairs: u64 = std::env::var("COMPARE_RATE_PAIRS").ok().and_then(|v| v.parse().ok()).unwrap_or(40);
    let counts: &[usize] = if pairs > 40 { &[180, 360, 720, 1800] } else { &[180, 720] };
    for &(reference, sigma, axis_se) in &[("tracker", REFERENCE_SIGMA, 1e-4), ("autocollimator", 0.1 / 3600.0, 0.0)] {
        for &n in counts {
            let mut changed = 0u64;
            for seed in 0..pairs {
                // Each survey's axis off by its own draw of the stated uncertainty.
                let survey = |s: u64| {
                    let mut rng = survey_processing::analysis::testutil::Normal::new(7 * s + n as u64);
                    let (c, d) = (axis_se * rng.sample(), axis_se * rng.sample());
                    let truth =
                        fig8(|e| e.push(periodic(PeriodicKind::Harmonic, 1.0, c.hypot(d), d.atan2(c).to_degrees())));
                    simulate(&truth, &circle(n), 3, true, sigma, s)
                };
                let (a, b) = (survey(5000 + 2 * seed), survey(5001 + 2 * seed));
                let opts = CompareOptions { axis_se_deg: [axis_se; 2], ..options() };
                changed += u64::from(compare(&a, &b, &opts).unwrap().verdict == Verdict::Changed);
            }
            let expected = 0.01 * pairs as f64;
            eprintln!("{reference}, {n} targets: {changed} of {pairs} control pairs changed");
            assert!(
                changed as f64 <= expected + 4.5 * expected.sqrt().max(1.0),
                "{reference}, {n} targets: {changed} of {pairs}"
            );
        }
    }
}

/// Issue 49, item 4: a new line neither survey names, twice the table's `U`
/// (so beyond `U` at two thirds of the readouts: the table no longer holds
/// in truth), at a bin the 36-target check sees. No cell of the check can
/// show it (a cell is outside beyond `U + 2 s_d`, 1.8e-3 deg here, above the
/// line's 1.3e-3), but what the table leaves, in rms over the check's 72
/// cells with their noise removed, is about 9e-4 deg against the 4.6e-4 a
/// line within `U` may leave: the table no longer holds, said with the
/// figures. Half `U` (within it everywhere) holds. Counted over 20 seeds
/// each: the rms test's rate is half the stated 1 %, so a holding table
/// fails in at most one or two of 20 by chance; the 2 `U` line's rms is 4
/// standard errors beyond its allowance, so at most a few of 20 miss it.
#[test]
fn a_new_line_the_cells_cannot_show_is_caught_by_what_the_table_leaves_in_rms() {
    let truth = fig8(|_| {});
    for (size, holds_in_truth) in [(2.0, false), (0.5, true)] {
        let amplitude = size * table_u();
        let new = fig8(|e| e.push(periodic(PeriodicKind::Harmonic, 7.0, amplitude, 30.0)));
        let (mut failed, mut by_cells, mut said) = (0, 0, String::new());
        for seed in 0..20u64 {
            let a = full(&truth, 100 + seed);
            let b = check(&new, 200 + seed);
            let held = table_on(&table_of(&a, 360), table_u(), &a, &b, 0.01, [0.0; 2]).unwrap();
            by_cells += usize::from(held.cells_outside > held.allowed_outside);
            if !held.holds {
                failed += 1;
                let c = compare(&a, &b, &options()).unwrap();
                let d = decide(&c, Some(&held), None);
                assert!(d.recalibrate, "{d:?}");
                said = d.reason;
            }
            if size == 2.0 {
                // The estimate is of the line's rms (A / sqrt 2), within its noise.
                let rms = amplitude / 2f64.sqrt();
                assert!((held.left_rms_deg - rms).abs() < 0.35 * rms, "{held:?}");
            }
        }
        eprintln!("a new line of {size} U: the table failed in {failed} of 20 ({by_cells} by its cells); {said}");
        if holds_in_truth {
            assert!(failed <= 2, "{failed}");
        } else {
            assert!(failed >= 17 && by_cells <= 2, "{failed} ({by_cells} by cells)");
            assert!(said.contains("rms over 72 cells"), "{said}");
        }
    }
}
