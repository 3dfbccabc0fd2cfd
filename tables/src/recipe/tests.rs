//! Recipes on synthetic surveys made with the error model.

use super::*;
use survey_controllers::corrector::ValueFormat;
use survey_processing::analysis::analyse;
use survey_processing::analysis::testutil::{circle, fig1, fig4, survey, survey_at_true_angle, true_angle};
use survey_processing::model::Model;
use survey_processing::table::CorrectionTable;
use survey_processing::types::Direction::{self, Forward, Reverse};

fn fig4_survey(points: usize, start: f64, seed: u64) -> (Model, Vec<survey_processing::Sample>) {
    let model = fig4();
    let s = survey_at_true_angle(&circle(points, start), 5, &[Forward, Reverse], 0.0002, seed, |_, d, t| {
        model.repeatable_error_deg(t, d)
    });
    (model, s)
}

fn small_table() -> Recipe {
    let mut r = Recipe::default();
    r.table.dense_points = 32768;
    r.table.rows = 16384;
    r
}

/// What the nulled 648-cycle line leaves in a table of fig4 at `n` points:
/// its products with the other lines, `A_648 A_k (pi / 180) (648 +- k) / 2`
/// at `648 +- k` cycles (the error at the true angle seen at the readout),
/// alias at the targets into the table's kept bins, where they are taken for
/// part of the kept lines. Their sum bounds what they add to the table.
fn products_of_648_on_kept_bins(model: &Model, kept: &[f64], n: usize) -> f64 {
    let bin = |f: f64| (f - n as f64 * (f / n as f64).round()).abs();
    let mut sum = 0.0;
    for e in model.periodic_effects() {
        if let survey_processing::model::Effect::Periodic { cycles_per_rev: k, amplitude_deg: a, .. } = e
            && *k != 648.0
        {
            for f in [648.0 + k, 648.0 - k] {
                if kept.contains(&bin(f)) {
                    sum += 0.00025 * a * std::f64::consts::PI / 180.0 * f / 2.0;
                }
            }
        }
    }
    sum
}

/// The table's largest deviation from `truth` (both columns), over 3600
/// readouts: `truth(theta, direction)` is the error at the TRUE angle, taken
/// at the angle where the positioner reads each readout (the contract).
fn worst(t: &CorrectionTable, truth: impl Fn(f64, Direction) -> f64) -> f64 {
    worst_less(t, truth, 0.0)
}

/// [`worst`] against the truth less a constant (a table whose mean was removed).
fn worst_less(t: &CorrectionTable, truth: impl Fn(f64, Direction) -> f64, constant: f64) -> f64 {
    let mut w = 0.0f64;
    for j in 0..3600 {
        let a = j as f64 * 0.1 + 0.013;
        for d in [Forward, Reverse] {
            let e = truth(true_angle(a, |th| truth(th, d)), d) - constant;
            w = w.max((t.error_at(a, d) - e).abs());
        }
    }
    w
}

#[test]
fn figure_4_first_processing_keeps_the_repeatable_lines_and_places_the_aliases() {
    let (model, samples) = fig4_survey(720, 0.0, 7);
    let defaults = small_table();
    let a = analyse(&samples, &model.design, &defaults.analysis).unwrap();
    let r = Recipe::from_analysis(&a, &defaults);
    assert_eq!(r.lines.keep, vec![2.0, 12.0, 24.0, 36.0, 48.0, 60.0, 72.0, 204.0, 216.0, 228.0], "{r:#?}");
    assert!(r.lines.remove.is_empty());
    let aliases: Vec<(usize, AliasChoiceAction, Option<usize>)> =
        r.aliases.iter().map(|a| (a.true_cycles, a.action, a.observed_cycles)).collect();
    // 432 appears at 288 alone: relocated; 648 shares bin 72 with the pinion's 6th harmonic: nulled.
    assert_eq!(aliases, vec![(432, AliasChoiceAction::Relocate, Some(288)), (648, AliasChoiceAction::Null, Some(72))]);

    let d = r.decide(&a).unwrap();
    assert_eq!(d.kept_cycles, vec![2.0, 12.0, 24.0, 36.0, 48.0, 60.0, 204.0, 216.0, 228.0, 432.0]);
    assert_eq!(d.edit.null, vec![72]);
    assert_eq!(
        d.edit.relocate,
        vec![survey_processing::resample::Relocation { observed_cycles: 288, true_cycles: 432 }]
    );
    let at = |c: f64| d.lines.iter().find(|l| l.cycles_per_rev == c).unwrap();
    assert_eq!((at(288.0).action, at(288.0).true_cycles_per_rev), (LineAction::Relocated, 432.0));
    assert_eq!(at(72.0).action, LineAction::Nulled);
    assert_eq!(at(12.0).action, LineAction::Kept);
    let contract: Vec<(f64, f64, decide::AliasOutcome)> =
        d.aliases.iter().filter(|x| x.applied).map(|x| (x.observed_cycles, x.true_cycles, x.action)).collect();
    assert!(contract.contains(&(288.0, 432.0, decide::AliasOutcome::Relocated)), "{contract:?}");
    assert!(contract.contains(&(72.0, 648.0, decide::AliasOutcome::Nulled)), "{contract:?}");

    // Backlash 0.001 against a hysteresis noise of 0.0002 sqrt(2/5): directional.
    let built = r.build_table(&a, &d).unwrap();
    assert!(built.directional, "{}", built.directional_reason);
    let h = built.hysteresis.as_ref().unwrap();
    assert!((h.mean_deg - 0.001).abs() < 2e-5 && (h.noise_deg / (0.0002 * 0.4f64.sqrt()) - 1.0).abs() < 0.1, "{h:?}");
    // The table is the model without the nulled 648-cycle harmonic (the rows
    // carry the mean noise of 5 runs on ten lines: a few 1e-5 deg), and the
    // products of that harmonic that alias onto the kept lines.
    let truth =
        |t: f64, dir: Direction| model.repeatable_error_deg(t, dir) - 0.00025 * (648.0 * t + 90.0).to_radians().sin();
    let w = worst(&built.table, truth);
    let products = products_of_648_on_kept_bins(&model, &d.kept_cycles, 720);
    assert!(w < 5e-5 + products, "worst {w:e} (products {products:e})");
    assert_eq!(built.method, TableMethod::Spectral { dense_points: 32768 });
}

#[test]
fn a_recipe_round_trips_through_its_file_and_replays_the_same_lines() {
    let (model, samples) = fig4_survey(720, 0.0, 7);
    let a = analyse(&samples, &model.design, &AnalysisOptions::default()).unwrap();
    let mut r = Recipe::from_analysis(&a, &small_table());
    r.lines.unlisted = Unlisted::Remove;
    r.export.binary_format = ValueFormat::F32;
    let text = r.to_toml();
    assert!(text.contains("keep = [2, 12, 24"), "{text}");
    let back = Recipe::parse(&text, "r.toml").unwrap();
    assert_eq!(back, r, "{text}");
    // A new survey of the same positioner, another noise draw: the same lines.
    let (_, again) = fig4_survey(720, 0.0, 99);
    let b = analyse(&again, &model.design, &back.analysis).unwrap();
    let first = r.decide(&a).unwrap();
    let second = back.decide(&b).unwrap();
    assert_eq!(first.kept_cycles, second.kept_cycles);
    assert_eq!(first.edit, second.edit);
    // A partial-range fit survives the round trip too.
    let mut partial = r.clone();
    partial.table.partial_method = Some(PartialMethod::LeastSquares { cycles: vec![6.0, 72.5], poly_degree: 3 });
    assert_eq!(Recipe::parse(&partial.to_toml(), "p.toml").unwrap(), partial);
    // The default file parses to the default recipe.
    assert_eq!(Recipe::parse("", "empty.toml").unwrap(), Recipe::default());
    assert_eq!(Recipe::parse(&Recipe::default().to_toml(), "d.toml").unwrap(), Recipe::default());
}

#[test]
fn the_recipe_overrides_the_tests_both_ways() {
    let (model, samples) = fig4_survey(720, 0.0, 7);
    let a = analyse(&samples, &model.design, &AnalysisOptions::default()).unwrap();
    let mut r = Recipe::from_analysis(&a, &small_table());
    // Keep a frequency with nothing at it, remove a repeatable line.
    r.lines.keep.retain(|&f| f != 12.0);
    r.lines.remove.push(12.0);
    r.lines.keep.push(100.0);
    let d = r.decide(&a).unwrap();
    assert!(!d.kept_cycles.contains(&12.0) && d.kept_cycles.contains(&100.0), "{:?}", d.kept_cycles);
    let l100 = d.lines.iter().find(|l| l.cycles_per_rev == 100.0).unwrap();
    assert!(!l100.significant && l100.action == LineAction::Kept && l100.from_recipe);
    let l12 = d.lines.iter().find(|l| l.cycles_per_rev == 12.0).unwrap();
    assert!(l12.repeatable && l12.action == LineAction::Removed);
    // An alias override: relocate 648 from bin 72 (the whole bin moves).
    let mut over = r.clone();
    over.aliases.iter_mut().find(|x| x.true_cycles == 648).unwrap().action = AliasChoiceAction::Relocate;
    let d = over.decide(&a).unwrap();
    assert!(d.edit.relocate.iter().any(|x| x.true_cycles == 648 && x.observed_cycles == 72));
    assert!(d.edit.null.is_empty());
}

#[test]
fn a_recipe_from_a_finer_survey_on_a_coarser_one() {
    // 360 points: 432 and 648 both alias to bin 72, so both cannot be relocated.
    let (model, fine) = fig4_survey(720, 0.0, 7);
    let a = analyse(&fine, &model.design, &AnalysisOptions::default()).unwrap();
    let mut r = Recipe::from_analysis(&a, &small_table());
    r.aliases.iter_mut().for_each(|x| x.action = AliasChoiceAction::Relocate);
    let (_, coarse) = fig4_survey(360, 0.0, 8);
    let b = analyse(&coarse, &model.design, &AnalysisOptions::default()).unwrap();
    let e = r.decide(&b).unwrap_err();
    assert_eq!(e.key, "alias[2].true_cycles", "{e}");
    assert!(e.message.contains("bin 72"), "{e}");
    // The same recipe on a finer survey: 432 is resolved there, so the alias entry keeps it as a line.
    let (_, finer) = fig4_survey(1800, 0.0, 9);
    let c = analyse(&finer, &model.design, &AnalysisOptions::default()).unwrap();
    let d = r.decide(&c).unwrap();
    assert!(d.kept_cycles.contains(&432.0) && d.kept_cycles.contains(&648.0), "{:?}", d.kept_cycles);
    assert!(d.notes.iter().any(|n| n.contains("resolved")), "{:?}", d.notes);
    // A dense grid too small for a relocation names its key.
    let mut tiny = r.clone();
    tiny.aliases.truncate(1);
    tiny.table.dense_points = 800;
    assert_eq!(tiny.decide(&a).unwrap_err().key, "table.dense_points");
}

#[test]
fn targets_that_start_off_zero_give_the_same_table() {
    let model = fig4();
    let clean = |_: u32, d: Direction, t: f64| model.repeatable_error_deg(t, d) + 0.003;
    let samples = survey_at_true_angle(&circle(720, 0.25), 3, &[Forward, Reverse], 1e-7, 3, clean);
    let a = analyse(&samples, &model.design, &AnalysisOptions::default()).unwrap();
    let r = Recipe::from_analysis(&a, &small_table());
    let decided = r.decide(&a).unwrap();
    let built = r.build_table(&a, &decided).unwrap();
    // Noise-free: the linear interpolation between the 16384 rows, A (2 pi k
    // / rows)^2 / 8 per line (1.3e-6 at 216 and 1.4e-6 at 432 cycles), and
    // the products of the nulled 648-cycle line on kept bins.
    let products = products_of_648_on_kept_bins(&model, &decided.kept_cycles, 720);
    let w = worst(&built.table, |t, d| clean(1, d, t) - 0.00025 * (648.0 * t + 90.0).to_radians().sin());
    assert!(w < 4e-6 + products, "worst {w:e} (products {products:e})");
    // remove_mean takes the common zero offset away, not the forward/reverse difference.
    let mut zero = r.clone();
    zero.table.remove_mean = true;
    let z = zero.build_table(&a, &zero.decide(&a).unwrap()).unwrap();
    let w = worst_less(&z.table, |t, d| clean(1, d, t) - 0.00025 * (648.0 * t + 90.0).to_radians().sin(), 0.003);
    assert!(w < 4e-6 + products, "worst {w:e}");
}

#[test]
fn directional_choice_follows_the_recipe_and_the_hysteresis() {
    let model = fig4();
    let no_backlash = |_: u32, _: Direction, t: f64| model.periodic_error_deg(t);
    let samples = survey(&circle(360, 0.0), 4, &[Forward, Reverse], 0.0002, 5, no_backlash);
    let a = analyse(&samples, &model.design, &AnalysisOptions::default()).unwrap();
    let mut r = Recipe::from_analysis(&a, &small_table());
    assert!(!r.directional_for(&a).0, "{}", r.directional_for(&a).1);
    r.table.directional = Directional::On;
    assert!(r.build_table(&a, &r.decide(&a).unwrap()).unwrap().table.is_directional());
    r.table.directional = Directional::Off;
    assert!(!r.directional_for(&a).0);
    let forward_only = survey(&circle(360, 0.0), 2, &[Forward], 0.0002, 5, no_backlash);
    let f = analyse(&forward_only, &model.design, &AnalysisOptions::default()).unwrap();
    r.table.directional = Directional::On;
    let (on, why, h) = r.directional_for(&f);
    assert!(!on && h.is_none() && why.contains("one direction"), "{why}");
}

#[test]
fn a_partial_range_is_fitted_at_the_kept_lines() {
    let model = fig1();
    let targets: Vec<f64> = (0..=200).map(|j| -10.0 + 0.5 * j as f64).collect();
    let samples =
        survey_at_true_angle(&targets, 3, &[Forward, Reverse], 0.0002, 11, |_, d, t| model.repeatable_error_deg(t, d));
    let a = analyse(&samples, &model.design, &AnalysisOptions::default()).unwrap();
    let r = Recipe::from_analysis(&a, &small_table());
    assert!(!r.lines.keep.is_empty());
    let d = r.decide(&a).unwrap();
    assert_eq!(d.points, None);
    let built = r.build_table(&a, &d).unwrap();
    assert!(matches!(built.method, TableMethod::Partial { .. }), "{:?}", built.method);
    let mut w = 0.0f64;
    for j in 0..=100 {
        let t = -10.0 + j as f64;
        for dir in [Forward, Reverse] {
            let e = if built.directional { model.repeatable_error_deg(t, dir) } else { model.periodic_error_deg(t) };
            w = w.max((built.table.error_at(t, dir) - e).abs());
        }
    }
    assert!(w < 1e-3, "worst {w:e} with {}", built.method);
}

fn parse_err(text: &str) -> RecipeError {
    Recipe::parse(text, "r.toml").unwrap_err()
}

#[test]
fn defects_name_the_file_line_and_key() {
    let e = parse_err("version = 1\n[table]\nrows = 1\n");
    assert_eq!((e.line, e.key.as_str()), (Some(3), "table.rows"), "{e}");
    assert_eq!(e.to_string(), "r.toml:3: table.rows: must be from 2 to 16777216, got 1");
    let e = parse_err("[table]\ndense_points = 8192\nrowz = 5\n");
    assert_eq!((e.line, e.key.as_str()), (Some(3), "table.rowz"), "{e}");
    assert!(e.message.contains("unknown field"), "{e}");
    let e = parse_err("[lines]\nkeep = [12]\nremove = [12]\n");
    assert_eq!((e.line, e.key.as_str()), (Some(3), "lines.remove"), "{e}");
    let e = parse_err("[table]\ndirectional = \"sometimes\"\n");
    assert_eq!((e.line, e.key.as_str()), (Some(2), "table.directional"), "{e}");
    let e = parse_err(
        "[[alias]]\ntrue_cycles = 432\naction = \"relocate\"\n\n[[alias]]\ntrue_cycles = 432\naction = \"null\"\n",
    );
    assert_eq!((e.line, e.key.as_str()), (Some(6), "alias[2].true_cycles"), "{e}");
    let e = parse_err("[[alias]]\ntrue_cycles = 432\naction = \"move\"\n");
    assert_eq!((e.line, e.key.as_str()), (Some(3), "alias[1].action"), "{e}");
    let e = parse_err("[analysis]\nfalse_alarm_rate = -1\n");
    assert_eq!((e.line, e.key.as_str()), (Some(2), "analysis.false_alarm_rate"), "{e}");
    let e = parse_err("[export]\nlinuxcnc_points = 300\n");
    assert_eq!((e.line, e.key.as_str()), (Some(2), "export.linuxcnc_points"), "{e}");
    let e = parse_err("version = 2\n");
    assert_eq!((e.line, e.key.as_str()), (Some(1), "version"), "{e}");
    let e = parse_err("[table\n");
    assert_eq!(e.line, Some(1), "{e}");
    // A survey-time error placed in its file.
    let text = "[table]\nrows = 64\ndense_points = 800\n";
    let placed = RecipeError::of_choice(ChoiceError::new("table.dense_points", "too small"), text, "r.toml");
    assert_eq!(placed.to_string(), "r.toml:3: table.dense_points: too small");
    assert_eq!(locate("[[alias]]\ntrue_cycles = 1\n[[alias]]\ntrue_cycles = 2\n", "alias[2].true_cycles"), Some(4));
    assert_eq!(locate("[lines]\nkeep = []\n", "lines.remove"), Some(1));
    assert_eq!(locate("", "table.rows"), None);
}
